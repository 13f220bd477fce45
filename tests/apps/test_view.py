"""`go2vlm view` as a real process with a real WebSocket client speaking the Foxglove protocol
(subprotocol foxglove.sdk.v1): it receives a JPEG camera image, the safety status and the detector's
annotations; with --publish and the token it advertises and publishes an e-stop that latches a real
safety gate process; its /cmd_vel and its release of the e-stop are refused. (Who may connect at all:
tests/attack/test_attack_view.py.)"""

from __future__ import annotations

import asyncio
import json
import re
import struct
import subprocess
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import websockets
from busutil import GO2VLM, Procs, env, wait_for
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from go2vlm.bus import Node, running
from go2vlm.bus.graph import discover
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.sensor_msgs import CompressedImage
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.msgs.vision_msgs import (
    BoundingBox2D,
    Detection2D,
    Detection2DArray,
    ObjectHypothesis,
    ObjectHypothesisWithPose,
    Point2D,
    Pose2D,
)

SUBPROTOCOL = "foxglove.sdk.v1"
TOKEN = "view-test-token-0123456789"


def server_port(proc: subprocess.Popen[str], timeout: float = 60) -> int:
    """The port from the view's start-up line (`ws://127.0.0.1:PORT`)."""
    deadline = time.monotonic() + timeout
    assert proc.stdout is not None
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            if proc.poll() is not None:
                break
            continue
        m = re.search(r"ws://([\d.]+):(\d+)", line)
        if m:
            assert m.group(1) == "127.0.0.1", line  # loopback unless asked
            return int(m.group(2))
    raise AssertionError("the view never said where it serves")


