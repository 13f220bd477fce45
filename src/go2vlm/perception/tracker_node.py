"""target_tracker: the one target a behaviour asks for, kept at camera rate between grounding answers
and reported only while it is confirmed.

Topics
  subscribes  /target/query          std_msgs/String, latched (transient-local) QoS: the label to track,
                                     e.g. "blue cylinder" ('' = nothing); the commander publishes its
                                     goal's object here. Publish by hand with --qos latched. The `query`
                                     parameter is the query until one arrives.
              <image_topic>          sensor_msgs/Image (/camera/image_raw, sensor-data QoS)
              <camera_info_topic>    sensor_msgs/CameraInfo (/camera/camera_info, sensor-data QoS):
                                     intrinsics for ranging and bearings; default_hfov_deg until one arrives
              <odom_topic>           nav_msgs/Odometry (/odom, reliable): the body's pitch at each frame's
                                     stamp, which the head camera shares (geometry/attitude.py); level
                                     until one arrives
              /vlm/detections        vision_msgs/Detection2DArray (reliable), grounding=vlm only: the vlm
                                     node's answers (mode=detect), boxes in the image's pixels, stamped
                                     with the frame they describe, label = each detection's best hypothesis
                                     (msgs/vision_msgs.py best_hypothesis)
  publishes   /target/tracked        go2vlm_msgs/TrackedTarget (reliable, keep-last 10), one per camera
                                     frame: header = the frame's header; label = the query; state idle |
                                     searching | tracking | lost | ungroundable; bbox (pixels) only while
                                     tracking; image size; confidence; bearing_rad (the box centre's, + left,
                                     from the camera model; NaN unless tracking) and hfov_rad (that model's
                                     field of view); distance_m (camera -> the object's near surface, NaN
                                     unknown) and range_method; grounding_age_s (NaN before any answer).
                                     Every behaviour reads this.
              /target_tracker/detections  vision_msgs/Detection2DArray (reliable), grounding=color only:
                                     the colour grounder's own answers, one per run (every frame while
                                     searching, every reground_period_s while tracking), stamped with
                                     the frame, the box it found for the query (label = the query) or
                                     none: what the object memory places (world/object_memory_node.py)
              /target_tracker/status std_msgs/String, latched JSON: query, state, grounding, last_refusal,
                                     counters (refused.<reason>, accepted, tracks_lost, ...); on every
                                     state change and every status_period_s

Grounding (`grounding`)
  color  (default, no model) the colour-shape grounder (perception/grounding.py) on the frames: labels
         "<red|green|blue|yellow> <ball|box|cylinder>" (either part optional); free text is
         `ungroundable`. Re-grounds every reground_period_s while tracking, every frame otherwise.
  vlm    answers on /vlm/detections; run the vlm node with mode=detect (it grounds /target/query).
Between answers a CamShift tracker (perception/tracker.py) follows the target frame by frame. An
answer describes an older frame: the tracker seeds on the stored frame with the answer's stamp and
catches up through the frames since (perception/tracking.py has the rules). An answer is refused and
counted, and changes nothing, when no box carries the query's label, when its box does not hold the
colour the label names (min_label_color), holds nothing trackable, is lost while catching up, or is
older than max_answer_age_s. A lost track is `lost` with no box, never the last box; so is a track no
answer confirmed for max_grounding_age_s, or (vlm) that max_unconfirmed_answers answers in a row did
not confirm. Bad images, camera infos and boxes are counted and dropped; the node keeps running.

Time: frames and answers are matched and aged by their stamps (header.stamp; a frame without one gets
the node clock's now()), so sim time and wall time both work as long as the camera and the vlm node
stamp on the same clock; status_period_s is in the node's clock.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from go2vlm.bus import Node, core_params, from_core, param
from go2vlm.bus.topics import (
    CAMERA_IMAGE,
    CAMERA_INFO,
    ODOM,
    TARGET_QUERY,
    TARGET_TRACKED,
    TRACKER_DETECTIONS,
    TRACKER_STATUS,
    VLM_DETECTIONS,
)
from go2vlm.geometry.attitude import PitchHistory
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.geometry.rotations import quat_pitch
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.go2vlm_msgs import STATE_NAMES, TrackedTarget
from go2vlm.msgs.image import camera_model, to_bgr
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.sensor_msgs import CameraInfo, Image
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.msgs.vision_msgs import BoundingBox2D, Detection2DArray, bbox_2d, detection_array, detection_boxes
from go2vlm.perception.ranging import check_object_sizes
from go2vlm.perception.tracking import Grounding, Observation, TargetTracking, TrackingParams
from go2vlm.robot_profile import DEFAULT_ROBOT, PROFILES, profile
from go2vlm.robot_profile import go2 as spec

__all__ = ["TargetTrackerConfig", "TargetTrackerNode", "grounding_of", "tracked_msg"]

ROUTINE_REFUSALS = frozenset({"no_match", "stale"})  # refused in normal running: debug, not warnings

STATE_CODES = {name: code for code, name in STATE_NAMES.items()}


@dataclass
class TargetTrackerConfig:
    """The target_tracker's parameters: those of the TargetTracking core are its TrackingParams' fields
    (`from_core`: default, help, bounds, written there once); the camera mount is the robot profile's."""

    query: str = param("", help="label to track until /target/query says otherwise, e.g. 'red ball'")
    grounding: str = from_core(TrackingParams, "grounding")
    image_topic: str = param(CAMERA_IMAGE.name, help="sensor_msgs/Image input")
    camera_info_topic: str = param(CAMERA_INFO.name, help="sensor_msgs/CameraInfo input")
    odom_topic: str = param(ODOM.name, help="nav_msgs/Odometry input: the body's pitch, for ranging")
    reground_period_s: float = from_core(TrackingParams, "reground_period_s")
    min_shape_score: float = from_core(TrackingParams, "min_shape_score")
    min_label_color: float = from_core(TrackingParams, "min_label_color")
    max_answer_age_s: float = from_core(TrackingParams, "max_answer_age_s")
    max_grounding_age_s: float = from_core(TrackingParams, "max_grounding_age_s")
    max_unconfirmed_answers: int = from_core(TrackingParams, "max_unconfirmed_answers")
    robot: str = param(
        DEFAULT_ROBOT, help="the robot whose head camera this is: its height and pitch, for ranging",
        choices=tuple(PROFILES),
    )  # fmt: skip
    default_hfov_deg: float = param(
        round(spec.head_camera_hfov_deg(640, 480), 1),
        help="horizontal FOV used until a CameraInfo arrives",
        min=10.0,
        max=170.0,
    )
    object_sizes: dict[str, float] = from_core(TrackingParams, "object_sizes")
    status_period_s: float = param(1.0, help="/target_tracker/status period besides on-change", min=0.1, max=60.0)

    def validate(self) -> None:
        check_object_sizes(self.object_sizes)

    def tracking_params(self) -> TrackingParams:
        head = profile(self.robot)
        return core_params(
            TrackingParams,
            self,
            camera_height_m=head.head_camera_height,
            camera_pitch_rad=math.radians(head.head_camera.pitch_deg),
            object_sizes={k: float(v) for k, v in self.object_sizes.items()},
        )


