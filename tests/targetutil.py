"""A synthetic camera scene for the target_tracker and commander tests: 640x480 frames with a blue
"cylinder" (a tall rectangle standing on the floor) and a red ball, a camera node that publishes them
at 10 Hz with a CameraInfo, stands in for the vlm node's answers and queries, and records what the
target_tracker and the commander say."""

from __future__ import annotations

import json
import threading

import cv2
import numpy as np

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.msgs.geometry_msgs import PointStamped, Twist
from go2vlm.msgs.go2vlm_msgs import TrackedTarget
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
    """The scene with the blue object centred at column `cx` (None: not there)."""
    img = np.full((480, 640, 3), 150, np.uint8)
    if cx is not None:
        cv2.rectangle(img, (cx - 30, 150), (cx + 30, 400), (255, 0, 0), -1)  # a blue "cylinder", bottom in view
    cv2.circle(img, (120, 330), 50, (0, 0, 255), -1)  # a red ball
    return img


def det(label: str, x1: float, y1: float, x2: float, y2: float, header: Header) -> Detection2D:
    """One detection as the vlm node publishes it (centre and size, label in class_id)."""
    return Detection2D(
        header=header,
        results=[ObjectHypothesisWithPose(hypothesis=ObjectHypothesis(class_id=label, score=1.0))],
        bbox=BoundingBox2D(center=Pose2D(position=Point2D(x=(x1 + x2) / 2, y=(y1 + y2) / 2)), size_x=x2 - x1,
                           size_y=y2 - y1),
    )  # fmt: skip


class Cam(Node):
    """A camera at 10 Hz whose blue object sits at `cx` (None: gone), a VLM stand-in publishing
    detections and queries, and recorders for what the target_tracker and the commander say."""

    name = "fake_camera"

    def __init__(self, **kw) -> None:
        super().__init__(**kw)
        self.lock = threading.Lock()
        self.cx: int | None = 400
        self.img = self.create_publisher(Image, "/camera/image_raw", QOS_DEFAULT)
        self.info = self.create_publisher(CameraInfo, "/camera/camera_info", QOS_DEFAULT)
        self.dets = self.create_publisher(Detection2DArray, "/vlm/detections", QOS_DEFAULT)
        self.query = self.create_publisher(String, "/target/query", QOS_LATCHED)
        self.goal = self.create_publisher(String, "/goal", QOS_DEFAULT)
        self.tracked: list[TrackedTarget] = []
        self.status: list[dict] = []  # /target_tracker/status
        self.commander: list[dict] = []  # /commander/status
        self.cmds: list[tuple[float, float]] = []  # /behavior/cmd_vel
        self.targets: list[PointStamped] = []  # /detected_target
        self.headers: list[Header] = []
        self.create_subscription(TrackedTarget, "/target/tracked", self._tracked, QOS_DEFAULT)
        self.create_subscription(String, "/target_tracker/status", self._st, QOS_LATCHED)
        self.create_subscription(String, "/commander/status", self._cst, QOS_LATCHED)
        self.create_subscription(Twist, "/behavior/cmd_vel", self._cmd, QOS_DEFAULT)
        self.create_subscription(PointStamped, "/detected_target", self._target, QOS_DEFAULT)
        self.create_timer(0.1, self.tick)

    def _tracked(self, m: TrackedTarget) -> None:
        with self.lock:
            self.tracked.append(m)

    def _st(self, m: String) -> None:
        with self.lock:
            self.status.append(json.loads(m.data))

    def _cst(self, m: String) -> None:
        with self.lock:
            self.commander.append(json.loads(m.data))

    def _cmd(self, m: Twist) -> None:
        with self.lock:
            self.cmds.append((m.linear.x, m.angular.z))

    def _target(self, m: PointStamped) -> None:
        with self.lock:
            self.targets.append(m)

    def tick(self) -> None:
        h = Header(stamp=self.stamp(), frame_id="camera")
        with self.lock:
            self.headers.append(h)
        self.img.publish(numpy_to_image(frame(self.cx), "bgr8", h))
        self.info.publish(camera_info(PinholeCamera.from_hfov(640, 480, 1.274)))

    def last(self) -> TrackedTarget | None:
        with self.lock:
            return self.tracked[-1] if self.tracked else None

    def counter(self, name: str) -> int:
        with self.lock:
            return int(self.status[-1]["counters"].get(name, 0)) if self.status else 0

    def cstate(self) -> dict:
        """The commander's newest status."""
        with self.lock:
            return self.commander[-1] if self.commander else {}

    def last_cmd(self) -> tuple[float, float] | None:
        with self.lock:
            return self.cmds[-1] if self.cmds else None

    def header_back(self, n: int) -> Header:
        with self.lock:
            return self.headers[-n]
