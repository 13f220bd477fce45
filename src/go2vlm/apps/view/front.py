"""The view's front door: when clients may publish, every Foxglove client comes in through here.

foxglove-sdk 0.30 tells a server listener only a client's number: it never shows the handshake (no
headers, no query string), so the SDK cannot check a token or an Origin itself. So with client
publishing on, the view's own port is this small WebSocket server (the `websockets` package), which
checks each handshake and then relays the connection, frame for frame, to the SDK's server on a
loopback port of its own (127.0.0.1, any free port):

    browser / Foxglove --ws://host:port/?token=...--> front door --ws://127.0.0.1:inner--> foxglove-sdk

A handshake is refused (HTTP 401 or 403, with the reason, before any Foxglove message) unless
  - it carries the token: `?token=TOKEN` in the URL (what the Foxglove app can send) or an
    `Authorization: Bearer TOKEN` header (a script), compared in constant time; and
  - its Origin, if it has one, is allowed (`allowed_origins`, exact, or `scheme://host:*` for any
    port). A browser always sends the page's Origin, so a page the operator merely opens cannot
    connect; a client with no Origin is not a browser (Foxglove's desktop app, a script) and needs
    only the token.
and it must offer the `foxglove.sdk.v1` subprotocol, the only one the SDK speaks.

The SDK's own port is reachable from this machine too, bypassing the front door. It serves what it
serves to anyone (viewing, as with publishing off), but publishes nothing for a client that did not
come through here: on each relayed connection the front door first advertises, then withdraws, a
channel whose topic holds a secret made at start-up and never sent anywhere else (`hello_topic`).
The view trusts a client's publishing only after its connection said that hello (view_node.py).

    door = FrontDoor(host, port, inner_port, check, on_refused)   # serving once the constructor returns
    door.port                                                      # the bound port (port 0: any free)
    door.close()
"""

from __future__ import annotations

import asyncio
import hmac
import json
import secrets
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from http import HTTPStatus
from typing import TYPE_CHECKING
from urllib.parse import parse_qs, urlsplit

if TYPE_CHECKING:
    from websockets.asyncio.client import ClientConnection
    from websockets.asyncio.server import Server, ServerConnection
    from websockets.http11 import Request, Response

__all__ = ["HELLO_CHANNEL", "SUBPROTOCOL", "TOKEN_ENV", "FrontDoor", "Handshake", "hello_messages", "origin_allowed"]

TOKEN_ENV = "GO2VLM_VIEW_TOKEN"  # where the clients' token is, unless a file is named (secret.py)
SUBPROTOCOL = "foxglove.sdk.v1"
HELLO_CHANNEL = 0xFFFFFFFF  # the hello's client channel id: withdrawn at once, free for the client after


def origin_allowed(origin: str, allowed: Sequence[str]) -> bool:
    """`origin` (a browser's Origin header) is one of `allowed`: exactly (case-insensitive, no trailing
    slash), or an entry `scheme://host:*` matches that host on any port."""
    o = origin.strip().rstrip("/").lower()
    for a in (x.strip().rstrip("/").lower() for x in allowed):
        if o == a or (a.endswith(":*") and o.startswith(a[:-1]) and o[len(a) - 1 :].isdigit()):
            return True
    return False


@dataclass(frozen=True)
class Handshake:
    """The rules a handshake must meet: the token and the allowed Origins."""

    token: str = field(repr=False)
    allowed_origins: tuple[str, ...] = ()

    def refusal(self, path: str, headers: dict[str, str]) -> tuple[int, str] | None:
        """(HTTP status, reason) to refuse a handshake with, or None to let it in. `headers` by
        lower-case name. The reason never repeats what the client sent as a token."""
        origin = headers.get("origin")
        if origin is not None and not origin_allowed(origin, self.allowed_origins):
            allowed = ", ".join(self.allowed_origins) or "none"
            return 403, f"Origin {origin[:100]!r} is not allowed (allowed_origins: {allowed})"
        given = parse_qs(urlsplit(path).query).get("token", [""])[-1]
        auth = headers.get("authorization", "")
        if not given and auth.lower().startswith("bearer "):
            given = auth[7:].strip()
        if not given:
            return 401, "no token: connect to ws://HOST:PORT/?token=TOKEN (or send Authorization: Bearer TOKEN)"
        if not hmac.compare_digest(given.encode(), self.token.encode()):
            return 401, "wrong token"
        return None


