"""object_memory: what the VLM saw stays where it is in the world.

Every grounding answer is about a frame with a stamp, and the robot's pose at that stamp is known:
each grounded box is placed in the world at the pose of the frame it describes (world/placement.py
over world/poses.py), however late the answer comes and wherever the robot has turned since, and
fused into remembered objects (world/memory.py). The memory never commands anything: the commander
reads /objects.

Topics
  subscribes  <answers_topic>       vision_msgs/Detection2DArray (reliable; /vlm/detections): grounding
                                    answers, boxes in the image's pixels, label in results[0].hypothesis.
                                    class_id, header.stamp = the stamp of the frame they describe. The
                                    vlm node's (mode=detect), the sim's ground truth (/sim/detections),
                                    answer_delay's, or the target_tracker's colour grounder's
                                    (/target_tracker/detections)
              <query_topic>         std_msgs/String, latched (/target/query): what the answers are asked
                                    about, for answers_cover=query
              <camera_info_topic>   sensor_msgs/CameraInfo (sensor-data QoS; /camera/camera_info): the
                                    camera model that turns a box into bearings. No CameraInfo yet: every
                                    answer is refused (no_camera_info)
              <image_topic>         sensor_msgs/Image (sensor-data QoS; /camera/image_raw; '' = off): kept
                                    small (160 px wide) for history_s, for the colour check
              <odom_topic>          nav_msgs/Odometry (reliable; /odom): the pose history (odom ->
                                    base_link), in world_frame, and the body's pitch, which the head
                                    camera shares (ranging; geometry/attitude.py)
              <scan_topic>          sensor_msgs/LaserScan (sensor-data QoS; /scan, frame base_link; '' =
                                    off): lidar ranges where a scan at the answer's stamp covers the box,
                                    and what hides an object from view
  publishes   /objects              vision_msgs/Detection3DArray, latched (transient-local, keep-last 1),
                                    header.frame_id = world_frame (odom), header.stamp = the stamp of the
                                    newest answer taken in: one Detection3D per object: id = a stable
                                    object id (blue_cylinder_1), results[0].hypothesis.class_id = the
                                    label ("blue cylinder"), .score = confidence 0..1, results[0].pose =
                                    position with covariance, bbox.center.position = world x, y, z (m),
                                    bbox.size = the object's size (m), header.stamp = when it was last
                                    seen (its frame's stamp). After every answer, at most every
                                    publish_period_s
              /objects/markers      visualization_msgs/MarkerArray, latched: a shape and a label per
                                    object (rviz2, Foxglove's 3D panel), at most every 0.5 s
              /object_memory/status std_msgs/String, latched JSON: world, frame, objects, answers, placed,
                                    refused.<reason> counts and the last refusal, answer latency p50/p95,
                                    the pose history's span, the memory files (`files`: count, bytes,
                                    caps, full) and the services' error replies; every
                                    status_period_s and on a new refusal
  services    /object_memory/where_is     go2vlm_msgs/srv/WhereIs: "where is X?" (a label; '' = all) ->
                                    found, one line for a person, the objects that fit (most confident
                                    first) as Detection3D
              /object_memory/memory_file  go2vlm_msgs/srv/MemoryFile: save | load a memory file on this
                                    node's machine: a name ("home" = $XDG_STATE_HOME/go2vlm/objects/
                                    home.json) or a path under $XDG_STATE_HOME/go2vlm/, nothing else
                                    (statefiles.py: memory files only, objects/*.json, opened by
                                    folder descriptor, never through a symlink); a save never
                                    replaces a file unless overwrite, and one that would take the
                                    memory files past max_files or max_files_mib is
                                    refused (the status's `files` says when a cap is reached). A load
                                    is all or nothing (world/memory_file.py). Every request is
                                    answered, a failure with its reason (bus/service.py)

Refused answers and boxes, counted on the status (refused.<reason>), never placed: no_stamp (a zero
stamp), no_camera_info, older_than_history (the pose history no longer reaches the stamp), pose_gap,
no_pose (no pose came within pose_wait_s), bad_box (NaN, absurd, no area), out_of_range,
color_mismatch (the box holds less than min_label_color of the colour its label names: the right label
on the wrong object), unranged (no range and nothing remembered along its bearings), uncertain (placed
less surely than new_max_sigma_m and fitting no object: world/memory.py), memory_full.
Bounded: at most max_objects objects, history_s of poses, scans and small frames, 32 answers waiting
for their pose; a flood of answers cannot grow it.

answers_cover: query -- an answer is about the label on /target/query (the vlm node grounds exactly
that; the colour grounder too): a remembered object of that label that the answer should have seen
and did not loses confidence (answers about frames taken within 0.5 s after the query changed say
nothing of it). all -- every answer lists everything visible (the sim's ground truth).

Memory file: memory_file (a name or a path in the memory files' folder, as for the service; loaded
at start: a file that is corrupt, of another world or frame, or of a newer version stops the node
with one line, exit 2; a missing one is started empty) and save_on_exit (replaces it).
`go2vlm objects` lists the memory, asks where something is, and saves or loads it.

Time: stamps only (the answers', the poses', the scans'): sim time and wall time both work while the
camera, /odom and the answers stamp on one clock. publish_period_s and status_period_s are in the
node's clock.
"""

