"""Attack: a web page the operator happens to open drives the robot through `go2vlm view` (docs/safety.md,
the attack table; docs/record_view.md). Browsers apply no same-origin rule to WebSockets: any page's
script can open ws://127.0.0.1:8765 with the `foxglove.sdk.v1` subprotocol, advertise
/emergency_stop/release and send `{"data": "RELEASE"}`, or drive /teleop/cmd_vel (the gate's highest
priority). Here a real WebSocket client plays that page (it sends the page's foreign Origin, as a
browser must), against real processes: a safety gate started latched and `go2vlm view`, with a probe
on the bus.

- The view as shipped (no --publish): the page connects (the SDK checks no handshake) and may look,
  but the server offers no publishing, and the SDK refuses its advertisement with the reason.
- With --publish: the page's handshake is refused (403, "Origin ... is not allowed"), with the token
  in its URL or without; a client without the token gets 401; a client that goes round the front door
  straight to the SDK's loopback port may look but publishes nothing ("did not come in through the
  view's port with the token"); a client with the token is told a release is never taken.
- Nothing of theirs reaches /emergency_stop/release or /teleop/cmd_vel and the gate stays latched; the
  token holder's teleop does reach the bus (so the probe would have seen the others).

Checked once against deliberately broken builds, each failing here: `Handshake.refusal` without its
Origin check (the page gets past the Origin: 401 for want of a token instead of 403, and with the
token it would be in); `ViewNode.client_advertised` without its check that the client came through
the front door (the bypassing client's channels are taken: only the release is refused, not all three).
"""

from __future__ import annotations

import asyncio
import json
import re
import struct
import time
from typing import Any

import pytest
from busutil import Output, Procs, Recorder, wait_for

from go2vlm.bus import Node, running
from go2vlm.bus.topics import ESTOP_RELEASE, SAFETY_STATUS, TELEOP_CMD_VEL
from go2vlm.msgs.geometry_msgs import Twist, Vector3

websockets = pytest.importorskip("websockets")
pytest.importorskip("foxglove")

SUBPROTOCOL = "foxglove.sdk.v1"
TOKEN = "attack-view-token-0123456789"
PAGE = "https://evil.example"  # the page the operator opened; a browser sends its Origin


class Bus:
    """What reaches the bus: the release, teleop, and the gate's e-stop as /safety/status says."""

    def __init__(self) -> None:
        self.node = Node(node_name="attack_probe")
        self.release, self.teleop = Recorder(), Recorder()
        self.estop: list[bool] = []
        ESTOP_RELEASE.subscription(self.node, self.release)
        TELEOP_CMD_VEL.subscription(self.node, self.teleop)
        SAFETY_STATUS.subscription(self.node, lambda m: self.estop.append(bool(json.loads(m.data)["estop"])))


def _view(procs: Procs, *args: str) -> tuple[Output, int, int | None]:
    """A view process: its output, its port, and (with --publish) the SDK's own loopback port."""
    out = Output(procs.start("view", "--port", "0", *args))
    assert out.wait_line("go2vlm view: Foxglove WebSocket on ws://", 60), "".join(out.lines)[-3000:]
    text = "".join(out.lines)
    port = re.search(r"go2vlm view: Foxglove WebSocket on ws://127\.0\.0\.1:(\d+)", text)
    inner = re.search(r"the SDK itself on 127\.0\.0\.1:(\d+)", text)
    assert port is not None
    return out, int(port.group(1)), int(inner.group(1)) if inner else None


async def _handshake(url: str, **kw: Any) -> tuple[int, str]:
    """The HTTP status of a WebSocket handshake (101: in) and the body of a refusal."""
    try:
        async with websockets.connect(url, subprotocols=[SUBPROTOCOL], proxy=None, open_timeout=30, **kw):
            return 101, ""
    except websockets.InvalidStatus as exc:
        return exc.response.status_code, exc.response.body.decode(errors="replace")


def _advertise(*channels: tuple[int, str, str]) -> str:
    chans = [{"id": i, "topic": t, "encoding": "json", "schemaName": s} for i, t, s in channels]
    return json.dumps({"op": "advertise", "channels": chans})


def _data(channel: int, payload: dict[str, Any]) -> bytes:
    return b"\x01" + struct.pack("<I", channel) + json.dumps(payload).encode()


