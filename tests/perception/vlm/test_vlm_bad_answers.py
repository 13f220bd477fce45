"""Bad VLM answers move nothing unsafe, end to end with real processes: the vlm node (a real tiny
Qwen2.5-VL, or the openai backend against a loopback HTTP server that fails), the target_tracker
(grounding=vlm), the commander and the safety gate, fed a synthetic camera over real DDS.

- a wrong label (the model names other objects than the goal's): the tracker gets empty answers;
- a box on the wrong object (the goal's label on an object of another colour): refused;
- a server that answers HTTP 500, then one that hangs: no answers at all.
In each case a real object of the goal's kind is in plain view, and the robot only searches (turns in
place): it never drives toward a box the tracker cannot confirm."""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import cv2
import numpy as np
import pytest
from busutil import wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node, running
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.msgs.geometry_msgs import Twist
from go2vlm.msgs.image import camera_info, numpy_to_image
from go2vlm.msgs.sensor_msgs import CameraInfo, Image
from go2vlm.msgs.std_msgs import String

# Slow: a tiny model or a failing server, with four node processes.
pytestmark = pytest.mark.slow

# Where the tiny model's answer (tiny_qwen.DEFAULT_ANSWER) puts its boxes in a 480x640 frame.
RED_BALL_BOX = (80, 120, 280, 360)
GREEN_BOX_BOX = (360, 40, 600, 240)


def scene(decoy: str) -> np.ndarray:
    """A red ball and a blue cylinder in plain view, away from the model's boxes, plus a decoy of the
    wrong colour exactly where the model says "red ball" (`decoy`: "blue" or "none")."""
    img = np.full((480, 640, 3), 150, np.uint8)
    cv2.circle(img, (470, 380), 45, (0, 0, 230), -1)  # the real red ball
    cv2.rectangle(img, (300, 250), (340, 470), (230, 60, 0), -1)  # the real blue cylinder
    if decoy == "blue":
        x1, y1, x2, y2 = RED_BALL_BOX
        cv2.rectangle(img, (x1 + 20, y1 + 20), (x2 - 20, y2 - 20), (230, 60, 0), -1)
    return img


class Rig(Node):
    """The camera, the goal, and recorders for what the nodes say and command."""

    name = "bad_answer_rig"

    def __init__(self, **kw) -> None:
        super().__init__(**kw)
        self.lock = threading.Lock()
        self.frame = scene("none")
        self.img = self.create_publisher(Image, "/camera/image_raw", QOS_DEFAULT)
        self.info = self.create_publisher(CameraInfo, "/camera/camera_info", QOS_DEFAULT)
        self.goal = self.create_publisher(String, "/goal", QOS_DEFAULT)
        self.behavior: list[tuple[float, float, float]] = []  # monotonic, vx, wz
        self.cmd: list[tuple[float, float, float]] = []
        self.status: dict[str, list[dict]] = {"commander": [], "tracker": [], "vlm": []}
        self.create_subscription(Twist, "/behavior/cmd_vel", lambda m: self._twist(self.behavior, m), QOS_DEFAULT)
        self.create_subscription(Twist, "/cmd_vel", lambda m: self._twist(self.cmd, m), QOS_DEFAULT)
        self.create_subscription(String, "/commander/status", lambda m: self._st("commander", m), QOS_LATCHED)
        self.create_subscription(String, "/target_tracker/status", lambda m: self._st("tracker", m), QOS_LATCHED)
        self.create_subscription(String, "/vlm/status", lambda m: self._st("vlm", m), QOS_DEFAULT)
        self.create_timer(0.1, self._tick)

    def _twist(self, into: list, m: Twist) -> None:
        with self.lock:
            into.append((time.monotonic(), m.linear.x, m.angular.z))

    def _st(self, key: str, m: String) -> None:
        with self.lock:
            self.status[key].append(json.loads(m.data))

    def _tick(self) -> None:
        self.img.publish(numpy_to_image(self.frame, "bgr8", self.header("camera")))
        self.info.publish(camera_info(PinholeCamera.from_hfov(640, 480, 1.274)))

    def last(self, key: str) -> dict:
        with self.lock:
            return self.status[key][-1] if self.status[key] else {}

    def counter(self, key: str, name: str) -> int:
        return int(self.last(key).get("counters", self.last(key).get("errors", {})).get(name, 0))

    def since(self, t: float) -> tuple[list, list]:
        with self.lock:
            return [b for b in self.behavior if b[0] > t], [c for c in self.cmd if c[0] > t]


def _start_rest(procs, goal: str) -> None:
    procs.start("run", "target_tracker", "--param", "grounding=vlm")
    procs.start("run", "commander", "--param", f"goal={goal}", "--param", "search_timeout_s=600")
    procs.start("run", "safety")