def grounding_of(msg: Detection2DArray) -> Grounding:
    """A Detection2DArray -> a Grounding (labelled x1, y1, x2, y2 boxes)."""
    return Grounding(msg.header.stamp.to_sec(), tuple((label, box) for label, box, _ in detection_boxes(msg)))


def tracked_msg(obs: Observation, header: Header, camera: PinholeCamera) -> TrackedTarget:
    """An Observation -> the TrackedTarget of its frame; `camera`: the frame's camera model."""
    return TrackedTarget(
        header=header,
        label=obs.label,
        state=STATE_CODES[obs.state],
        bbox=BoundingBox2D() if obs.box is None else bbox_2d(obs.box),
        image_width=obs.width,
        image_height=obs.height,
        confidence=float(obs.confidence),
        bearing_rad=math.nan if obs.bearing is None else float(obs.bearing),
        hfov_rad=float(camera.scaled_to(obs.width, obs.height).hfov),
        distance_m=math.nan if obs.distance is None else float(obs.distance),
        range_method=obs.range_method,
        grounding_age_s=math.nan if obs.grounding_age is None else float(obs.grounding_age),
    )


class TargetTrackerNode(Node):
    """The ``target_tracker`` node; its contract (topics, grounding, parameters) is the module docstring."""

    name = "target_tracker"
    Config = TargetTrackerConfig

    def __init__(self, config: TargetTrackerConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        cfg: TargetTrackerConfig = self.config
        self.tracking = TargetTracking(cfg.tracking_params())
        self.tracking.set_query(cfg.query)
        self._cam: PinholeCamera | None = None
        self.pitch = PitchHistory()
        self.frames = 0
        self.last: Observation | None = None
        self._last_status_key: tuple[str, str] | None = None
        self.pub_tracked = TARGET_TRACKED.publisher(self)
        self.pub_status = TRACKER_STATUS.publisher(self)
        TARGET_QUERY.subscription(self, self.on_query)
        CAMERA_IMAGE.subscription(self, self.on_image, name=cfg.image_topic)
        CAMERA_INFO.subscription(self, self.on_camera_info, name=cfg.camera_info_topic)
        ODOM.subscription(self, self.on_odom, name=cfg.odom_topic)
        if cfg.grounding == "vlm":
            VLM_DETECTIONS.subscription(self, self.on_detections)
        else:
            self.pub_answers = TRACKER_DETECTIONS.publisher(self)
        self.create_timer(cfg.status_period_s, self.publish_status)
        self.publish_status()
        self.log.info(f"grounding={cfg.grounding}, query={cfg.query!r}, listening on {self.resolve(cfg.image_topic)}")

    # -- inputs ------------------------------------------------------------------------------
    def on_query(self, msg: String) -> None:
        before = self.tracking.query
        self.tracking.set_query(msg.data[:200])
        q = self.tracking.query
        if q == before:
            return
        self.log.info(f"tracking {q.text!r}" if q else "query cleared: tracking nothing")
        if q is not None and self.tracking.state == "ungroundable":
            self.log.warning(
                f"the colour-shape grounder cannot ground {q.text!r}: it knows red/green/blue/yellow "
                "ball/box/cylinder; run the vlm node (mode=detect) and grounding=vlm for other objects"
            )
        self.publish_status()

    def on_camera_info(self, msg: CameraInfo) -> None:
        try:
            self._cam = camera_model(msg)
        except (ValueError, IndexError) as exc:
            n = self.count("bad_camera_info")
            self.log.throttled("error", 5.0, f"ignoring a CameraInfo ({n} so far): {exc}", key="caminfo")

    def on_odom(self, msg: Odometry) -> None:
        q = msg.pose.pose.orientation
        if not self.pitch.add(msg.header.stamp.to_sec(), quat_pitch(q.w, q.x, q.y, q.z)):
            self.count("odom_refused")

    def on_detections(self, msg: Detection2DArray) -> None:
        if not msg.detections:
            self.count("empty_answers")
        why = self.tracking.add_answer(grounding_of(msg))
        if why is not None:
            # The object not in view yet, or an answer about an old frame, is normal (counted on the status).
            level = "debug" if self.tracking.last_refusal.split(":")[0] in ROUTINE_REFUSALS else "warning"
            self.log.throttled(level, 5.0, f"refused a grounding answer: {self.tracking.last_refusal}", key="ref")
        self._status_if_changed()

    def on_image(self, msg: Image) -> None:
        try:
            bgr = to_bgr(msg)
        except ValueError as exc:
            n = self.count("bad_images")
            self.log.throttled("error", 5.0, f"dropping a bad image ({n} so far): {exc}", key="image")
            return
        self.frames += 1
        h, w = bgr.shape[:2]
        header = msg.header
        if not (header.stamp.sec or header.stamp.nanosec):  # an unstamped camera: stamp it on arrival
            header = Header(stamp=self.stamp(), frame_id=header.frame_id)
        cam = self._cam.scaled_to(w, h) if self._cam is not None else None
        if cam is None:
            cam = PinholeCamera.from_hfov(w, h, math.radians(self.config.default_hfov_deg))
        t = header.stamp.to_sec()
        obs = self.tracking.on_frame(t, bgr, cam, self.pitch.at(t))
        self.last = obs
        stamp = Time(sec=header.stamp.sec, nanosec=header.stamp.nanosec)
        self.pub_tracked.publish(tracked_msg(obs, Header(stamp=stamp, frame_id=header.frame_id), cam))
        for _, box in self.tracking.color_answers:  # the colour grounder's answers (about this frame), as a VLM's
            h = Header(stamp=stamp, frame_id=header.frame_id)
            self.pub_answers.publish(detection_array(h, [] if box is None else [(obs.label, box, 1.0)]))
        self.tracking.color_answers.clear()
        self._status_if_changed()

    # -- status --------------------------------------------------------------------------------
    def _status_if_changed(self) -> None:
        key = (self.tracking.state, self.tracking.last_refusal)
        if key != self._last_status_key:
            if self._last_status_key is not None and key[0] != self._last_status_key[0]:
                self.log.info(f"{self._last_status_key[0]} -> {key[0]}")
            self.publish_status()

    def status(self) -> dict[str, Any]:
        q = self.tracking.query
        obs = self.last if self.last is not None and self.last.box is not None else None
        return {
            "query": q.text if q else "",
            "state": self.tracking.state,
            "grounding": self.config.grounding,
            "box": [round(v, 1) for v in obs.box] if obs and obs.box else None,
            "distance_m": round(obs.distance, 3) if obs and obs.distance is not None else None,
            "last_refusal": self.tracking.last_refusal,
            "frames": self.frames,
            "counters": {**self.tracking.counters, **self.counters},
        }

    def publish_status(self) -> None:
        self._last_status_key = (self.tracking.state, self.tracking.last_refusal)
        self.pub_status.publish(String(data=json.dumps(self.status(), ensure_ascii=False)))