async def _drive(url: str, n_statuses: int, **kw: Any) -> tuple[dict[str, Any], list[str]]:
    """What the page's script does once connected: advertise the release and teleop, send RELEASE and a
    forward twist, and an e-stop `false`; returns the server's info and the status messages it got."""
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], proxy=None, max_size=None, **kw) as ws:
        info = json.loads(await ws.recv())
        await ws.send(_advertise((1, "/emergency_stop/release", "std_msgs/msg/String"),
                                 (2, "/teleop/cmd_vel", "geometry_msgs/msg/Twist"),
                                 (3, "/emergency_stop", "std_msgs/msg/Bool")))  # fmt: skip
        twist = {"linear": {"x": 1.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
        for _ in range(5):
            await ws.send(_data(1, {"data": "RELEASE"}))
            await ws.send(_data(2, twist))
            await ws.send(_data(3, {"data": False}))
        statuses: list[str] = []
        deadline = time.monotonic() + 15
        while len(statuses) < n_statuses and time.monotonic() < deadline:
            try:
                frame = await asyncio.wait_for(ws.recv(), max(0.0, deadline - time.monotonic()))
            except asyncio.TimeoutError:
                break
            if isinstance(frame, str) and json.loads(frame).get("op") == "status":
                statuses.append(json.loads(frame)["message"])
        return info, statuses


async def _teleop_with_token(url: str) -> None:
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], proxy=None) as ws:
        await ws.recv()
        chan = {"id": 8, "topic": "/teleop/cmd_vel", "encoding": "cdr", "schemaName": "geometry_msgs/msg/Twist"}
        await ws.send(json.dumps({"op": "advertise", "channels": [chan]}))
        for _ in range(20):
            await ws.send(b"\x01" + struct.pack("<I", 8) + Twist(linear=Vector3(x=0.1)).serialize())
            await asyncio.sleep(0.05)  # a teleop rate, not synchronisation


def test_a_web_page_cannot_release_the_estop_or_drive_through_the_view(
    procs: Procs, monkeypatch: pytest.MonkeyPatch
) -> None:
    bus = Bus()
    procs.start("run", "safety", "--param", "start_engaged=true")
    with running(bus.node):
        assert wait_for(lambda: bool(bus.estop) and bus.estop[-1], 60), "the gate never reported latched"
        found: dict[str, Any] = {}

        # The view as shipped: the page gets in (the SDK checks nothing), may look, publishes nothing.
        out, port, inner = _view(procs)
        assert inner is None, "no front door without --publish"
        info, statuses = asyncio.run(_drive(f"ws://127.0.0.1:{port}", 1, origin=PAGE))
        assert "clientPublish" not in info.get("capabilities", []), info
        assert statuses and "does not support clientPublish" in statuses[0], statuses  # the SDK's own refusal
        found["shipped: refused"] = statuses[0]

        # --publish: the front door checks the handshake before the SDK sees the client.
        monkeypatch.setenv("GO2VLM_VIEW_TOKEN", TOKEN)
        out, port, inner = _view(procs, "--publish")
        assert inner is not None and inner != port
        base = f"ws://127.0.0.1:{port}"
        t0 = time.monotonic()
        page = asyncio.run(_handshake(base, origin=PAGE))
        found["page refused in ms"] = round((time.monotonic() - t0) * 1000, 1)
        assert page[0] == 403 and f"Origin '{PAGE}' is not allowed" in page[1], page
        page_with_token = asyncio.run(_handshake(f"{base}/?token={TOKEN}", origin=PAGE))
        assert page_with_token[0] == 403 and "is not allowed" in page_with_token[1], page_with_token
        no_token = asyncio.run(_handshake(base))
        assert no_token[0] == 401 and "no token" in no_token[1], no_token
        wrong = asyncio.run(_handshake(base, additional_headers={"Authorization": "Bearer " + "x" * 28}))
        assert wrong[0] == 401 and "wrong token" in wrong[1] and TOKEN not in wrong[1], wrong
        assert out.wait_line("refused a client: Origin 'https://evil.example' is not allowed", 10)

        # Round the front door, straight to the SDK's loopback port: it may look, it publishes nothing.
        info, statuses = asyncio.run(_drive(f"ws://127.0.0.1:{inner}", 3, origin=PAGE))
        assert len(statuses) == 3 and all("did not come in through the view's port" in s for s in statuses), statuses
        found["bypass: refused advertisements"] = len(statuses)

        # The token holder: its teleop reaches the bus (so the probe would have seen the others'), and
        # then its release is refused even so.
        asyncio.run(_teleop_with_token(f"{base}/?token={TOKEN}"))
        assert wait_for(lambda: len(bus.teleop) > 0, 10), "the probe saw no teleop even from the token holder"
        assert all(m.linear.x == pytest.approx(0.1) for m in bus.teleop.msgs()), bus.teleop.msgs()
        found["teleop from the others"] = sum(m.linear.x != pytest.approx(0.1) for m in bus.teleop.msgs())
        _, statuses = asyncio.run(_drive(f"{base}/?token={TOKEN}", 1))
        assert any("never releases the e-stop" in s for s in statuses), statuses
        assert len(bus.release) == 0 and bus.estop[-1] is True, bus.estop[-5:]
        found["on /emergency_stop/release"] = len(bus.release)
    print(f"a web page against go2vlm view: {found}")