class Client:
    """A minimal Foxglove WebSocket client: advertise/subscribe in JSON, messages in binary frames."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.channels: dict[str, dict[str, Any]] = {}
        self.subs: dict[int, str] = {}
        self.received: dict[str, list[bytes]] = {}
        self.statuses: list[dict[str, Any]] = []

    async def pump(self, until: Any, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not until():
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            try:
                frame = await asyncio.wait_for(self.ws.recv(), left)
            except asyncio.TimeoutError:
                return False
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg["op"] == "advertise":
                    for ch in msg["channels"]:
                        self.channels[ch["topic"]] = ch
                elif msg["op"] == "status":
                    self.statuses.append(msg)
            elif frame[0] == 0x01:  # message data: sub id, log time, payload
                sub_id, _t = struct.unpack_from("<IQ", frame, 1)
                self.received.setdefault(self.subs[sub_id], []).append(bytes(frame[13:]))
        return True

    async def subscribe(self, *topics: str) -> None:
        subs = []
        for topic in topics:
            sub_id = len(self.subs) + 1
            self.subs[sub_id] = topic
            subs.append({"id": sub_id, "channelId": self.channels[topic]["id"]})
        await self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    async def advertise(self, chan_id: int, topic: str, encoding: str, schema_name: str) -> None:
        channel = {"id": chan_id, "topic": topic, "encoding": encoding, "schemaName": schema_name}
        await self.ws.send(json.dumps({"op": "advertise", "channels": [channel]}))

    async def publish(self, chan_id: int, payload: bytes) -> None:
        await self.ws.send(b"\x01" + struct.pack("<I", chan_id) + payload)


def last_status(client: Client) -> dict[str, Any]:
    return json.loads(String.deserialize(client.received["/safety/status"][-1]).data)


@pytest.fixture
def pipeline(procs: Procs, monkeypatch: pytest.MonkeyPatch) -> tuple[int, subprocess.Popen[str]]:
    procs.start("run", "safety")
    procs.start("run", "test_pattern", "--param", "period_s=0.1")
    procs.start("run", "color_detector")
    monkeypatch.setenv("GO2VLM_VIEW_TOKEN", TOKEN)
    view = procs.start("view", "--port", "0", "--publish")
    return server_port(view), view


def test_view_both_directions(procs: Procs, pipeline: tuple[int, subprocess.Popen[str]]) -> None:
    port, view = pipeline
    vlm = Node(node_name="fake_vlm")
    dets = vlm.create_publisher(Detection2DArray, "/vlm/detections")
    box = BoundingBox2D(center=Pose2D(position=Point2D(x=450, y=150)), size_x=160, size_y=160)
    hyp = ObjectHypothesisWithPose(hypothesis=ObjectHypothesis(class_id="red ball", score=0.9))
    vlm.create_timer(0.1, lambda: dets.publish(Detection2DArray(Header(), [Detection2D(results=[hyp], bbox=box)])))
    confirms: list[str] = []  # a person's answer to `go2vlm mcp --confirm`, from the Publish panel
    vlm.create_subscription(String, "/mcp/confirm", lambda m: confirms.append(m.data))

    async def session() -> Client:
        url = f"ws://127.0.0.1:{port}/?token={TOKEN}"
        async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None, proxy=None) as ws:
            c = Client(ws)
            wanted = (
                "/camera/image_raw/compressed",
                "/safety/status",
                "/detected_target/annotations",
                "/vlm/detections/annotations",
                "/view/robot",
                "/detected_target",
            )
            assert await c.pump(lambda: all(t in c.channels for t in wanted), 60), sorted(c.channels)
            assert c.channels["/camera/image_raw/compressed"]["schemaName"] == "sensor_msgs/msg/CompressedImage"
            assert c.channels["/camera/image_raw/compressed"]["schemaEncoding"] == "ros2msg"
            assert c.channels["/safety/status"]["encoding"] == "cdr"
            assert "/camera/image_raw" not in c.channels  # raw frames are never sent
            assert c.channels["/detected_target/annotations"]["schemaName"] == "foxglove.ImageAnnotations"
            # A channel advertised while we connect can still be unknown to the server's client state
            # for a moment (foxglove-sdk then answers "unknown channel"): subscribe again to what is missing.
            missing = list(wanted)
            for _ in range(4):
                await c.subscribe(*missing)
                await c.pump(lambda: all(c.received.get(t) for t in wanted), 15)
                missing = [t for t in wanted if not c.received.get(t)]
                if not missing:
                    break
            assert not missing, (missing, c.statuses)
            assert last_status(c)["estop"] is False

            # publish: an e-stop (json) is let through, /cmd_vel (cdr) and the release are refused
            await c.advertise(1, "/emergency_stop", "json", "std_msgs/msg/Bool")
            await c.advertise(2, "/cmd_vel", "cdr", "geometry_msgs/msg/Twist")
            await c.advertise(4, "/emergency_stop/release", "json", "std_msgs/msg/String")
            await c.publish(2, Twist(linear=Vector3(x=1.0)).serialize())
            await c.publish(1, b'{"data": true}')
            await c.advertise(3, "/mcp/confirm", "json", "std_msgs/msg/String")
            await c.publish(3, b'{"data": "yes 1"}')
            latched = await c.pump(lambda: bool(c.received["/safety/status"]) and last_status(c)["estop"], 30)
            assert latched, last_status(c)
            await c.publish(4, b'{"data": "RELEASE"}')
            await c.pump(lambda: any("/cmd_vel" in s.get("message", "") for s in c.statuses), 10)
            await c.pump(lambda: any("never releases" in s.get("message", "") for s in c.statuses), 10)
            assert last_status(c)["estop"] is True
            return c

    with running(vlm):
        c = asyncio.run(session())
    image = CompressedImage.deserialize(c.received["/camera/image_raw/compressed"][-1])
    assert image.format == "jpeg" and image.header.frame_id == "camera"
    arr = cv2.imdecode(np.frombuffer(image.data, np.uint8), cv2.IMREAD_COLOR)
    assert arr.shape == (480, 640, 3)
    assert arr[150, 450, 2] > 200 and arr[150, 450, 1] < 60  # the test pattern's red circle survives JPEG
    assert c.channels["/view/robot"]["schemaName"] == "foxglove.SceneUpdate"
    assert c.channels["/detected_target"]["schemaName"] == "geometry_msgs/msg/PointStamped"  # raw, for plots
    assert any(b"red ball" in m for m in c.received["/vlm/detections/annotations"])  # the label, in protobuf
    assert any("refused" in s["message"] and "/cmd_vel" in s["message"] for s in c.statuses), c.statuses
    assert wait_for(lambda: confirms == ["yes 1"], 10), confirms
    # Nobody but the safety gate publishes /cmd_vel.
    seen: dict[str, Any] = {}
    assert wait_for(lambda: bool(seen.update(discover(0.3)) or seen.get("/cmd_vel")), 10)
    assert len(seen["/cmd_vel"].publishers) == 1
    procs.stop(view)
    out = view.stdout.read() if view.stdout else ""
    assert "refused: a client may not publish /cmd_vel" in out, out[-2000:]
    assert "Traceback" not in out


def test_view_usage_errors() -> None:
    out = subprocess.run([*GO2VLM, "view", "--host", " "], capture_output=True, text=True, timeout=60, env=env())
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr
    # --publish without a token (or a short one): refused at start, with the reason, the token never shown.
    for token in ("", "short"):
        e = {**env(), "GO2VLM_VIEW_TOKEN": token}
        out = subprocess.run([*GO2VLM, "view", "--port", "0", "--publish"], capture_output=True, text=True,
                             timeout=60, env=e)  # fmt: skip
        assert out.returncode == 2 and "needs a token of at least 16 characters" in out.stderr, out.stderr
        assert "Traceback" not in out.stderr and (not token or token not in out.stderr)


@pytest.mark.slow
def test_demo_serves_foxglove_live_and_records_a_bag(procs: Procs, tmp_path: Path) -> None:
    """`go2vlm demo --foxglove 0 --bag`: a real WebSocket client sees the sim's camera while the demo
    runs, and rosbags reads the demo's bag back afterwards."""
    out = tmp_path / "demo"
    demo = procs.start(
        "demo", "--duration", "6", "--rtf", "1", "--mode", "kinematic", "--no-video", "--no-progress",
        "--bag", "--foxglove", "0", "--out", str(out),
    )  # fmt: skip
    port = server_port(demo)

    async def session() -> Client:
        async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], max_size=None) as ws:
            c = Client(ws)
            topic = "/camera/image_raw/compressed"
            assert await c.pump(lambda: topic in c.channels, 60), sorted(c.channels)
            for _ in range(4):  # see test_view_both_directions: a fresh channel may be unknown for a moment
                await c.subscribe(topic)
                if await c.pump(lambda: bool(c.received.get(topic)), 15):
                    break
            assert c.received.get(topic), c.statuses
            return c

    c = asyncio.run(session())
    image = CompressedImage.deserialize(c.received["/camera/image_raw/compressed"][-1])
    assert image.format == "jpeg"
    assert demo.wait(timeout=300) == 0, demo.stdout.read() if demo.stdout else ""
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["bag"]["messages"] > 0 and metrics["options"]["bag"] is True
    with AnyReader([out / "bag"], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        n = {t: 0 for t in types}
        for conn, _t, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            n[conn.topic] += 1
    assert types["/camera/image_raw"] == "sensor_msgs/msg/Image" and types["/cmd_vel"] == "geometry_msgs/msg/Twist"
    assert n["/camera/image_raw"] >= 20 and n["/cmd_vel"] > 0 and n["/clock"] > 0, n
