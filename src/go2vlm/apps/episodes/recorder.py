"""The one recorder of every episode: a node that listens like any other and keeps what the metrics,
the plot and the video need. It runs on sim time, so every time it keeps is sim time (stamps, and
the sim time at which a message arrived).

Subscribes: /clock, /sim/status, /sim/ground_truth, /joint_states, /cmd_vel, /behavior/cmd_vel,
/detected_target, /commander/status, /safety/status (the e-stop), /camera/camera_info,
/sim/detections, /vlm/detections, /vlm/status, /target/tracked, /objects (the object memory), /map
and /map/costmap (only the newest grid of each is kept: a map is large), /plan (the commander's
routes, each new one, at most MAX_PLANS) and, for the video, /camera/image_raw (kept as small JPEGs).
"""

from __future__ import annotations

import json
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from go2vlm.bus import Node
from go2vlm.bus.topics import (
    BEHAVIOR_CMD_VEL,
    CAMERA_IMAGE,
    CAMERA_INFO,
    CLOCK,
    CMD_VEL,
    COMMANDER_STATUS,
    DETECTED_TARGET,
    JOINT_STATES,
    MAP,
    MAP_COSTMAP,
    OBJECTS,
    PLAN,
    SAFETY_STATUS,
    SIM_DETECTIONS,
    SIM_GROUND_TRUTH,
    SIM_STATUS,
    TARGET_TRACKED,
    VLM_DETECTIONS,
    VLM_STATUS,
)
from go2vlm.msgs.geometry_msgs import PointStamped, Twist
from go2vlm.msgs.go2vlm_msgs import STATE_NAMES, TrackedTarget
from go2vlm.msgs.image import image_to_numpy
from go2vlm.msgs.nav_msgs import OccupancyGrid, Path
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.sensor_msgs import CameraInfo, Image, JointState
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.tf2_msgs import TFMessage
from go2vlm.msgs.vision_msgs import Detection2DArray, Detection3DArray, PixelBox, detection_boxes
from go2vlm.world.map_msg import Grid, grid_of
from go2vlm.world.objects_msg import Remembered, remembered

__all__ = ["MAX_PLANS", "THUMB_WIDTH", "EpisodeRecorder", "Recording"]

THUMB_WIDTH = 320  # head frames are kept at this width for the video's inset (JPEG, ~15 kB each)

MAX_PLANS = 200  # /plan routes kept (the newest); a route is replanned about once a second at most
Pose7 = tuple[float, float, float, float, float, float, float]  # x, y, z, qw, qx, qy, qz


@dataclass
class Recording:
    """What the recorder heard, copied out at the end of an episode (plain data, no DDS)."""

    sim_time: float = -1.0  # the newest /clock
    status: list[dict[str, Any]] = field(default_factory=list)  # /sim/status of this run
    fell: bool = False
    poses: list[tuple[float, dict[str, Pose7]]] = field(default_factory=list)  # stamp, body -> pose
    joints: list[tuple[float, list[float]]] = field(default_factory=list)  # stamp, 12 joint angles
    cmds: list[tuple[float, float, float, float]] = field(default_factory=list)  # sim t, vx, vy, wz (/cmd_vel)
    behavior: list[tuple[float, float, float]] = field(default_factory=list)  # sim t, vx, wz
    targets: list[tuple[float, float, float, float]] = field(default_factory=list)  # stamp, x, y, z
    commander: list[tuple[float, dict[str, Any]]] = field(default_factory=list)  # sim t, /commander/status
    frames: list[float] = field(default_factory=list)  # camera_info stamps: one per head frame
    thumbs: dict[float, bytes] = field(default_factory=dict)  # frame stamp -> JPEG (RGB order encoded)
    truth: dict[float, list[PixelBox]] = field(default_factory=dict)  # /sim/detections by frame stamp
    answers: list[tuple[float, float, list[PixelBox]]] = field(default_factory=list)  # sim t, stamp, boxes
    vlm_status: list[dict[str, Any]] = field(default_factory=list)
    # /target/tracked: sim t received, frame stamp, state name, grounding_age_s (NaN before any answer)
    tracked: list[tuple[float, float, str, float]] = field(default_factory=list)
    memory: list[tuple[float, list[Remembered]]] = field(default_factory=list)  # sim t, /objects
    estop: list[tuple[float, bool, str]] = field(default_factory=list)  # sim t, the gate's e-stop and why, on change
    grid: Grid | None = None  # the newest /map
    costmap: Grid | None = None  # the newest /map/costmap
    plans: list[tuple[float, list[tuple[float, float]]]] = field(default_factory=list)  # sim t, waypoints (x, y)