def hello_messages(topic: str) -> list[str]:
    """What the front door says first on each relayed connection: advertise the hello, withdraw it."""
    channel = {"id": HELLO_CHANNEL, "topic": topic, "encoding": "json", "schemaName": "go2vlm/hello"}
    return [
        json.dumps({"op": "advertise", "channels": [channel]}),
        json.dumps({"op": "unadvertise", "channelIds": [HELLO_CHANNEL]}),
    ]


class FrontDoor:
    """The authenticating relay in front of the SDK's server; runs its own asyncio loop on a thread."""

    def __init__(
        self,
        host: str,
        port: int,
        inner_port: int,
        rules: Handshake,
        on_refused: Callable[[str], None],
    ) -> None:
        self.hello_topic = f"/_go2vlm/hello/{secrets.token_hex(16)}"
        self._host, self._inner = host, inner_port
        self._rules, self._on_refused = rules, on_refused
        self._loop = asyncio.new_event_loop()
        self._stop: asyncio.Event | None = None
        self._started = threading.Event()
        self._error: BaseException | None = None
        self.port = 0
        self._thread = threading.Thread(target=self._run, args=(port,), name="view-front-door", daemon=True)
        self._thread.start()
        self._started.wait(30)
        if self._error is not None:
            raise self._error
        if not self._started.is_set():
            raise OSError(f"the front door did not start on {host}:{port}")

    def _run(self, port: int) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._serve(port))
        except BaseException as exc:  # noqa: BLE001 - handed to the constructor (a taken port, a bad host)
            self._error = exc
            self._started.set()
        finally:
            self._loop.close()

    async def _serve(self, port: int) -> None:
        from websockets.asyncio.server import serve

        self._stop = asyncio.Event()
        server: Server
        async with serve(
            self._relay,
            self._host,
            port,
            process_request=self._check,
            subprotocols=[SUBPROTOCOL],  # type: ignore[list-item]  # a str is a Subprotocol
            compression=None,  # JPEG and CDR do not deflate; spare the CPU
            max_size=None,
        ) as server:
            self.port = next(iter(server.sockets)).getsockname()[1]
            self._started.set()
            await self._stop.wait()

    def _check(self, connection: ServerConnection, request: Request) -> Response | None:
        headers = {k.lower(): v for k, v in request.headers.raw_items()}
        refused = self._rules.refusal(request.path, headers)
        if refused is None:
            return None
        status, why = refused
        self._on_refused(why)
        return connection.respond(HTTPStatus(status), f"go2vlm view: refused: {why}\n")

    async def _relay(self, client: ServerConnection) -> None:
        from websockets.asyncio.client import connect

        try:
            async with connect(
                f"ws://127.0.0.1:{self._inner}",
                subprotocols=[SUBPROTOCOL],  # type: ignore[list-item]
                compression=None,
                max_size=None,
                proxy=None,
            ) as inner:
                for text in hello_messages(self.hello_topic):
                    await inner.send(text)
                await _pipe_both(client, inner)
        except Exception as exc:  # noqa: BLE001 - the SDK's port gone or refusing: this client ends, the door stays
            self._on_refused(f"the SDK's server did not take the connection: {type(exc).__name__}: {exc}")

    def close(self) -> None:
        if self._stop is not None and self._loop.is_running():
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(5.0)


async def _pipe_both(a: ServerConnection, b: ClientConnection) -> None:
    """Relay frames both ways until either side closes; then close the other."""

    async def pipe(src: ServerConnection | ClientConnection, dst: ServerConnection | ClientConnection) -> None:
        from websockets.exceptions import ConnectionClosed

        try:
            async for frame in src:
                await dst.send(frame)
        except ConnectionClosed:
            pass

    tasks = [asyncio.ensure_future(pipe(a, b)), asyncio.ensure_future(pipe(b, a))]
    _done, pending = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    for t in pending:
        t.cancel()
    await a.close()
    await b.close()