def _only_searching(rig: Rig, t: float, label: str) -> None:
    """Since `t`: the commander searched for `label`, turning in place; nothing moved forward."""
    assert wait_for(lambda: len(rig.since(t)[0]) > 20 and len(rig.since(t)[1]) > 50, 20)
    behavior, cmd = rig.since(t)
    assert all(vx == 0.0 for _, vx, _ in behavior), "the commander drove toward an unconfirmed box"
    assert all(vx == 0.0 for _, vx, _ in cmd), "the gate passed a forward velocity"
    assert any(abs(wz) > 0.1 for *_, wz in cmd)  # the search turn reaches the robot: the loop is live
    st = rig.last("commander")
    assert st["state"] == "searching" and st["target"] == label and not st["seen"], st


def test_a_wrong_label_and_a_box_on_the_wrong_object_move_nothing(procs, tiny_ckpt: Path) -> None:
    rig = Rig()
    with running(rig):
        procs.start(
            "run", "vlm",
            "--param", f"model={tiny_ckpt}",
            "--param", "mode=detect",
            "--param", "device=cpu",
            "--param", "max_pixels=12544",
            "--param", "max_new_tokens=96",
            "--param", "period_s=0.3",
        )  # fmt: skip
        _start_rest(procs, "go to the blue cylinder")
        # The model names a red ball and a green box: nothing labelled "blue cylinder" comes back.
        assert wait_for(lambda: rig.counter("tracker", "empty_answers") >= 3, 180), rig.last("tracker")
        t = time.monotonic()

        # Each answer is refused for `why` (or, on a busy machine, because its frame is too old).
        def refused(why: str) -> int:
            return rig.counter("tracker", f"refused.{why}") + rig.counter("tracker", "refused.stale")

        # Each empty answer: no box matches.
        assert wait_for(lambda: refused("no_match") >= rig.counter("tracker", "empty_answers"), 30), rig.last("tracker")
        _only_searching(rig, t, "blue cylinder")
        assert rig.last("tracker")["state"] == "searching" and rig.counter("tracker", "accepted") == 0
        # Now the goal's label on the wrong object: "red ball" where a blue box stands.
        rig.frame = scene("blue")
        rig.goal.publish(String(data="go to the red ball"))
        assert wait_for(lambda: rig.counter("tracker", "refused.color_mismatch") >= 3, 60), rig.last("tracker")
        t = time.monotonic()
        n = refused("color_mismatch")  # each later answer is refused too: the colour
        assert wait_for(lambda: refused("color_mismatch") >= n + 2, 60), rig.last("tracker")
        _only_searching(rig, t, "red ball")
        assert rig.counter("tracker", "accepted") == 0 and rig.last("tracker")["query"] == "red ball"
        with rig.lock:
            said = [st.get("last_refusal", "") for st in rig.status["tracker"]]
        assert any("% red" in why for why in said), said[-3:]


class _FailingServer:
    """An OpenAI-compatible endpoint on loopback that answers HTTP 500, or hangs, to every request."""

    def __init__(self) -> None:
        self.mode = "500"
        self.requests = 0
        self.release = threading.Event()
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:  # noqa: N802 - http.server's name
                outer.requests += 1
                self.rfile.read(int(self.headers.get("Content-Length", 0)))
                if outer.mode == "hang":
                    outer.release.wait(60)  # far beyond the client's timeout
                    return
                body = b'{"error": {"message": "internal error", "type": "server_error"}}'
                self.send_response(500)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args: object) -> None:
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.httpd.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.release.set()
        self.httpd.shutdown()
        self.httpd.server_close()


def test_a_server_that_fails_or_hangs_moves_nothing(procs) -> None:
    pytest.importorskip("openai")
    server = _FailingServer()
    rig = Rig()
    try:
        with running(rig):
            procs.start(
                "run", "vlm",
                "--param", "backend=openai",
                "--param", f"base_url={server.url}",
                "--param", "model=failing-test-server",
                "--param", "mode=detect",
                "--param", "timeout_s=1.0",
                "--param", "retries=1",
                "--param", "period_s=0.2",
                "--param", "status_period_s=0.3",
            )  # fmt: skip
            _start_rest(procs, "go to the red ball")

            def errors() -> int:
                st = [s for s in rig.status["vlm"] if s.get("model") == "failing-test-server"]
                return int(st[-1]["errors"].get("backend_errors", 0)) if st else 0

            assert wait_for(lambda: errors() >= 3, 60), rig.last("vlm")
            t = time.monotonic()
            _only_searching(rig, t, "red ball")  # a red ball is in plain view: it is not approached
            assert server.requests >= 6  # each failure was retried once
            server.mode = "hang"
            n = errors()
            assert wait_for(lambda: errors() >= n + 2, 30), rig.last("vlm")  # timeouts, counted
            t = time.monotonic()
            _only_searching(rig, t, "red ball")
            assert rig.counter("tracker", "accepted") == 0 and rig.last("tracker")["state"] == "searching"
    finally:
        server.close()