from __future__ import annotations

import json
import math
import os
import statistics
from collections import OrderedDict, deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from go2vlm.bus import Node, core_params, from_core, param
from go2vlm.bus.topics import (
    CAMERA_IMAGE,
    CAMERA_INFO,
    MEMORY_FILE_SERVICE,
    OBJECT_MARKERS,
    OBJECT_MEMORY_STATUS,
    OBJECTS,
    ODOM,
    SCAN,
    TARGET_QUERY,
    VLM_DETECTIONS,
    WHERE_IS_SERVICE,
)
from go2vlm.errors import ConfigError
from go2vlm.geometry.attitude import PitchHistory
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.geometry.rotations import quat_pitch, quat_yaw
from go2vlm.geometry.scan import frame_scan_points
from go2vlm.msgs.go2vlm_msgs import (
    MemoryFile,
    MemoryFile_Request,
    MemoryFile_Response,
    WhereIs,
    WhereIs_Request,
    WhereIs_Response,
)
from go2vlm.msgs.image import camera_model, to_bgr
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.sensor_msgs import CameraInfo, Image, LaserScan
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.vision_msgs import Detection2DArray, detection_boxes
from go2vlm.perception.ranging import RangeEstimator, check_object_sizes
from go2vlm.perception.tracking import TrackingParams
from go2vlm.robot_profile import DEFAULT_ROBOT, PROFILES, profile
from go2vlm.robot_profile import go2 as spec
from go2vlm.statefiles import FileCaps, Quota, StateFileError, read_bounded, state_file, write_atomic
from go2vlm.vocabulary.pixels import color_in_box, label_color_mask
from go2vlm.vocabulary.words import parse_label
from go2vlm.world.labels import normalize_label
from go2vlm.world.memory import MemoryParams, ObjectMemory, View
from go2vlm.world.memory_file import MAX_FILE_BYTES, STATE_KIND, MemoryFileError, dumps, loads
from go2vlm.world.objects_msg import detection_of, markers_of, objects_array
from go2vlm.world.placement import CameraMount, Placed, PlacementError, PlacementParams, place, rebase
from go2vlm.world.poses import Pose2D, PoseHistory, PoseUnavailable

__all__ = ["ObjectMemoryConfig", "ObjectMemoryNode"]

SMALL_WIDTH = 160  # px: frames kept for the colour check
SCAN_WINDOW_S = 0.15  # a scan this close in time to the frame covers it
FRAME_WINDOW_S = 0.06  # a small frame this close in time is the answer's frame
QUERY_SETTLE_S = 0.5  # answers about frames this soon after a new query may be about the old one
MAX_PENDING = 32
# Refusals that a working memory meets all the time (an answer about something too far, or too
# unsure to place, or not ranged): logged at debug, counted on the status (`refused`).
ROUTINE_REFUSALS = frozenset({"out_of_range", "uncertain", "unranged"})
MAX_RANGERS = 128
MARKER_PERIOD_S = 0.5


