"""commander: language goals -> a grounded, tracked target -> safe motion.

"follow the red ball", "go to the blue cylinder", "look for the green box", "stop", "sit", "stand"
(and Chinese: 跟着红球, 走到蓝色圆柱, 找一下绿色盒子, 停下, 坐下, 站起来; see behavior/goals.py).

Topics
  subscribes  /goal                 std_msgs/String       a goal as text (also the `goal` parameter)
              <image_topic>         sensor_msgs/Image     (/camera/image_raw, sensor-data QoS)
              <camera_info_topic>   sensor_msgs/CameraInfo  intrinsics for ranging (/camera/camera_info)
              /vlm/detections       vision_msgs/Detection2DArray  only with grounding=vlm (the vlm node in
                                                          mode=detect): boxes in the image's pixels
  publishes   /detected_target      geometry_msgs/PointStamped  follow goals with follow_control=follower:
                                    the colour detector's convention (x, y in -1..1 from the centre,
                                    z = half the box's larger side / (w/2)); the follower drives
              /behavior/cmd_vel     geometry_msgs/Twist   go to / look for (and follow with
                                    follow_control=self) at control_rate_hz; lowest priority in the
                                    safety gate (/teleop > /follower > /behavior)
              /go2/command          std_msgs/String       "sit" / "stand" (the Go2 driver / sim acts)
              /commander/status     std_msgs/String       latched JSON: goal, kind, target, state,
                                    reason, seen, x, distance_m, decision, counters; on every change
                                    and every status_period_s

Goals and states
  follow    tracking | lost | searching(self mode only)        never ends by itself
  go to     searching -> approaching -> reached (stops at stop_distance_m, base -> object surface)
  look for  searching -> aligning -> found (target centred), or not_found after search_timeout_s
  stop      stopped (zero velocity); sit / stand -> done; text it cannot parse -> rejected: reason on
            /commander/status, zero velocity, nothing else moves.
  Target not seen for lost_timeout_s: zero at once; go to / look for then search (turn in place
  towards where it was last seen) if search_on_loss.

Grounding (`grounding`)
  color  (default, no weights) perception/grounding.py: red/green/blue/yellow x ball/box/cylinder from
         HSV segmentation and contour shape; re-run every reground_period_s while tracking.
  vlm    the vlm node's /vlm/detections: the detection whose label matches the goal's object.
  Between groundings a CamShift tracker (perception/tracker.py) follows the target every frame;
  a VLM answer (which describes an older frame) re-seeds it on that frame and is fast-forwarded
  through the frames since.

Decisions (decision_period_s > 0, decision_model set): every period a VLM (the vlm package's
backends, run on this node's worker thread) is asked "is there a person or an obstacle ahead?" and
must answer with the schema of behavior/decisions.py: stop | continue | turn (|angle| <= 30 deg) |
sit. Anything else is ignored, logged and counted (decisions_rejected). The text never becomes a
velocity: stop holds still for decision_hold_s, turn turns in place at decision_turn_rate for
angle/rate seconds, and all motion still goes through the safety gate.

Parameters at runtime: the gains, speeds, distances, timeouts and search settings, frame_id,
default_hfov_deg, camera_forward_m and decision_hold_s/decision_turn_rate (the approach parameters are
rebuilt at once); read-only: goal (use /goal), grounding, follow_control, the topics, the rates, the
ranging set-up of a goal (camera_height_m, camera_pitch_deg, object_sizes) and the decision model.
Time: every period and timeout here (control_rate_hz, lost_timeout_s, search_timeout_s,
reground_period_s, decision_period_s, decision_hold_s, turns, the zero burst) is in the node's clock:
sim time with use_sim_time. vlm_max_age_s compares the answer's stamp with the newest frame's stamp,
so it holds in either mode as long as the camera and the vlm node stamp on the same clock.
"""

from __future__ import annotations