class EpisodeRecorder(Node):
    """Listens to the whole graph; `snapshot()` copies what it heard."""

    name = "episode_recorder"

    def __init__(self, config: Any = None, *, video: bool = True, **kwargs: Any) -> None:
        kwargs.setdefault("use_sim_time", True)
        super().__init__(config, **kwargs)
        # Latched /sim/status may still hold a previous run's sample (another episode in this
        # process): its wall_time tells.
        self.wall_start = time.time()  # wall time: /sim/status carries the wall time it was sent at
        self.lock = threading.Lock()
        self.rec = Recording()
        CLOCK.subscription(self, self._on_clock)
        SIM_STATUS.subscription(self, self._on_sim_status)
        SIM_GROUND_TRUTH.subscription(self, self._on_gt)
        CMD_VEL.subscription(self, self._on_cmd)
        BEHAVIOR_CMD_VEL.subscription(self, self._on_behavior)
        DETECTED_TARGET.subscription(self, self._on_target)
        COMMANDER_STATUS.subscription(self, self._on_commander)
        SAFETY_STATUS.subscription(self, self._on_safety)
        CAMERA_INFO.subscription(self, self._on_info)
        SIM_DETECTIONS.subscription(self, self._on_truth)
        VLM_DETECTIONS.subscription(self, self._on_answer)
        VLM_STATUS.subscription(self, self._on_vlm_status)
        TARGET_TRACKED.subscription(self, self._on_tracked)
        OBJECTS.subscription(self, self._on_objects)
        MAP.subscription(self, self._on_map)
        MAP_COSTMAP.subscription(self, self._on_costmap)
        PLAN.subscription(self, self._on_plan)
        if video:
            JOINT_STATES.subscription(self, self._on_joints)
            CAMERA_IMAGE.subscription(self, self._on_image)

    @property
    def sim_time(self) -> float:
        return self.rec.sim_time

    @property
    def fell(self) -> bool:
        return self.rec.fell

    def snapshot(self) -> Recording:
        with self.lock:
            r = self.rec
            return Recording(
                r.sim_time,
                list(r.status),
                r.fell,
                list(r.poses),
                list(r.joints),
                list(r.cmds),
                list(r.behavior),
                list(r.targets),
                list(r.commander),
                list(r.frames),
                dict(r.thumbs),
                dict(r.truth),
                list(r.answers),
                list(r.vlm_status),
                list(r.tracked),
                list(r.memory),
                list(r.estop),
                r.grid,
                r.costmap,
                list(r.plans),
            )

    def latest_state(self) -> str | None:
        with self.lock:
            return self.rec.commander[-1][1].get("state") if self.rec.commander else None

    def last_status(self) -> dict[str, Any]:
        with self.lock:
            return dict(self.rec.status[-1]) if self.rec.status else {}

    def frame_count(self) -> int:
        with self.lock:
            return len(self.rec.frames)

    # -- callbacks (the recorder's own thread) -------------------------------------------------
    def _json(self, msg: String) -> dict[str, Any] | None:
        try:
            d = json.loads(msg.data)
        except ValueError:
            self.count("bad_status")
            return None
        return d if isinstance(d, dict) else None

    def _on_clock(self, msg: Clock) -> None:
        self.rec.sim_time = msg.clock.to_sec()

    def _on_sim_status(self, msg: String) -> None:
        st = self._json(msg)
        if st is None or float(st.get("wall_time", 0.0)) < self.wall_start:
            return
        with self.lock:
            self.rec.status.append(st)
            self.rec.fell = self.rec.fell or bool(st.get("fell"))

    def _on_gt(self, msg: TFMessage) -> None:
        if not msg.transforms:
            return
        poses: dict[str, Pose7] = {}
        for tf in msg.transforms:
            t, q = tf.transform.translation, tf.transform.rotation
            poses[tf.child_frame_id.removeprefix("gt/")] = (t.x, t.y, t.z, q.w, q.x, q.y, q.z)
        with self.lock:
            self.rec.poses.append((msg.transforms[0].header.stamp.to_sec(), poses))

    def _on_joints(self, msg: JointState) -> None:
        with self.lock:
            self.rec.joints.append((msg.header.stamp.to_sec(), list(msg.position)))

    def _on_cmd(self, msg: Twist) -> None:
        with self.lock:
            self.rec.cmds.append((self.now(), msg.linear.x, msg.linear.y, msg.angular.z))

    def _on_behavior(self, msg: Twist) -> None:
        with self.lock:
            self.rec.behavior.append((self.now(), msg.linear.x, msg.angular.z))

    def _on_target(self, msg: PointStamped) -> None:
        p = msg.point
        if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
            self.count("bad_targets")
            return
        with self.lock:
            self.rec.targets.append((msg.header.stamp.to_sec(), p.x, p.y, p.z))

    def _on_commander(self, msg: String) -> None:
        st = self._json(msg)
        if st is not None:
            with self.lock:
                self.rec.commander.append((self.now(), st))

    def _on_safety(self, msg: String) -> None:
        st = self._json(msg)
        if st is None or not isinstance(st.get("estop"), bool):
            return
        engaged, why = st["estop"], str(st.get("estop_why") or "")
        with self.lock:
            if not self.rec.estop or self.rec.estop[-1][1:] != (engaged, why):
                self.rec.estop.append((self.now(), engaged, why))

    def _on_info(self, msg: CameraInfo) -> None:
        with self.lock:
            self.rec.frames.append(msg.header.stamp.to_sec())

    def _on_truth(self, msg: Detection2DArray) -> None:
        with self.lock:
            self.rec.truth[msg.header.stamp.to_sec()] = detection_boxes(msg)

    def _on_answer(self, msg: Detection2DArray) -> None:
        with self.lock:
            self.rec.answers.append((self.now(), msg.header.stamp.to_sec(), detection_boxes(msg)))

    def _on_vlm_status(self, msg: String) -> None:
        st = self._json(msg)
        if st is not None:
            with self.lock:
                self.rec.vlm_status.append(st)

    def _on_tracked(self, msg: TrackedTarget) -> None:
        state = STATE_NAMES.get(int(msg.state), "unknown")
        with self.lock:
            self.rec.tracked.append((self.now(), msg.header.stamp.to_sec(), state, float(msg.grounding_age_s)))

    def _on_objects(self, msg: Detection3DArray) -> None:
        objs = [r for r in map(remembered, msg.detections) if r is not None]
        with self.lock:
            self.rec.memory.append((self.now(), objs))

    def _grid(self, msg: OccupancyGrid) -> Grid | None:
        try:
            return grid_of(msg)
        except ValueError as exc:
            self.count("bad_maps")
            self.log.throttled("warn", 5.0, f"map: {exc}")
            return None

    def _on_map(self, msg: OccupancyGrid) -> None:
        g = self._grid(msg)
        if g is not None:
            with self.lock:
                self.rec.grid = g  # only the newest: the older ones are dropped here

    def _on_costmap(self, msg: OccupancyGrid) -> None:
        g = self._grid(msg)
        if g is not None:
            with self.lock:
                self.rec.costmap = g

    def _on_plan(self, msg: Path) -> None:
        pts = [(p.pose.position.x, p.pose.position.y) for p in msg.poses]
        with self.lock:
            if pts and (not self.rec.plans or self.rec.plans[-1][1] != pts):
                self.rec.plans.append((self.now(), pts))
                del self.rec.plans[:-MAX_PLANS]

    def _on_image(self, msg: Image) -> None:
        import cv2

        try:
            arr = image_to_numpy(msg)
        except ValueError as exc:
            self.count("bad_images")
            self.log.throttled("error", 2.0, f"video: {exc}")
            return
        h, w = arr.shape[:2]
        size = (THUMB_WIDTH, max(2, round(h * THUMB_WIDTH / w / 2) * 2))
        small = cv2.resize(arr, size, interpolation=cv2.INTER_AREA)
        if small.ndim == 2:
            small = cv2.cvtColor(small, cv2.COLOR_GRAY2BGR)
        elif small.shape[2] == 4:
            small = small[:, :, :3]
        if msg.encoding not in ("bgr8", "8UC3"):  # rgb8 (the sim's): JPEG wants BGR order
            small = cv2.cvtColor(small, cv2.COLOR_RGB2BGR)
        ok, jpg = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, 85])
        if ok:
            with self.lock:
                self.rec.thumbs[msg.header.stamp.to_sec()] = jpg.tobytes()
