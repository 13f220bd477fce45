"""The go2 driver over WebRTC against the simulator's WebRTC server, on loopback.

One module harness, in this process: the sim (`webrtc: true`, kinematic), the driver
(`transport: webrtc`), the safety gate and a probe node, over real DDS, with a real aiortc peer
connection between the driver and the sim. The tests run in order: the route works, bad messages are
dropped both ways, the e-stop damps, a dropped link stops and reconnects, a foreign controller and a
WebRTC takeover latch the e-stop. The start-up errors run `go2vlm run go2` as a process.

ICE picks the host's own addresses (aioice leaves 127.0.0.1 out), so the media never leaves this host.
"""

from __future__ import annotations

import json
import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import pytest
from busutil import GO2VLM, Recorder, env, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_IMAGE, QOS_LATCHED, QOS_SENSOR, QOS_UNITREE_WRITER, Node
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.sensor_msgs import Image, LaserScan
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.msgs.unitree import LowState, Request
from go2vlm.robots.go2 import protocol as p
from go2vlm.robots.go2.webrtc import codec

pytest.importorskip("aiortc", reason="the webrtc extra: pip install 'go2vlm[webrtc]'")

pytestmark = pytest.mark.slow

REMAP = {
    "/cmd_vel": "/sim/cmd_vel",
    "/odom": "/sim/odom",
    "/imu": "/sim/imu",
    "/tf": "/sim/tf",
    "/scan": "/sim/scan",
    "/camera/image_raw": "/sim/camera/image_raw",
    "/camera/camera_info": "/sim/camera/camera_info",
}


def free_port(host: str = "127.0.0.1") -> int:
    with socket.socket() as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


