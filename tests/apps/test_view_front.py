"""The view's front door rules (apps/view/front.py), without I/O: a handshake gets in only with the token
and, if it has an Origin, an allowed one; the reason never repeats the token; what the door says first
on a relayed connection. The door itself, over real sockets: tests/attack/test_attack_view.py."""

from __future__ import annotations

import json

from hypothesis import given
from hypothesis import strategies as st

from go2vlm.apps.view.front import HELLO_CHANNEL, Handshake, hello_messages, origin_allowed

TOKEN = "front-door-token-0123456789"
RULES = Handshake(TOKEN, ("https://app.foxglove.dev", "http://localhost:*"))


def test_origins() -> None:
    assert origin_allowed("https://app.foxglove.dev", RULES.allowed_origins)
    assert origin_allowed("https://APP.foxglove.dev/", RULES.allowed_origins)
    assert origin_allowed("http://localhost:8080", RULES.allowed_origins)
    for foreign in ("https://evil.example", "https://app.foxglove.dev.evil.example", "http://localhost.evil:80",
                    "http://localhost:80x", "null", "http://localhost", ""):  # fmt: skip
        assert not origin_allowed(foreign, RULES.allowed_origins), foreign


@given(st.sampled_from(["", "https://evil.example", "https://app.foxglove.dev", "null"]),
       st.sampled_from(["", TOKEN, "0xdeadbeef-guess", TOKEN + "x"]), st.booleans())  # fmt: skip
def test_a_handshake_gets_in_only_with_the_token_and_an_allowed_origin(origin: str, token: str, bearer: bool) -> None:
    headers = {"origin": origin} if origin else {}
    path = "/"
    if token and bearer:
        headers["authorization"] = f"Bearer {token}"
    elif token:
        path = f"/?token={token}"
    refused = RULES.refusal(path, headers)
    ok_origin = origin in ("", "https://app.foxglove.dev")
    assert (refused is None) == (ok_origin and token == TOKEN)
    if refused is not None:
        status, why = refused
        assert status == (401 if ok_origin else 403) and why
        assert TOKEN not in why and (not token or token not in why)


def test_the_hello_is_advertised_then_withdrawn() -> None:
    adv, unadv = (json.loads(m) for m in hello_messages("/_go2vlm/hello/abc"))
    assert adv["op"] == "advertise" and adv["channels"][0]["topic"] == "/_go2vlm/hello/abc"
    assert adv["channels"][0]["id"] == HELLO_CHANNEL and unadv == {"op": "unadvertise", "channelIds": [HELLO_CHANNEL]}
