"""For the world tests: the synthetic views of testing_support.world_views, and a robot stand-in
(odometry, a CameraInfo, a VLM's answers) that records what the object memory says."""

from __future__ import annotations

import json
import threading

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node
from go2vlm.geometry.rotations import yaw_quat
from go2vlm.msgs.geometry_msgs import Point, Pose, Quaternion
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.sensor_msgs import CameraInfo
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.msgs.vision_msgs import Detection2DArray, Detection3DArray
from go2vlm.msgs.visualization_msgs import MarkerArray
from go2vlm.world.objects_msg import remembered
from testing_support.world_views import CAM, MOUNT, cylinder_box, cylinder_scan

__all__ = ["CAM", "CYL", "MOUNT", "Robot", "cylinder_box", "cylinder_scan"]

CYL = (3.0, 0.8)  # a blue cylinder, r 0.3, 1.5 m tall, in front of a robot at the origin


class Robot(Node):
    """Odometry at 50 Hz (the robot turns at `wz`), a CameraInfo, and a VLM stand-in."""

    name = "fake_robot"

    def __init__(self, **kw) -> None:
        super().__init__(**kw)
        self.lock = threading.Lock()
        self.yaw, self.wz = 0.0, 0.0
        self.poses: list[tuple[float, float]] = []  # stamp, yaw
        self.odom = self.create_publisher(Odometry, "/odom", QOS_DEFAULT)
        self.info = self.create_publisher(CameraInfo, "/camera/camera_info", QOS_DEFAULT)
        self.answers = self.create_publisher(Detection2DArray, "/vlm/detections", QOS_DEFAULT)
        self.query = self.create_publisher(String, "/target/query", QOS_LATCHED)
        self.objects: list[Detection3DArray] = []
        self.markers: list[MarkerArray] = []
        self.status: list[dict] = []
        self.create_subscription(Detection3DArray, "/objects", self._objects, QOS_LATCHED)
        self.create_subscription(MarkerArray, "/objects/markers", lambda m: self.markers.append(m), QOS_LATCHED)
        self.create_subscription(String, "/object_memory/status", self._status, QOS_LATCHED)
        self.create_timer(0.02, self.tick)

    def _objects(self, m: Detection3DArray) -> None:
        with self.lock:
            self.objects.append(m)

    def _status(self, m: String) -> None:
        with self.lock:
            self.status.append(json.loads(m.data))

    def tick(self) -> None:
        t = self.now()
        with self.lock:
            self.yaw += self.wz * 0.02
            self.poses.append((t, self.yaw))
        q = yaw_quat(self.yaw)
        pose = Pose(position=Point(), orientation=Quaternion(x=0.0, y=0.0, z=float(q[3]), w=float(q[0])))
        msg = Odometry(header=Header(stamp=self.stamp(t), frame_id="odom"), child_frame_id="base_link")
        msg.pose.pose = pose
        self.odom.publish(msg)

    def last_status(self) -> dict:
        with self.lock:
            return self.status[-1] if self.status else {}

    def ready(self) -> bool:
        """The memory has a CameraInfo and some pose history."""
        st = self.last_status()
        return bool(st.get("camera_info")) and st.get("poses_s", 0) > 0.3

    def refused(self, reason: str) -> int:
        return self.last_status().get("refused", {}).get(reason, 0)

    def memory(self) -> dict:
        with self.lock:
            last = self.objects[-1] if self.objects else None
        return {} if last is None else {r.id: r for r in map(remembered, last.detections) if r is not None}