import json
import math
import queue
import threading
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from go2vlm.behavior.approach import DEFAULT_SIZES, ApproachParams, RangeEstimator, RangeReading, approach_command
from go2vlm.behavior.decisions import DECISION_PROMPT, Decision, DecisionRejected, parse_decision
from go2vlm.behavior.goals import Goal, GoalParseError, Target, parse_goal, parse_target
from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node, param
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.geometry.target import normalized_target
from go2vlm.msgs.geometry_msgs import Point, PointStamped, Twist, Vector3
from go2vlm.msgs.image import camera_model, to_bgr
from go2vlm.msgs.sensor_msgs import CameraInfo, Image
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.msgs.vision_msgs import Detection2DArray
from go2vlm.perception.grounding import ground
from go2vlm.perception.tracker import HistTracker
from go2vlm.robots.go2 import spec

__all__ = ["CommanderConfig", "CommanderNode", "match_detection"]

TERMINAL = ("idle", "stopped", "rejected", "done", "reached", "found", "not_found", "sat")
HISTORY_FRAMES = 40  # frames kept for fast-forwarding a late VLM answer (4 s at 10 Hz)
ZERO_BURST_S = 0.5  # zeros sent after a goal ends, then /behavior/cmd_vel goes quiet
CENTRED_X = 0.1  # look for: |x| below this counts as found


@dataclass
class CommanderConfig:
    goal: str = param("", help="goal to start with, e.g. 'follow the red ball' or 走到蓝色圆柱 ('' = wait for /goal)")
    grounding: str = param("color", choices=("color", "vlm"), help="color: no weights; vlm: /vlm/detections")
    follow_control: str = param(
        "follower", choices=("follower", "self"), help="follow: /detected_target for the follower, or own control"
    )
    image_topic: str = param("/camera/image_raw", help="sensor_msgs/Image input")
    camera_info_topic: str = param("/camera/camera_info", help="sensor_msgs/CameraInfo input")
    stop_distance_m: float = param(
        0.8, help="go to: stop this far from the object's surface (base)", min=0.2, max=5.0, live=True
    )
    follow_distance_m: float = param(1.2, help="follow_control=self: keep this distance", min=0.3, max=5.0, live=True)
    distance_tolerance_m: float = param(
        0.05, help="go to: reached within this of stop_distance_m", min=0.0, max=1.0, live=True
    )
    max_linear: float = param(
        0.4, help="forward speed ceiling (m/s); the gate limits again", min=0.0, max=1.0, live=True
    )
    max_angular: float = param(0.8, help="|yaw rate| ceiling (rad/s)", min=0.0, max=2.0, live=True)
    kp_linear: float = param(0.8, help="go to: P gain from distance error to linear.x", min=0.0, max=5.0, live=True)
    kp_angular: float = param(1.5, help="P gain from horizontal offset x to angular.z", min=0.0, max=10.0, live=True)
    search_yaw_rate: float = param(0.5, help="turn rate while searching (rad/s)", min=0.05, max=1.5, live=True)
    search_timeout_s: float = param(30.0, help="give up searching after this long", min=1.0, max=600.0, live=True)
    search_on_loss: bool = param(True, help="go to / look for: search again when the target is lost", live=True)
    lost_timeout_s: float = param(
        1.0, help="target unseen this long = lost (zero velocity)", min=0.1, max=10.0, live=True
    )
    reground_period_s: float = param(
        0.5, help="color grounding: re-ground this often while tracking", min=0.0, live=True
    )
    min_shape_score: float = param(
        0.35, help="color grounding: shape score needed to accept", min=0.0, max=1.0, live=True
    )
    vlm_max_age_s: float = param(
        5.0, help="vlm grounding: ignore answers about frames older than this", min=0.1, live=True
    )
    camera_height_m: float = param(spec.HEAD_CAMERA_HEIGHT, help="camera height above the floor (ranging)", min=0.05)
    camera_forward_m: float = param(
        spec.HEAD_CAMERA_POS[0], help="camera ahead of the base centre", min=-1.0, max=1.0, live=True
    )
    camera_pitch_deg: float = param(0.0, help="camera pitch, + = looking down", min=-45.0, max=45.0)
    default_hfov_deg: float = param(
        round(spec.head_camera_hfov_deg(640, 480), 1),
        help="horizontal FOV used until a CameraInfo arrives",
        min=10.0,
        max=170.0,
        live=True,
    )
    object_sizes: dict = param(
        dict(DEFAULT_SIZES), help="ranging before calibration: ball/cylinder radius, box width (m)"
    )
    control_rate_hz: float = param(20.0, help="control loop rate", min=2.0, max=100.0)
    status_period_s: float = param(1.0, help="/commander/status period besides on-change", min=0.1, max=60.0)
    frame_id: str = param("camera", help="frame_id of /detected_target", live=True)
    decision_period_s: float = param(0.0, help="VLM scene decision period (0 = off)", min=0.0, max=600.0)
    decision_model: str = param("", help="decisions: checkpoint dir / hub id / served model name")
    decision_backend: str = param("transformers", choices=("transformers", "openai"), help="decisions backend")
    decision_base_url: str = param("http://127.0.0.1:8000/v1", help="decisions, openai backend: server URL")
    decision_device: str = param("auto", help="decisions, transformers backend: auto, cpu, cuda, cuda:N")
    decision_max_new_tokens: int = param(48, help="decisions: generation budget", min=4, max=512)
    decision_max_pixels: int = param(256 * 28 * 28, help="decisions: image budget after smart resize", min=784)
    decision_hold_s: float = param(3.0, help="a 'stop' decision holds still this long", min=0.1, max=60.0, live=True)
    decision_turn_rate: float = param(0.5, help="turn rate of a 'turn' decision (rad/s)", min=0.05, max=1.0, live=True)
    max_turn_deg: float = param(30.0, help="largest |angle| a 'turn' decision may ask for", min=0.0, max=30.0)

    def validate(self) -> None:
        if self.decision_period_s > 0 and not self.decision_model.strip():
            raise ValueError("decision_period_s > 0 needs decision_model (a checkpoint dir or served model name)")
        for key, value in self.object_sizes.items():
            if key not in DEFAULT_SIZES:
                raise ValueError(f"object_sizes: unknown shape {key!r}; use {sorted(DEFAULT_SIZES)}")
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not 0.01 <= float(value) <= 20:
                raise ValueError(f"object_sizes[{key!r}] = {value!r} must be a number in 0.01..20 m")