class Harness:
    def __init__(self) -> None:
        self.port = free_port()
        self.sim = make_node(
            "sim",
            params={
                "mode": "kinematic",
                "world": "vision_test",
                "world_camera": False,
                "camera_width": 320,
                "camera_height": 240,
                "webrtc": True,
                "webrtc_port": self.port,
                "webrtc_takeover": True,
            },
            remap=REMAP,
        )
        self.driver = make_node(
            "go2",
            params={
                "transport": "webrtc",
                "ip": "127.0.0.1",
                "signal_port": self.port,
                "stand_on_start": True,
                "rpc_timeout_s": 5.0,
            },
        )
        self.gate = make_node("safety", params={"robot": "go2", "max_vx_forward": 0.5})
        n = self.probe = Node(node_name="go2_webrtc_probe")
        self.odom, self.images, self.scans, self.lows = Recorder(), Recorder(), Recorder(), Recorder()
        self.status, self.sim_status, self.gate_cmd = Recorder(), Recorder(), Recorder()
        n.create_subscription(Odometry, "/odom", self.odom)
        n.create_subscription(Image, "/camera/image_raw", self.images, QOS_IMAGE)
        n.create_subscription(LaserScan, "/scan", self.scans, QOS_SENSOR)
        n.create_subscription(LowState, "/go2/lowstate", self.lows, QOS_SENSOR)
        n.create_subscription(String, "/go2/status", lambda m: self.status(json.loads(m.data)), QOS_LATCHED)
        n.create_subscription(String, "/sim/status", lambda m: self.sim_status(json.loads(m.data)), QOS_LATCHED)
        n.create_subscription(Twist, "/cmd_vel", self.gate_cmd)
        self.teleop = n.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)
        self.estop = n.create_publisher(Bool, "/emergency_stop", QOS_LATCHED)
        self.release = n.create_publisher(String, "/emergency_stop/release", QOS_DEFAULT)
        self.rogue = n.create_publisher(Request, p.request_topic(p.SPORT_SERVICE), QOS_UNITREE_WRITER)
        for node in (self.sim, self.driver, self.gate, self.probe):
            node.start()

    def close(self) -> None:
        for node in (self.probe, self.gate, self.driver, self.sim):
            node.shutdown()

    def last(self, rec: Recorder) -> Any:
        msgs = rec.msgs()
        return msgs[-1] if msgs else None

    def x(self) -> float:
        return self.odom.msgs()[-1].pose.pose.position.x

    def sim_mode(self) -> str:
        s = self.last(self.sim_status)
        return s["mode"] if s else ""

    def drive(self, vx: float, until: Any, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if until():
                return True
            self.teleop.publish(Twist(linear=Vector3(vx, 0.0, 0.0)))
            time.sleep(0.05)  # the teleop rate, not synchronisation
        return until()


@pytest.fixture(scope="module")
def h() -> Iterator[Harness]:
    harness = Harness()
    try:
        yield harness
    finally:
        harness.close()


def test_the_route_works(h: Harness) -> None:
    """State, camera, lidar and lowstate arrive over WebRTC; a teleop command walks the robot."""
    assert wait_for(lambda: (s := h.last(h.status)) is not None and s["link"]["connected"], 20)
    assert wait_for(lambda: (h.last(h.status) or {}).get("mode") == "balance_stand", 20)  # stand_on_start
    status = h.last(h.status)
    assert status["transport"] == "webrtc" and status["link"]["firmware"] == p.SIM_FIRMWARE
    assert wait_for(lambda: len(h.images) >= 3 and len(h.scans) >= 3 and len(h.lows) >= 3 and len(h.odom) > 5, 30)
    img = h.images.msgs()[-1]
    assert (img.width, img.height, img.encoding) == (320, 240, "bgr8")
    x0 = h.x()
    assert h.drive(0.3, lambda: h.x() > x0 + 0.15, 20), f"the robot did not walk: x {x0:.3f} -> {h.x():.3f}"
    assert h.driver.moves_sent > 0 and h.sim.bridge.moves > 0


def test_malformed_messages_are_counted_and_dropped(h: Harness) -> None:
    """Garbage from the robot reaches the driver's real data channel: counted, dropped, the driver goes on;
    garbage to the robot: the sim counts it and keeps serving."""
    peer = h.sim.webrtc.peer
    bad = [
        "not json",
        codec.message(p.DC_MSG, p.RTC_SPORT_STATE, {"position": "nowhere"}),
        codec.message(p.DC_MSG, p.RTC_LOW_STATE, {"motor_state": 5}),
        codec.encode_binary({"type": p.DC_MSG, "topic": p.RTC_LIDAR_VOXELS, "data": {"src_size": 3}}, b"\x00"),
        b"\x01",
    ]
    for raw in bad:
        h.sim.webrtc._loop.call_soon_threadsafe(peer.send, raw)
    assert wait_for(lambda: h.driver.counters.get("webrtc_bad_messages", 0) >= 3, 10)
    assert wait_for(lambda: h.driver.link.link.counters.get("bad_messages", 0) >= len(bad), 10)
    n = len(h.odom)
    assert wait_for(lambda: len(h.odom) > n + 10, 5), "the driver stopped publishing"
    for raw in ("{}", "[", codec.message(p.DC_REQUEST, p.RTC_SPORT_REQUEST, {"header": {}}), b"\x00\x01"):
        h.driver.link.link.send(raw)
    assert wait_for(lambda: h.sim.counters.get("webrtc_bad_messages", 0) >= 4, 10)
    assert h.last(h.status)["link"]["connected"]


def test_estop_damps_over_webrtc(h: Harness) -> None:
    h.estop.publish(Bool(data=True))
    assert wait_for(lambda: h.sim_mode() == "damped", 15), h.sim_mode()
    assert wait_for(lambda: h.driver._damp_acked, 10)
    h.release.publish(String(data="RELEASE"))
    assert wait_for(lambda: not h.driver.estop.engaged and not h.sim.estop.engaged, 10)
    h.estop.publish(Bool(data=False))  # the latched sample: `false` does not latch again
    h.driver.run_command("recover")
    assert wait_for(lambda: (h.last(h.status) or {}).get("last_command", {}).get("name") == "recover", 15)
    h.driver.run_command("balance")
    assert wait_for(lambda: h.sim_mode() in ("standing", "walking"), 15)


def test_a_dropped_link_stops_the_robot_and_reconnects(h: Harness) -> None:
    """The sim's WebRTC side goes silent: the driver says the link is down, the gate holds zero (the
    lowstate stream is gone), nothing is sent while down, and the link comes back by itself."""
    assert wait_for(lambda: h.last(h.status)["link"]["connected"], 10)
    connects = h.driver.link.link.connects
    stop = threading.Event()

    def teleop() -> None:
        while not stop.is_set():
            h.teleop.publish(Twist(linear=Vector3(0.2, 0.0, 0.0)))
            time.sleep(0.05)

    t = threading.Thread(target=teleop, daemon=True)
    t.start()
    try:
        assert wait_for(lambda: h.last(h.gate_cmd) is not None and h.last(h.gate_cmd).linear.x > 0.05, 15)
        h.sim.webrtc._loop.call_soon_threadsafe(time.sleep, 3.0)  # the robot's WebRTC side freezes
        assert wait_for(lambda: not h.driver.link.link.connected, 5)
        assert wait_for(lambda: h.last(h.gate_cmd).linear.x == 0.0, 5), "the gate did not stop"
        assert wait_for(lambda: h.driver.counters.get("link_down", 0) >= 1, 5)
        assert wait_for(lambda: not h.last(h.status)["link"]["connected"], 5)  # the driver says so
        moves = h.driver.moves_sent
        assert wait_for(lambda: h.driver.link.link.connects > connects, 30), "no reconnect"
        assert h.driver.link.link.connected
        assert not h.driver.estop.engaged  # silence is not a takeover
        assert wait_for(lambda: h.driver.moves_sent > moves, 20), "the robot does not move again"
    finally:
        stop.set()
        t.join()


def _set_sim(name: str, value: str) -> None:
    r = subprocess.run([*GO2VLM, "param", "set", "sim", name, value], capture_output=True, text=True, env=env(),
                       timeout=60)  # fmt: skip
    assert r.returncode == 0, r.stderr


def test_a_stalled_data_channel_with_live_video_sends_no_move(h: Harness) -> None:
    """The data channel goes silent while the video goes on (the sim's fault_webrtc_silent): no Move is
    sent (the driver sends none on a channel silent for 0.5 s, whatever the video does; the gate also
    stops on the state stream that channel carried); once the channel speaks again, Moves resume."""
    assert wait_for(lambda: h.last(h.status)["link"]["connected"], 30)
    stop = threading.Event()

    def teleop() -> None:
        while not stop.is_set():
            h.teleop.publish(Twist(linear=Vector3(0.2, 0.0, 0.0)))
            time.sleep(0.05)  # the teleop rate, not synchronisation

    t = threading.Thread(target=teleop, daemon=True)
    t.start()
    link = h.driver.link.link
    try:
        moves = h.driver.moves_sent
        assert wait_for(lambda: h.driver.moves_sent > moves + 5, 30), "no Moves to begin with"
        _set_sim("fault_webrtc_silent", "true")
        assert wait_for(lambda: time.monotonic() - link.channel_heard > 0.6, 10), "the channel still speaks"
        moves, frames = h.driver.moves_sent, len(h.images)
        assert wait_for(lambda: len(h.images) > frames + 10, 20), "the video stopped too"
        assert h.driver.moves_sent == moves, "a Move was sent while the data channel was silent"
        # The driver's own rule, whatever the gate does: a Move (zero here) is refused on the silent channel.
        assert link.connected and not h.driver.sport.send_noreply(p.MOVE, {"x": 0.0, "y": 0.0, "z": 0.0})
        assert link.counters.get("quiet_link", 0) >= 1
        _set_sim("fault_webrtc_silent", "false")
        assert wait_for(lambda: h.driver.moves_sent > moves, 30), "Moves did not resume"
    finally:
        stop.set()
        t.join()
        _set_sim("fault_webrtc_silent", "false")


def _doctor(port: int) -> subprocess.CompletedProcess[str]:
    skip = [a for c in ("render", "torch", "peers", "cmd_vel", "rcvbuf") for a in ("--skip", c)]
    args = ["doctor", "--robot", "127.0.0.1", "--robot-port", str(port), *skip]
    return subprocess.run([*GO2VLM, *args], capture_output=True, text=True, env=env(), timeout=90)


def test_doctor_sees_the_app_holding_the_robot(h: Harness) -> None:
    """`go2vlm doctor --robot`: the robot answers, its protocol, and another client (here the driver,
    as the phone app would be) holding the one connection."""
    assert wait_for(lambda: h.driver.link.link.connected, 30)
    h.sim.webrtc.takeover = False
    try:
        proc = _doctor(h.port)
    finally:
        h.sim.webrtc.takeover = True
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "[  ok] webrtc.robot: 127.0.0.1 answers" in proc.stdout
    assert "webrtc.signalling: con_notify" in proc.stdout and "data2=2" in proc.stdout
    assert "[FAIL] webrtc.connection: another WebRTC client holds the robot" in proc.stdout
    assert h.driver.link.link.connected and not h.driver.estop.engaged  # a rejected probe disturbs nothing


def test_a_foreign_sport_request_latches_the_estop(h: Harness) -> None:
    """Another client on the robot's DDS (relayed over WebRTC as rt/api/sport/request) commands it."""
    assert wait_for(lambda: h.driver.link.link.connected and h.sim.webrtc.peer.validated, 30)
    assert wait_for(lambda: p.RTC_SPORT_REQUEST in h.sim.webrtc.peer.topics, 10)
    h.rogue.publish(p.build_request(p.BALANCE_STAND))
    assert wait_for(lambda: h.driver.estop.engaged, 10)
    assert wait_for(lambda: h.sim_mode() == "damped", 15)
    assert h.last(h.status) is not None and h.driver.foreign["requests"] >= 1
    h.release.publish(String(data="RELEASE"))
    assert wait_for(lambda: not h.driver.estop.engaged, 10)


def test_a_webrtc_takeover_latches_the_estop(h: Harness) -> None:
    """Another WebRTC client (as the phone app) takes the robot's connection over: the driver damps."""
    from go2vlm.robots.go2.webrtc.link import Go2Link, LinkSettings

    events: list[tuple[bool, str]] = []
    other = Go2Link(
        LinkSettings(ip="127.0.0.1", port=h.port),
        on_message=lambda m, b: None,
        on_link=lambda u, r: events.append((u, r)),
    )
    try:
        other.connect_first()
        assert wait_for(lambda: h.driver.estop.engaged, 10), "the driver did not latch on the takeover"
        writers = h.driver.foreign["writers"]
        assert any("WebRTC" in w for w in writers), writers
        assert wait_for(lambda: h.driver.link.link.connected and h.driver._damp_acked, 30)
        assert wait_for(lambda: h.sim_mode() == "damped", 15)
    finally:
        other.stop()


def test_doctor_checks_the_robot(h: Harness) -> None:
    """Last: with takeover the doctor's probe takes the connection (the driver damps, as it should)."""
    proc = _doctor(h.port)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "[  ok] webrtc.connection: WebRTC connected and validated" in proc.stdout
    assert f"[  ok] webrtc.firmware: {p.SIM_FIRMWARE} (the go2vlm simulator)" in proc.stdout
    nobody = _doctor(free_port())
    assert nobody.returncode == 1 and "[FAIL] webrtc.robot: nothing answers at 127.0.0.1" in nobody.stdout


# -- start-up errors: one line, exit 2 -----------------------------------------------------------
class _Robot(BaseHTTPRequestHandler):
    answer: bytes | None = b""

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
        pass

    def do_POST(self) -> None:  # noqa: N802
        if self.answer is None:
            time.sleep(30)  # a robot that accepts and never answers
            return
        self.send_response(200)
        self.send_header("Content-Length", str(len(self.answer)))
        self.end_headers()
        self.wfile.write(self.answer)


def _fake_robot(answer: bytes | None) -> tuple[ThreadingHTTPServer, int]:
    handler = type("Robot", (_Robot,), {"answer": answer})
    server = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, server.server_address[1]


def _run_driver(port: int, ip: str = "127.0.0.1") -> subprocess.CompletedProcess[str]:
    args = ["run", "go2", "--param", "transport=webrtc", "--param", f"ip={ip}", "--param", f"signal_port={port}"]
    return subprocess.run(
        [*GO2VLM, *args, "--param", "connect_timeout_s=3"], capture_output=True, text=True, env=env(), timeout=60
    )


def _notify(envelope: object) -> bytes:
    import base64

    return base64.b64encode(json.dumps(envelope).encode())


@pytest.mark.parametrize(
    ("answer", "says"),
    [
        ("nobody", "no Go2 answers at"),
        (b"<html>hello</html>", "not base64 JSON"),
        (_notify({"data1": "x" * 60, "data2": 9}), "data2=9, a protocol go2vlm does not know"),
        (None, "did not answer"),
    ],
    ids=["wrong-ip", "unparseable", "unknown-protocol", "no-answer"],
)
def test_start_up_errors_are_one_line_exit_2(answer: bytes | str | None, says: str) -> None:
    if answer == "nobody":
        proc = _run_driver(free_port())  # nothing listens there
    else:
        server, port = _fake_robot(answer if isinstance(answer, bytes) or answer is None else None)
        try:
            proc = _run_driver(port)
        finally:
            server.shutdown()
            server.server_close()
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2, proc.stderr
    assert says in lines[-1] and "Traceback" not in proc.stderr, proc.stderr
    assert lines[-1].startswith("go2vlm run:"), lines
