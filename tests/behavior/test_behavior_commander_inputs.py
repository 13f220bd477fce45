"""The commander on synthetic camera frames: VLM grounding (a Detection2DArray seeds the tracker),
bad images / camera info / detections are counted and ignored, and a goal given as a CLI parameter
that cannot be parsed is answered on /commander/status with zero motion through the real gate."""

from __future__ import annotations

import json
import threading
import time

import cv2
import numpy as np
import pytest
from busutil import echo_json, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node, ParamError, running
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import PointStamped, Twist
from go2vlm.msgs.image import camera_info, numpy_to_image
from go2vlm.msgs.sensor_msgs import CameraInfo, Image
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


def frame(cx: int | None) -> np.ndarray:
    img = np.full((480, 640, 3), 150, np.uint8)
    if cx is not None:
        cv2.rectangle(img, (cx - 30, 150), (cx + 30, 400), (255, 0, 0), -1)  # a blue "cylinder", bottom in view
    cv2.circle(img, (120, 330), 50, (0, 0, 255), -1)  # a red ball
    return img


def det(label: str, x1: float, y1: float, x2: float, y2: float, header: Header) -> Detection2D:
    return Detection2D(
        header=header,
        results=[ObjectHypothesisWithPose(hypothesis=ObjectHypothesis(class_id=label, score=1.0))],
        bbox=BoundingBox2D(center=Pose2D(position=Point2D(x=(x1 + x2) / 2, y=(y1 + y2) / 2)), size_x=x2 - x1,
                           size_y=y2 - y1),
    )  # fmt: skip


class _Cam(Node):
    name = "fake_camera"

    def __init__(self, **kw) -> None:
        super().__init__(**kw)
        self.lock = threading.Lock()
        self.cx: int | None = 400
        self.img = self.create_publisher(Image, "/camera/image_raw", QOS_DEFAULT)
        self.info = self.create_publisher(CameraInfo, "/camera/camera_info", QOS_DEFAULT)
        self.dets = self.create_publisher(Detection2DArray, "/vlm/detections", QOS_DEFAULT)
        self.status: list[dict] = []
        self.targets: list[PointStamped] = []
        self.cmds: list[tuple[float, float]] = []
        self.headers: list[Header] = []
        self.create_subscription(String, "/commander/status", self._st, QOS_LATCHED)
        self.create_subscription(Twist, "/behavior/cmd_vel", lambda m: self.cmds.append((m.linear.x, m.angular.z)),
                                 QOS_DEFAULT)  # fmt: skip
        self.create_subscription(PointStamped, "/detected_target", self.targets.append, QOS_DEFAULT)
        self.create_timer(0.1, self.tick)

    def _st(self, m: String) -> None:
        with self.lock:
            self.status.append(json.loads(m.data))

    def tick(self) -> None:
        h = Header(stamp=self.stamp(), frame_id="camera")
        self.headers.append(h)
        self.img.publish(numpy_to_image(frame(self.cx), "bgr8", h))
        self.info.publish(camera_info(PinholeCamera.from_hfov(640, 480, 1.274)))

    def last(self) -> dict:
        with self.lock:
            return self.status[-1] if self.status else {}