@dataclass
class ObjectMemoryConfig:
    answers_topic: str = param(VLM_DETECTIONS.name, help="grounding answers (vision_msgs/Detection2DArray)")
    answers_cover: str = param(
        "query", choices=("query", "all"), help="an answer is about /target/query (query) or lists everything (all)"
    )
    query_topic: str = param(TARGET_QUERY.name, help="what the answers are asked about (answers_cover=query)")
    camera_info_topic: str = param(CAMERA_INFO.name, help="sensor_msgs/CameraInfo: the camera model")
    image_topic: str = param(CAMERA_IMAGE.name, help="frames for the colour check ('' = no check)")
    odom_topic: str = param(ODOM.name, help="nav_msgs/Odometry in world_frame: the pose history")
    scan_topic: str = param(SCAN.name, help="sensor_msgs/LaserScan in base_link: lidar ranges ('' = none)")
    world: str = param("", help="the place this memory is of; a memory file of another world is refused")
    world_frame: str = param(spec.GO2.frames.odom, help="the frame objects are remembered in (/odom's)")
    memory_file: str = param(
        "", help="a memory file to load at start: a name or a path under $XDG_STATE_HOME/go2vlm ('' = start empty)"
    )
    save_on_exit: bool = param(False, help="write memory_file when the node stops")
    max_files: int = from_core(FileCaps, "max_files")
    max_files_mib: float = from_core(FileCaps, "max_files_mib")
    history_s: float = param(30.0, help="poses, scans and frames kept: the oldest answer placed (s)", min=1.0,
                             max=600.0)  # fmt: skip
    pose_wait_s: float = param(1.0, help="an answer newer than the newest pose waits this long (s)", min=0.0,
                               max=10.0)  # fmt: skip
    robot: str = param(
        DEFAULT_ROBOT, help="the robot whose head camera this is: its mount and pitch, for placing and ranging",
        choices=tuple(PROFILES),
    )  # fmt: skip
    object_sizes: dict[str, float] = from_core(TrackingParams, "object_sizes")
    min_label_color: float = from_core(TrackingParams, "min_label_color")
    max_objects: int = from_core(MemoryParams, "max_objects")
    gate_sigma: float = from_core(MemoryParams, "gate_sigma")
    gate_min_m: float = from_core(MemoryParams, "gate_min_m")
    hit: float = from_core(MemoryParams, "hit")
    miss: float = from_core(MemoryParams, "miss")
    forget_below: float = from_core(MemoryParams, "forget_below")
    view_max_m: float = from_core(MemoryParams, "view_max_m")
    new_max_sigma_m: float = from_core(MemoryParams, "new_max_sigma_m")
    publish_period_s: float = param(0.05, help="/objects at most this often (s)", min=0.0, max=10.0)
    status_period_s: float = param(1.0, help="/object_memory/status period besides on a new refusal", min=0.1,
                                   max=60.0)  # fmt: skip

    def validate(self) -> None:
        check_object_sizes(self.object_sizes)
        self.memory_params()

    def memory_params(self) -> MemoryParams:
        return core_params(MemoryParams, self)

    def mount(self) -> CameraMount:
        return CameraMount.of(profile(self.robot))

    def quota(self) -> Quota:
        return core_params(FileCaps, self).quota(STATE_KIND)