def approach_params(cfg: CommanderConfig) -> ApproachParams:
    return ApproachParams(
        stop_distance=cfg.stop_distance_m,
        tolerance=cfg.distance_tolerance_m,
        kp_linear=cfg.kp_linear,
        kp_angular=cfg.kp_angular,
        max_linear=cfg.max_linear,
        min_linear=min(0.08, cfg.max_linear),
        max_angular=cfg.max_angular,
    )


def _words(text: str) -> set[str]:
    return {w for w in "".join(ch if ch.isalnum() else " " for ch in text.lower()).split() if w}


def match_detection(target: Target, labels: list[str]) -> int | None:
    """Index of the label that names `target` best (colour and shape agree; exact label first)."""
    best: tuple[int, int] | None = None
    want = _words(target.label)
    for i, label in enumerate(labels):
        if not label.strip():
            continue
        score = 0
        try:
            t2 = parse_target(label)
        except GoalParseError:
            t2 = Target(label=label)
        if target.color is not None or target.shape is not None:
            if target.color is not None and t2.color != target.color:
                continue
            if target.shape is not None and t2.shape != target.shape:
                continue
            score = 2 if (t2.color, t2.shape) == (target.color, target.shape) else 1
        else:
            have = _words(label)
            if not want or not want <= have:
                continue
            score = 2 if have == want else 1
        if best is None or score > best[0]:
            best = (score, i)
    return None if best is None else best[1]