def test_vlm_grounding_seeds_the_tracker_and_bad_inputs_are_counted() -> None:
    commander = make_node("commander", params={"goal": "go to the blue cylinder", "grounding": "vlm"})
    cam = _Cam()
    with running(cam, commander):
        assert wait_for(lambda: cam.dets.matched >= 1 and cam.img.matched >= 1, 10)
        assert wait_for(lambda: cam.last().get("state") == "searching" and len(cam.headers) > 3, 5)  # no VLM answer
        # Garbage first: a truncated image, a CameraInfo with fx = 0, a detection with a NaN box.
        cam.img.publish(Image(height=480, width=640, encoding="bgr8", step=1920, data=b"\x00" * 100))
        cam.info.publish(CameraInfo(width=640, height=480, k=[0.0] * 9))
        h = cam.headers[-1]
        bad = det("blue cylinder", 0, 0, 10, 10, h)
        bad.bbox.size_x = float("nan")
        cam.dets.publish(Detection2DArray(header=h, detections=[bad]))
        assert wait_for(lambda: cam.last().get("counters", {}).get("bad_images", 0) >= 1, 5), cam.last()
        assert wait_for(lambda: cam.last().get("counters", {}).get("bad_detections", 0) >= 1, 5), cam.last()
        assert cam.last()["counters"].get("bad_camera_info", 0) >= 1
        assert cam.last()["state"] == "searching"
        # A VLM answer about a frame 1 s old: the red ball is no match, the blue cylinder is.
        time.sleep(1.0)
        old = cam.headers[-10]
        cam.dets.publish(Detection2DArray(header=old, detections=[
            det("red ball", 70, 280, 170, 380, old), det("blue cylinder", 370, 150, 430, 400, old)]))  # fmt: skip
        assert wait_for(lambda: cam.last().get("state") == "approaching", 5), cam.last()
        st = cam.last()
        assert st["seen"] and abs(st["x"] - (400 - 320) / 320) < 0.05
        assert st["counters"].get("vlm_reseeds") == 1
        assert 1.0 < st["distance_m"] < 3.0  # bottom-edge ranging from the CameraInfo
        # The tracker follows the object (no new VLM answer) as it moves across the image.
        cam.cx = 330
        assert wait_for(lambda: abs(cam.last().get("x") or 1) < 0.05, 5), cam.last()
        assert wait_for(lambda: cam.cmds and cam.cmds[-1][0] > 0.05, 5)  # centred: walking
        assert not cam.targets  # go to drives itself; /detected_target is for follow goals only


def test_losing_the_target_stops_at_once_then_searches_towards_where_it_was() -> None:
    commander = make_node("commander", params={"goal": "go to the blue cylinder", "lost_timeout_s": 0.5})
    cam = _Cam()
    with running(cam, commander):
        assert wait_for(lambda: cam.last().get("state") == "approaching", 10), cam.last()
        assert cam.last()["x"] > 0.2  # on the right
        cam.cx = None  # gone
        assert wait_for(lambda: cam.last().get("state") == "lost", 3), cam.last()
        assert wait_for(lambda: cam.cmds[-1] == (0.0, 0.0), 1)
        assert wait_for(lambda: cam.last().get("state") == "searching", 3), cam.last()
        assert wait_for(lambda: cam.cmds[-1][1] < -0.1, 1)  # turning right, where it was last seen
        assert all(vx == 0.0 for vx, _ in cam.cmds[-5:])  # searching = turning in place
        cam.cx = 500  # back in view: approach again
        assert wait_for(lambda: cam.last().get("state") == "approaching", 5), cam.last()


def test_unparseable_goal_parameter_gets_a_reply_and_no_motion(procs) -> None:
    procs.start("run", "commander", "--param", "goal=please do a backflip")
    procs.start("run", "safety")
    status = echo_json("/commander/status", count=1, timeout=30)[0]
    data = json.loads(status["data"])
    assert data["state"] == "rejected" and data["goal"] == "please do a backflip"
    assert "cannot understand" in data["reason"] and "accepted goals" in data["reason"]
    cmds = echo_json("/cmd_vel", count=10, timeout=30)
    assert all(c["linear"]["x"] == 0.0 and c["angular"]["z"] == 0.0 for c in cmds)


def test_bad_parameters_are_clear_errors() -> None:
    with pytest.raises(ParamError, match="decision_model"):
        make_node("commander", params={"decision_period_s": 1.0})
    with pytest.raises(ParamError, match="object_sizes"):
        make_node("commander", params={"object_sizes": {"pyramid": 1.0}})
    with pytest.raises(ParamError, match="max_turn_deg"):
        make_node("commander", params={"max_turn_deg": 45})
    with pytest.raises(ParamError, match="grounding"):
        make_node("commander", params={"grounding": "lidar"})