class ObjectMemoryNode(Node):
    """The ``object_memory`` node; its contract (topics, services, parameters) is the module docstring."""

    name = "object_memory"
    Config = ObjectMemoryConfig

    def __init__(self, config: ObjectMemoryConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        cfg: ObjectMemoryConfig = self.config
        self.memory = ObjectMemory(cfg.memory_params())
        self.poses = PoseHistory(horizon_s=cfg.history_s)
        self.pitch = PitchHistory(horizon_s=cfg.history_s)  # the body's: the camera's, for ranging
        self.mount = cfg.mount()
        self.placement = PlacementParams()
        self._cam: PinholeCamera | None = None
        self._scans: deque[tuple[float, np.ndarray]] = deque(maxlen=int(cfg.history_s * 50) + 10)
        self._frames: deque[tuple[float, np.ndarray, float]] = deque(maxlen=int(cfg.history_s * 30) + 10)
        self._rangers: OrderedDict[str, RangeEstimator] = OrderedDict()
        self._pending: deque[tuple[float, Detection2DArray]] = deque(maxlen=MAX_PENDING)
        self._query, self._query_since = "", -math.inf
        self._latency: deque[float] = deque(maxlen=200)
        self.answered_through = 0.0
        self.refused: dict[str, int] = {}
        self.last_refusal = ""
        self._dirty = self._markers_dirty = True
        self._last_pub = self._last_markers = -math.inf
        if cfg.memory_file:
            self._load_at_start(self._own_file())
        self.pub_objects = OBJECTS.publisher(self)
        self.pub_markers = OBJECT_MARKERS.publisher(self)
        self.pub_status = OBJECT_MEMORY_STATUS.publisher(self)
        ODOM.subscription(self, self.on_odom, name=cfg.odom_topic)
        CAMERA_INFO.subscription(self, self.on_camera_info, name=cfg.camera_info_topic)
        if cfg.scan_topic:
            SCAN.subscription(self, self.on_scan, name=cfg.scan_topic)
        if cfg.image_topic:
            CAMERA_IMAGE.subscription(self, self.on_image, name=cfg.image_topic)
        if cfg.answers_cover == "query":
            TARGET_QUERY.subscription(self, self.on_query, name=cfg.query_topic)
        VLM_DETECTIONS.subscription(self, self.on_answers, name=cfg.answers_topic)
        self.create_service(WhereIs, WHERE_IS_SERVICE, self.where_is)
        self.create_service(MemoryFile, MEMORY_FILE_SERVICE, self.memory_file)
        self.create_timer(max(0.02, cfg.publish_period_s), self._flush)
        self.create_timer(cfg.status_period_s, self.publish_status)
        self._flush(force=True)
        self.publish_status()
        self.log.info(
            f"answers on {self.resolve(cfg.answers_topic)} (cover {cfg.answers_cover}), world {cfg.world!r}, "
            f"{len(self.memory.objects)} object(s) remembered"
        )

    # -- inputs ------------------------------------------------------------------------------
    def on_params_changed(self, old: ObjectMemoryConfig, changed: frozenset[str]) -> None:
        self.memory.params = self.config.memory_params()

    def on_query(self, msg: String) -> None:
        q = normalize_label(msg.data)
        if q != self._query:
            self._query, self._query_since = q, self.now()

    def on_camera_info(self, msg: CameraInfo) -> None:
        try:
            self._cam = camera_model(msg)
        except (ValueError, IndexError) as exc:
            n = self.count("bad_camera_info")
            self.log.throttled("error", 5.0, f"ignoring a CameraInfo ({n} so far): {exc}", key="caminfo")

    def on_odom(self, msg: Odometry) -> None:
        if msg.header.frame_id and msg.header.frame_id != self.config.world_frame:
            n = self.count("odom_wrong_frame")
            self.log.throttled("error", 5.0, f"ignoring /odom in frame {msg.header.frame_id!r} ({n} so far); "
                               f"world_frame is {self.config.world_frame!r}", key="odom")  # fmt: skip
            return
        p = msg.pose.pose
        q = p.orientation
        t = msg.header.stamp.to_sec()
        self.pitch.add(t, quat_pitch(q.w, q.x, q.y, q.z))
        if self.poses.add(t, p.position.x, p.position.y, quat_yaw(q.w, q.x, q.y, q.z)):
            self._retry_pending()

    def on_scan(self, msg: LaserScan) -> None:
        try:
            pts = frame_scan_points(spec.BASE_FRAME, msg.header.frame_id, msg.ranges, msg.angle_min,
                                    msg.angle_increment, msg.range_min, msg.range_max)  # fmt: skip
        except (ValueError, TypeError, OverflowError) as exc:
            n = self.count("bad_scan")
            self.log.throttled("error", 5.0, f"ignoring a bad scan ({n} so far): {exc}", key="scan")
            return
        stamp = msg.header.stamp.to_sec()
        self._scans.append((stamp, pts))
        while self._scans and self._scans[0][0] < stamp - self.config.history_s:
            self._scans.popleft()

    def on_image(self, msg: Image) -> None:
        try:
            bgr = to_bgr(msg)
        except ValueError:
            self.count("bad_images")
            return
        h, w = bgr.shape[:2]
        scale = SMALL_WIDTH / w if w > SMALL_WIDTH else 1.0
        small = cv2.resize(bgr, (max(1, round(w * scale)), max(1, round(h * scale))), interpolation=cv2.INTER_AREA)
        stamp = msg.header.stamp.to_sec()
        self._frames.append((stamp, small, scale))
        while self._frames and self._frames[0][0] < stamp - self.config.history_s:
            self._frames.popleft()

    def on_answers(self, msg: Detection2DArray) -> None:
        self.count("answers")
        stamp = msg.header.stamp.to_sec()
        if stamp <= 0.0:
            self._refuse("no_stamp", "an answer without a stamp: which frame is it about?")
            return
        if self._cam is None:
            self._refuse("no_camera_info", f"no CameraInfo on {self.resolve(self.config.camera_info_topic)} yet")
            return
        self._take(msg, self.now())

    # -- placing answers ---------------------------------------------------------------------
    def _take(self, msg: Detection2DArray, arrived: float) -> None:
        stamp = msg.header.stamp.to_sec()
        try:
            pose = self.poses.at(stamp)
        except PoseUnavailable as exc:
            if exc.reason in ("newer_than_pose", "no_pose") and self.now() - arrived <= self.config.pose_wait_s:
                self._pending.append((arrived, msg))  # the pose will catch up
                return
            self._refuse(exc.reason, str(exc))
            return
        self._place_answer(msg, stamp, pose, arrived)

    def _retry_pending(self) -> None:
        waiting, self._pending = list(self._pending), deque(maxlen=MAX_PENDING)
        for arrived, msg in waiting:
            self._take(msg, arrived)

    def _place_answer(self, msg: Detection2DArray, stamp: float, pose: Pose2D, arrived: float) -> None:
        cam = self._cam
        assert cam is not None
        self._latency.append(max(0.0, arrived - stamp))
        scan_base, scan_world = self._scan_at(stamp, pose)
        placed: list[Placed] = []
        for label, box, _score in detection_boxes(msg):
            lab = normalize_label(label)
            if not lab:
                self._refuse("no_label", "a box without a label")
                continue
            why = self._color_check(lab, box, stamp)
            if why:
                self._refuse("color_mismatch", why)
                continue
            try:
                placed.append(place(lab, box, stamp, pose, cam, self.mount, self._ranger(lab), scan_base,
                                    self.placement, self.pitch.at(stamp)))  # fmt: skip
            except PlacementError as exc:
                self._refuse(exc.reason, f"{lab!r}: {exc.detail}")
        covers: frozenset[str] | None = None
        if self.config.answers_cover == "query":
            fresh = self._query and stamp >= self._query_since + QUERY_SETTLE_S
            covers = frozenset({self._query}) if fresh else frozenset()
        cam_xy = pose.to_world(self.mount.forward_m, self.mount.left_m)
        view = View(stamp, cam_xy, pose.yaw, cam.hfov, covers, scan_world)
        for res in self.memory.observe(placed, view):
            if res.startswith("refused."):
                self._refuse(res.removeprefix("refused."), "a sighting the memory could not use", count=False)
            else:
                self.count("placed")
        self.answered_through = max(self.answered_through, stamp)
        self._dirty = self._markers_dirty = True
        self._flush()

    def _scan_at(self, stamp: float, pose: Pose2D) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The scan nearest `stamp` (within SCAN_WINDOW_S) in the base frame at `pose`, and in the world."""
        best = min(self._scans, key=lambda s: abs(s[0] - stamp), default=None)
        if best is None or abs(best[0] - stamp) > SCAN_WINDOW_S:
            return None, None
        try:
            at = self.poses.at(best[0])
        except PoseUnavailable:
            return None, None
        base = rebase(best[1], at, pose)
        world = rebase(best[1], at, Pose2D(0.0, 0.0, 0.0))
        return base, world

    def _color_check(self, label: str, box: tuple[float, float, float, float], stamp: float) -> str:
        """'' when the box holds enough of the colour its label names (or nothing can be checked)."""
        color = parse_label(label).color
        if color is None or not self._frames or not all(math.isfinite(v) for v in box):
            return ""
        stamp_f, small, scale = min(self._frames, key=lambda f: abs(f[0] - stamp))
        if abs(stamp_f - stamp) > FRAME_WINDOW_S:
            self.count("color_unchecked")
            return ""
        x1, y1, x2, y2 = (v * scale for v in box)
        mask = label_color_mask(small, color)
        return color_in_box(
            mask, (x1, y1, x2, y2), label=label, color=color, min_fraction=self.config.min_label_color, shown=box
        )[1]

    def _ranger(self, label: str) -> RangeEstimator:
        r = self._rangers.get(label)
        if r is None:
            cfg = self.config
            sizes = {k: float(v) for k, v in cfg.object_sizes.items()}
            r = RangeEstimator(parse_label(label).shape, camera_height=self.mount.height_m,
                               camera_pitch=self.mount.pitch_rad, default_sizes=sizes)  # fmt: skip
            self._rangers[label] = r
            if len(self._rangers) > MAX_RANGERS:
                self._rangers.popitem(last=False)
        self._rangers.move_to_end(label)
        return r

    def _refuse(self, reason: str, detail: str, *, count: bool = True) -> None:
        if count:
            self.count(f"refused.{reason}")
        self.refused[reason] = self.refused.get(reason, 0) + 1
        new = f"{reason}: {detail}"
        if new.split(":")[0] != self.last_refusal.split(":")[0]:
            self.last_refusal = new
            # A normal event (the status counts it) is no warning: a warning is for a person to act on.
            level = "debug" if reason in ROUTINE_REFUSALS else "warning"
            self.log.throttled(level, 5.0, f"refused: {new}", key=f"refused.{reason}")
            self.publish_status()
        self.last_refusal = new

    # -- outputs -----------------------------------------------------------------------------
    def _flush(self, force: bool = False) -> None:
        now = self.clock.monotonic()
        cfg = self.config
        if force or (self._dirty and now - self._last_pub >= cfg.publish_period_s):
            self._dirty, self._last_pub = False, now
            self.pub_objects.publish(objects_array(self.memory.snapshot(), cfg.world_frame, self.answered_through))
        if force or (self._markers_dirty and now - self._last_markers >= MARKER_PERIOD_S):
            self._markers_dirty, self._last_markers = False, now
            self.pub_markers.publish(markers_of(self.memory.snapshot(), cfg.world_frame, self.answered_through))

    def where_is(self, req: WhereIs_Request) -> WhereIs_Response:
        label = str(req.label)[:200]
        fits = self.memory.where_is(label)
        frame = self.config.world_frame
        if not fits:
            known = sorted({o.label for o in self.memory.objects.values()})
            return WhereIs.Response(False, f"I remember no {label or 'object'}" + (
                f" (I remember: {', '.join(known)})" if known else " (I remember nothing yet)"), [])  # fmt: skip
        best = fits[0]
        age = max(0.0, self.answered_through - best.last_seen)
        msg = (f"{best.label} at ({best.x:.2f}, {best.y:.2f}) m in {frame}, +-{best.sigma:.2f} m, confidence "
               f"{best.confidence:.2f}, seen {best.seen} times, last {age:.1f} s before the newest answer")  # fmt: skip
        if len(fits) > 1:
            msg += f"; {len(fits) - 1} more fit"
        return WhereIs.Response(True, msg, [detection_of(o, frame) for o in fits])

    def memory_file(self, req: MemoryFile_Request) -> MemoryFile_Response:
        if req.command not in ("save", "load"):
            return MemoryFile.Response(False, f"unknown command {str(req.command)[:20]!r}: use save or load", 0)
        try:
            path = state_file(str(req.path), STATE_KIND)
        except StateFileError as exc:
            return MemoryFile.Response(False, f"refused: {_one_line(exc)}", 0)
        if req.command == "save":
            try:
                n = self.save(path, overwrite=bool(req.overwrite))
            except StateFileError as exc:
                self.publish_status()  # a cap reached shows there
                return MemoryFile.Response(False, f"refused: {_one_line(exc)}", 0)
            except OSError as exc:
                return MemoryFile.Response(False, f"cannot write {path}: {exc.strerror or exc}", 0)
            return MemoryFile.Response(True, f"saved {n} object(s) of world {self.config.world!r} to {path}", n)
        if req.command == "load":
            try:
                objs = self._read(path)
            except (MemoryFileError, StateFileError, OSError) as exc:
                return MemoryFile.Response(False, f"refused {path}: {_one_line(exc)}", 0)
            self.memory.load(objs)
            self._dirty = self._markers_dirty = True
            self._flush(force=True)
            self.log.info(f"loaded {len(objs)} object(s) from {path}")
        return MemoryFile.Response(True, f"loaded {len(objs)} object(s) from {path}", len(objs))

    def _read(self, path: Path) -> list[Any]:
        cfg = self.config
        data = read_bounded(path, MAX_FILE_BYTES)
        return loads(data, cfg.world, cfg.world_frame, cfg.max_objects)

    def _load_at_start(self, path: Path) -> None:
        if not os.path.lexists(path):
            self.log.info(f"no memory file {path} yet: starting empty")
            return
        try:
            objs = self._read(path)
        except (MemoryFileError, StateFileError, OSError) as exc:
            raise ConfigError(f"memory_file {path}: {_one_line(exc)}") from None
        self.memory.load(objs)

    def _own_file(self) -> Path:
        """memory_file, confined to the state directory (a ConfigError at start otherwise)."""
        try:
            return state_file(self.config.memory_file, STATE_KIND)
        except StateFileError as exc:
            raise ConfigError(f"memory_file: {_one_line(exc)}") from None

    def save(self, path: Path, *, overwrite: bool = False) -> int:
        """Write the memory to `path` (already confined) atomically; the number of objects written."""
        cfg = self.config
        objs = self.memory.snapshot()
        data = dumps(objs, cfg.world, cfg.world_frame, self.answered_through).encode()
        write_atomic(path, data, overwrite=overwrite, quota=cfg.quota())
        return len(objs)

    def status(self) -> dict[str, Any]:
        lat = sorted(self._latency)
        return {
            "world": self.config.world,
            "frame": self.config.world_frame,
            "objects": len(self.memory.objects),
            "answers": self.counters.get("answers", 0),
            "placed": self.counters.get("placed", 0),
            "refused": dict(sorted(self.refused.items())),
            "last_refusal": self.last_refusal,
            "answered_through": round(self.answered_through, 3),
            "latency_s": {
                "p50": round(statistics.median(lat), 3) if lat else None,
                "p95": round(lat[min(len(lat) - 1, int(0.95 * len(lat)))], 3) if lat else None,
                "n": len(lat),
            },
            "poses_s": round((self.poses.newest or 0.0) - (self.poses.oldest or 0.0), 2),
            "camera_info": self._cam is not None,
            "files": self.config.quota().usage(),
            "services": self.service_stats(),
            "refused_inputs": self.input_refusals(),
            "counters": {**self.memory.counters, **self.counters},
        }

    def publish_status(self) -> None:
        self.pub_status.publish(String(data=json.dumps(self.status(), ensure_ascii=False)))

    def close(self) -> None:
        cfg = self.config
        if cfg.save_on_exit and cfg.memory_file:
            try:
                n = self.save(self._own_file(), overwrite=True)
                self.log.info(f"saved {n} object(s) to {cfg.memory_file}")
            except (OSError, ConfigError) as exc:
                self.log.error(f"cannot save the memory to {cfg.memory_file}: {exc}")


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())