class CommanderNode(Node):
    """The ``commander`` node; its contract (topics, goals, parameters) is the module docstring."""

    name = "commander"
    Config = CommanderConfig

    def __init__(self, config: CommanderConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        cfg: CommanderConfig = self.config
        self.approach = approach_params(cfg)
        self.pub_target = self.create_publisher(PointStamped, "/detected_target", QOS_DEFAULT)
        self.pub_cmd = self.create_publisher(Twist, "/behavior/cmd_vel", QOS_DEFAULT)
        self.pub_go2 = self.create_publisher(String, "/go2/command", QOS_DEFAULT)
        self.pub_status = self.create_publisher(String, "/commander/status", QOS_LATCHED)
        self.create_subscription(String, "/goal", self.on_goal, QOS_DEFAULT)
        self.create_subscription(Image, cfg.image_topic, self.on_image, QOS_SENSOR)
        self.create_subscription(CameraInfo, cfg.camera_info_topic, self.on_camera_info, QOS_SENSOR)
        if cfg.grounding == "vlm":
            self.create_subscription(Detection2DArray, "/vlm/detections", self.on_detections, QOS_DEFAULT)

        # goal and state (node thread only)
        self.goal: Goal | None = None
        self.state = "idle"
        self.reason = "no goal yet"
        self.tracker = HistTracker()
        self.ranger = RangeEstimator(None)
        self._t_state = self.clock.monotonic()
        self._t_search = 0.0
        self._last_seen: float | None = None
        self._ever_seen = False
        self._box: tuple[float, float, float, float] | None = None
        self._box_fresh = False
        self._box_stamp: Header | None = None
        self._last_x = 0.0
        self._range = RangeReading(None, "none")
        self._last_reground = -math.inf
        self._cmd = (0.0, 0.0)
        self._zero_until = 0.0
        self._hold_until = 0.0
        self._turn_until = 0.0
        self._turn_dir = 0.0
        self.last_decision: dict[str, Any] | None = None
        # inputs
        self._cam: PinholeCamera | None = None
        self._pending_image: Image | None = None
        self._pending_dets: Detection2DArray | None = None
        self._history: deque[tuple[float, np.ndarray]] = deque(maxlen=HISTORY_FRAMES)
        self._size: tuple[int, int] | None = None
        # decisions worker
        self._frame_lock = threading.Lock()
        self._latest_bgr: np.ndarray | None = None
        self._decisions: queue.Queue[tuple[str, Decision | DecisionRejected | str]] = queue.Queue()
        self._halt = threading.Event()
        self._worker: threading.Thread | None = None
        if cfg.decision_period_s > 0:
            self._worker = threading.Thread(target=self._decide_loop, name=f"{self.node_name}:decide", daemon=True)
            self._worker.start()

        self.create_timer(1.0 / cfg.control_rate_hz, self.tick)
        self.create_timer(cfg.status_period_s, self.publish_status)
        if cfg.goal.strip():
            self.set_goal(cfg.goal)
        else:
            self.publish_status()
        decisions = f"every {cfg.decision_period_s:g} s" if cfg.decision_period_s > 0 else "off"
        self.log.info(f"grounding={cfg.grounding}, follow_control={cfg.follow_control}, decisions={decisions}")

    def on_params_changed(self, old: CommanderConfig, changed: frozenset[str]) -> None:
        self.approach = approach_params(self.config)

    # -- inputs ------------------------------------------------------------------------------
    def on_goal(self, msg: String) -> None:
        self.set_goal(msg.data)

    def on_image(self, msg: Image) -> None:
        if self._pending_image is not None:
            self.count("frames_skipped")  # the newest frame wins
        self._pending_image = msg

    def on_camera_info(self, msg: CameraInfo) -> None:
        try:
            self._cam = camera_model(msg)
        except (ValueError, IndexError) as exc:
            n = self.count("bad_camera_info")
            self.log.throttled("error", 5.0, f"ignoring a CameraInfo ({n} so far): {exc}", key="caminfo")

    def on_detections(self, msg: Detection2DArray) -> None:
        self._pending_dets = msg

    # -- goals -------------------------------------------------------------------------------
    def set_goal(self, text: str) -> None:
        cfg: CommanderConfig = self.config
        now = self.clock.monotonic()
        try:
            goal = parse_goal(text)
            if goal.moves and goal.target is not None and cfg.grounding == "color" and not goal.target.classical:
                raise GoalParseError(
                    f"the colour grounder cannot find {goal.target.label!r}: it knows red/green/blue/yellow "
                    "ball/box/cylinder; run the vlm node (mode=detect) and set grounding=vlm for other objects"
                )
        except GoalParseError as exc:
            self.count("rejected_goals")
            self.log.throttled("warning", 1.0, f"goal rejected: {exc}", key="goal")
            self.goal = Goal("stop", None, str(text)[:200])
            self._enter("rejected", str(exc), now)
            return
        current = self.goal
        if (
            goal.moves
            and current is not None
            and (current.kind, current.target) == (goal.kind, goal.target)
            and self.state not in TERMINAL
        ):
            self.publish_status()  # the same goal again (a UI re-sending it): carry on, don't restart
            return
        self.goal = goal
        self.tracker.reset()
        shape = goal.target.shape if goal.target else None
        self.ranger = RangeEstimator(
            shape,
            camera_height=cfg.camera_height_m,
            camera_pitch=math.radians(cfg.camera_pitch_deg),
            default_sizes={k: float(v) for k, v in cfg.object_sizes.items()},
        )
        self._last_seen = None
        self._ever_seen = False
        self._box = None
        self._range = RangeReading(None, "none")
        self._last_reground = -math.inf
        self._hold_until = self._turn_until = 0.0
        self.log.info(f"goal: {goal.describe()} ({text!r})")
        if goal.kind == "stop":
            self._enter("stopped", "stop requested", now)
        elif goal.kind in ("sit", "stand"):
            self.pub_go2.publish(String(data=goal.kind))
            self._enter("done", f"sent {goal.kind!r} on /go2/command", now)
        else:
            self._t_search = now
            label = goal.target.label if goal.target else ""
            if goal.kind == "follow" and cfg.follow_control == "follower":
                self._enter("waiting", f"waiting for the {label} to come into view", now)
            else:
                self._enter("searching", f"looking for the {label}", now)

    def _enter(self, state: str, reason: str, now: float) -> None:
        if state != self.state or reason != self.reason:
            self.log.info(f"{self.state} -> {state}: {reason}" if state != self.state else reason)
        self.state, self.reason, self._t_state = state, reason, now
        if state in TERMINAL:
            self._cmd = (0.0, 0.0)
            self._zero_until = now + ZERO_BURST_S
            self._publish_cmd(0.0, 0.0)
        self.publish_status()

    # -- perception ----------------------------------------------------------------------------
    def _camera(self, width: int, height: int) -> PinholeCamera:
        if self._cam is None:
            return PinholeCamera.from_hfov(width, height, math.radians(self.config.default_hfov_deg))
        return self._cam.scaled_to(width, height)

    def _decode(self, msg: Image) -> np.ndarray | None:
        try:
            return to_bgr(msg)
        except ValueError as exc:
            n = self.count("bad_images")
            self.log.throttled("error", 5.0, f"dropping a bad image ({n} so far): {exc}", key="image")
            return None

    def _perceive(self, now: float) -> None:
        msg, self._pending_image = self._pending_image, None
        self._box_fresh = False
        bgr = self._decode(msg) if msg is not None else None
        if bgr is not None:
            self._size = (bgr.shape[1], bgr.shape[0])
            stamp = msg.header.stamp.to_sec()
            self._history.append((stamp, bgr))
            with self._frame_lock:
                self._latest_bgr = bgr
        goal = self.goal
        tracking = goal is not None and goal.moves and self.state not in TERMINAL
        if not tracking:
            self._pending_dets = None
            return
        if self._pending_dets is not None:
            self._reseed_from_vlm(self._pending_dets)
            self._pending_dets = None
        if bgr is None:
            return
        box: tuple[float, float, float, float] | None = None
        if self.tracker.active:
            track = self.tracker.update(bgr)
            box = track.xyxy if track else None
        cfg: CommanderConfig = self.config
        if cfg.grounding == "color" and (box is None or now - self._last_reground >= cfg.reground_period_s):
            self._last_reground = now
            assert goal is not None and goal.target is not None
            cands = ground(bgr, goal.target.color, goal.target.shape, min_shape_score=cfg.min_shape_score)
            if cands:
                pick = cands[0]
                if box is not None:  # prefer the candidate that is the tracked object
                    pick = max(cands, key=lambda c: _iou(c.xyxy, box))
                    if _iou(pick.xyxy, box) < 0.1:
                        pick = cands[0]
                if self.tracker.init(bgr, pick.bbox):
                    box = pick.xyxy
        if box is not None:
            self._box, self._box_fresh, self._box_stamp = box, True, msg.header
            self._last_seen = now
            self._ever_seen = True
            w, h = bgr.shape[1], bgr.shape[0]
            self._last_x = normalized_target(box, w, h)[0]
            self._range = self.ranger.estimate(box, self._camera(w, h))

    def _reseed_from_vlm(self, msg: Detection2DArray) -> None:
        goal = self.goal
        assert goal is not None and goal.target is not None
        labels = [d.results[0].hypothesis.class_id if d.results else "" for d in msg.detections]
        idx = match_detection(goal.target, labels)
        if idx is None:
            self.count("vlm_no_match")
            return
        det = msg.detections[idx]
        stamp = msg.header.stamp.to_sec()
        if not self._history:
            return
        if stamp > 0 and self._history[-1][0] - stamp > self.config.vlm_max_age_s:
            self.count("vlm_stale")
            return
        b = det.bbox
        vals = (b.center.position.x, b.center.position.y, b.size_x, b.size_y)
        if not all(math.isfinite(v) for v in vals) or b.size_x <= 1 or b.size_y <= 1:
            n = self.count("bad_detections")
            self.log.throttled("error", 5.0, f"ignoring a detection with a bad box ({n} so far): {vals}", key="det")
            return
        xywh = (vals[0] - vals[2] / 2, vals[1] - vals[3] / 2, vals[2], vals[3])
        # Seed on the frame the model saw, then catch up through the frames that came since.
        frames = list(self._history)
        start = 0 if stamp <= 0 else min(range(len(frames)), key=lambda i: abs(frames[i][0] - stamp))
        if stamp <= 0:
            start = len(frames) - 1
        if not self.tracker.init(frames[start][1], xywh):
            self.count("vlm_seed_failed")
            return
        for _, img in frames[start + 1 :]:
            if self.tracker.update(img) is None:
                self.count("vlm_lost_in_catch_up")
                return
        self.count("vlm_reseeds")

    # -- control -------------------------------------------------------------------------------
    def tick(self) -> None:
        now = self.clock.monotonic()
        self._perceive(now)
        self._apply_decisions(now)
        goal = self.goal
        if goal is None or self.state in TERMINAL:
            if now < self._zero_until:
                self._publish_cmd(0.0, 0.0)
            return
        cfg: CommanderConfig = self.config
        if now < self._hold_until:
            self._set_state("holding", "a VLM decision said stop", now)
            self._publish_cmd(0.0, 0.0)
            return
        if now < self._turn_until:
            self._set_state("turning", "a VLM decision said turn", now)
            self._publish_cmd(0.0, self._turn_dir * min(cfg.decision_turn_rate, cfg.max_angular))
            return
        seen = self._last_seen is not None and now - self._last_seen < cfg.lost_timeout_s
        if seen:
            self._t_search = now
        if goal.kind == "follow":
            self._tick_follow(now, seen)
        elif goal.kind == "go_to":
            self._tick_go_to(now, seen)
        else:
            self._tick_look_for(now, seen)

    def _set_state(self, state: str, reason: str, now: float) -> None:
        if state != self.state:
            self._enter(state, reason, now)
        else:
            self.reason = reason

    def _search(self, now: float) -> None:
        cfg: CommanderConfig = self.config
        assert self.goal is not None and self.goal.target is not None
        if now - self._t_search > cfg.search_timeout_s:
            self._enter("not_found", f"no {self.goal.target.label} in view after {cfg.search_timeout_s:g} s", now)
            return
        direction = -1.0 if self._last_x > 0 else 1.0  # towards where it was last seen; left by default
        self._set_state("searching", f"turning in place to find the {self.goal.target.label}", now)
        self._publish_cmd(0.0, direction * min(cfg.search_yaw_rate, cfg.max_angular))

    def _lost(self, now: float) -> bool:
        """Zero while the target has just been lost; True while holding (no search yet)."""
        cfg: CommanderConfig = self.config
        assert self._last_seen is not None
        if now - self._last_seen < 2 * cfg.lost_timeout_s or not cfg.search_on_loss:
            self._set_state("lost", "target not in view: stopped", now)
            self._publish_cmd(0.0, 0.0)
            return True
        return False

    def _tick_follow(self, now: float, seen: bool) -> None:
        cfg: CommanderConfig = self.config
        if cfg.follow_control == "follower":
            if seen:
                self._set_state("tracking", "target in view: /detected_target for the follower", now)
                if self._box_fresh and self._box is not None and self._size is not None:
                    self._publish_target(self._box)
            elif self._ever_seen:
                self._set_state("lost", "target not in view: the follower stops on its own timeout", now)
            else:
                self._set_state("waiting", "target not in view yet", now)
            return
        if seen and self._box is not None:
            self._set_state("tracking", "target in view: following", now)
            dist = self._base_distance()
            params = ApproachParams(**{**self.approach.__dict__, "stop_distance": cfg.follow_distance_m})
            vx, wz, _ = approach_command(self._last_x, dist, params)
            self._publish_cmd(vx, wz)
        elif self._ever_seen and self._lost(now):
            return
        else:
            self._search(now)

    def _base_distance(self) -> float | None:
        d = self._range.distance
        return None if d is None else d + self.config.camera_forward_m

    def _tick_go_to(self, now: float, seen: bool) -> None:
        if seen and self._box is not None:
            dist = self._base_distance()
            vx, wz, reached = approach_command(self._last_x, dist, self.approach)
            if reached:
                self._enter("reached", f"{dist:.2f} m from the {self.goal.target.label} ({self._range.method})", now)
                return
            how = "unknown" if dist is None else f"{dist:.2f} m ({self._range.method})"
            self._set_state("approaching", f"target at {how}", now)
            self._publish_cmd(vx, wz)
        elif self._ever_seen and self._lost(now):
            return
        else:
            self._search(now)

    def _tick_look_for(self, now: float, seen: bool) -> None:
        cfg: CommanderConfig = self.config
        if seen and self._box is not None:
            if abs(self._last_x) < CENTRED_X:
                self._enter("found", f"the {self.goal.target.label} is straight ahead", now)
                return
            wz = max(-cfg.max_angular, min(cfg.max_angular, -cfg.kp_angular * self._last_x))
            # A slow search turn must not overshoot into a fast swing: at least a gentle turn.
            wz = math.copysign(max(abs(wz), 0.15), wz)
            self._set_state("aligning", "target in view: turning to face it", now)
            self._publish_cmd(0.0, wz)
        elif self._ever_seen and self._lost(now):
            return
        else:
            self._search(now)

    def _publish_cmd(self, vx: float, wz: float) -> None:
        self._cmd = (vx, wz)
        self.pub_cmd.publish(Twist(linear=Vector3(x=float(vx)), angular=Vector3(z=float(wz))))

    def _publish_target(self, box: tuple[float, float, float, float]) -> None:
        assert self._size is not None
        x, y, z = normalized_target(box, *self._size)
        stamp = self._box_stamp.stamp if self._box_stamp is not None else self.stamp()
        header = Header(stamp=stamp, frame_id=self.config.frame_id)
        self.pub_target.publish(PointStamped(header=header, point=Point(x=x, y=y, z=z)))

    # -- decisions -----------------------------------------------------------------------------
    def _apply_decisions(self, now: float) -> None:
        cfg: CommanderConfig = self.config
        while True:
            try:
                text, result = self._decisions.get_nowait()
            except queue.Empty:
                return
            if isinstance(result, str):  # a backend failure
                self.count("decision_errors")
                self.log.throttled("error", 10.0, f"decision query failed: {result}", key="decide")
                continue
            if isinstance(result, DecisionRejected):
                n = self.count("decisions_rejected")
                self.count(f"decisions_rejected.{result.reason}")
                self.last_decision = {"accepted": False, "reason": result.reason, "answer": text[:120]}
                self.log.throttled(
                    "warning", 5.0, f"ignored a VLM decision outside the schema ({n} so far): {result}", key="dec"
                )
                continue
            self.count("decisions_accepted")
            self.last_decision = {"accepted": True, **result.to_dict()}
            active = self.goal is not None and self.goal.moves and self.state not in TERMINAL
            if not active:
                continue
            if result.action == "stop":
                self._hold_until = now + cfg.decision_hold_s
            elif result.action == "continue":
                self._hold_until = 0.0
            elif result.action == "turn":
                rate = min(cfg.decision_turn_rate, cfg.max_angular)
                angle = math.radians(result.angle_deg)
                self._turn_dir = math.copysign(1.0, angle) if angle else 0.0
                self._turn_until = now + (abs(angle) / rate if rate > 0 else 0.0)
            elif result.action == "sit":
                self.pub_go2.publish(String(data="sit"))
                self._enter("sat", "a VLM decision said sit: sent 'sit' on /go2/command", now)

    def _decide_loop(self) -> None:
        from go2vlm.perception.vlm.backend import BackendSettings, resolve_api_key
        from go2vlm.perception.vlm.factory import make_backend

        cfg: CommanderConfig = self.config
        settings = BackendSettings(
            model=cfg.decision_model,
            backend=cfg.decision_backend,
            device=cfg.decision_device,
            max_new_tokens=cfg.decision_max_new_tokens,
            max_pixels=cfg.decision_max_pixels,
            min_pixels=min(cfg.decision_max_pixels, 56 * 56),
            base_url=cfg.decision_base_url,
            api_key=resolve_api_key(None),
        )
        try:
            backend = make_backend(settings)
            backend.load()
        except Exception as exc:  # noqa: BLE001 - reported in status; the node keeps running without decisions
            self._decisions.put(("", f"cannot load the decision model: {type(exc).__name__}: {exc}"))
            return
        self.log.info(f"decision model ready: {getattr(backend, 'description', cfg.decision_model)}")
        try:
            while not self.clock.sleep(cfg.decision_period_s, self._halt):
                goal, state = self.goal, self.state  # read across threads: a stale value only skips a turn
                if goal is None or not goal.moves or state in TERMINAL:
                    continue
                with self._frame_lock:
                    bgr = self._latest_bgr
                if bgr is None:
                    continue
                rgb = np.ascontiguousarray(bgr[:, :, ::-1])
                try:
                    text = backend.generate(rgb, DECISION_PROMPT).text
                except Exception as exc:  # noqa: BLE001
                    self._decisions.put(("", f"{type(exc).__name__}: {exc}"))
                    continue
                try:
                    result: Decision | DecisionRejected = parse_decision(text, self.config.max_turn_deg)
                except DecisionRejected as rej:
                    result = rej
                self._decisions.put((text, result))
        finally:
            try:
                backend.close()
            except Exception:  # noqa: BLE001
                pass

    # -- status --------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        goal = self.goal
        now = self.clock.monotonic()
        seen = self._last_seen is not None and now - self._last_seen < self.config.lost_timeout_s
        return {
            "goal": goal.text if goal else "",
            "kind": goal.kind if goal else None,
            "target": goal.target.label if goal and goal.target else None,
            "state": self.state,
            "reason": self.reason,
            "grounding": self.config.grounding,
            "seen": seen,
            "x": round(self._last_x, 4) if seen else None,
            "distance_m": None if (d := self._base_distance()) is None or not seen else round(d, 3),
            "range_method": self._range.method if seen else None,
            "cmd": [round(self._cmd[0], 4), round(self._cmd[1], 4)],
            "decision": self.last_decision,
            "counters": dict(self.counters),
        }

    def publish_status(self) -> None:
        self.pub_status.publish(String(data=json.dumps(self.status(), ensure_ascii=False)))

    def close(self) -> None:
        self._halt.set()
        if self._worker is not None:
            self._worker.join(timeout=5.0)
        # Leave the robot still: the gate also times the input out, this is just faster.
        try:
            self._publish_cmd(0.0, 0.0)
        except Exception:  # noqa: BLE001 - the writer may already be gone
            pass


def _iou(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0
