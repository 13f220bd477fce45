"""commander: language goals -> what the robot does, over the target_tracker's confirmed target.

"follow the red ball", "go to the blue cylinder", "look for the green box", "stop", "sit", "stand",
"turn left 20 degrees" (and Chinese: 跟着红球, 走到蓝色圆柱, 找一下绿色盒子, 停下, 坐下, 站起来; see behavior/goals.py).
A thin node over the pure Mission core (behavior/mission.py has the rules); it does not look at
images: the target_tracker grounds, tracks and ranges, the vlm node answers decisions.

Topics (QoS: reliable, volatile, keep-last 10 unless noted)
  subscribes  /goal               std_msgs/String       a goal as text (also the `goal` parameter)
              /target/tracked     go2vlm_msgs/TrackedTarget  the target_tracker's target, one per camera
                                  frame; only `tracking` reports for the goal's object count
              /vlm/decision       std_msgs/String       raw VLM scene decisions (the vlm node in
                                  mode=decide), mapped onto the whitelist of behavior/decisions.py
              /scan               sensor_msgs/LaserScan  best-effort, keep-last 5 (`scan_topic`, frame
                                  base_link): obstacles for the local planner (avoid_obstacles)
              /odom               nav_msgs/Odometry     (`odom_topic`): keeps the target's last confirmed
                                  place while a detour takes it out of view
  publishes   /target/query       std_msgs/String, latched (transient-local, keep-last 1): the goal's
                                  object while a motion goal runs ("blue cylinder"), else ''; the
                                  target_tracker tracks it and the vlm node (mode=detect) grounds it
              /behavior/cmd_vel   geometry_msgs/Twist   go to / look for / search (and follow with
                                  follow_control=self) at control_rate_hz; zeros for 0.5 s after a goal
                                  ends, then quiet; lowest priority in the safety gate
                                  (/teleop > /follower > /behavior)
              /detected_target    geometry_msgs/PointStamped  follow goals with follow_control=follower,
                                  while the target is confirmed and no decision holds: the tracked box
                                  in the colour detector's convention (geometry/target.py: x, y in -1..1
                                  from the centre, z = half the box's larger side / (w/2)), stamped with
                                  the source frame's header; the follower drives
              /go2/command        std_msgs/String       "sit" / "stand" (the Go2 driver / sim acts)
              /commander/status   std_msgs/String       latched JSON: goal, kind, target, state, reason,
                                  seen, x, distance_m, range_method, tracker, cmd, decision, counters;
                                  on every change and every status_period_s

Goals and states
  follow    tracking | waiting | lost | searching(self mode only)   never ends by itself
  go to     searching -> approaching -> reached (stops at stop_distance_m, base -> object surface);
            detouring while the local planner (behavior/planner.py) steers round an obstacle on /scan
  look for  searching -> aligning -> found (target centred), or not_found after search_timeout_s
  turn      turning (in place at decision_turn_rate, |angle| <= 30 deg) -> done
  stop      stopped (zero velocity); sit / stand -> done; text it cannot parse -> rejected: reason on
            /commander/status, zero velocity, nothing else moves; an object the target_tracker cannot
            ground (free text with its colour grounder) -> rejected.
  The target counts only while the tracker confirms it (its newest report says tracking, younger than
  lost_timeout_s): otherwise zero at once (`lost`), then go to / look for search (turn in place
  towards where it was last seen) if search_on_loss.

Obstacles: with a fresh /scan (younger than scan_timeout_s) go to and follow (follow_control=self)
steer round what lies between the robot and the target, planner_margin_m each side of the footprint.
A detour that takes the target out of the camera's view carries on towards its last confirmed place
(from /odom) for up to detour_memory_s, and only while the direct way is blocked. Without a scan the
approach is straight; the safety gate's collision guard stops it short of anything either way. Follow
with follow_control=follower is the article's follower: the gate's guard is what keeps it off walls.

Decisions (/vlm/decision): stop | continue | turn (|angle| <= max_turn_deg <= 30) | sit; anything else
is ignored, logged and counted (decisions_rejected). The text never becomes a velocity: stop holds
still for decision_hold_s, turn turns in place at decision_turn_rate for angle/rate seconds; all
motion still goes through the safety gate.

Time: every period and timeout here (control_rate_hz, lost_timeout_s, search_timeout_s,
decision_hold_s, turns, the zero burst) is in the node's clock: sim time with use_sim_time.

Parameters at runtime (`go2vlm param set commander ...`): the gains, speeds, distances, timeouts,
search settings, decision limits and avoid_obstacles, planner_margin_m, detour_memory_s; goal (use
/goal), follow_control, the topics, scan_timeout_s, camera_fovy_deg and the rates are read-only.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from go2vlm.behavior.mission import Intent, Mission, MissionParams, Sighting
from go2vlm.behavior.planner import PlannerParams
from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node, param
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.geometry.rotations import quat_yaw
from go2vlm.geometry.scan import frame_scan_points
from go2vlm.geometry.target import normalized_target
from go2vlm.msgs.geometry_msgs import Point, PointStamped, Twist, Vector3
from go2vlm.msgs.go2vlm_msgs import STATE_NAMES, TrackedTarget
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.sensor_msgs import LaserScan
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.robot_profile import go2 as spec

__all__ = ["CommanderConfig", "CommanderNode"]

MAX_IMAGE_SIDE = 100_000  # a TrackedTarget claiming a bigger image is garbage


@dataclass
class CommanderConfig:
    goal: str = param("", help="goal to start with, e.g. 'follow the red ball' or 走到蓝色圆柱 ('' = wait for /goal)")
    follow_control: str = param(
        "follower", choices=("follower", "self"), help="follow: /detected_target for the follower, or own control"
    )
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
        1.0, help="a tracker report older than this confirms nothing", min=0.1, max=10.0, live=True
    )
    camera_forward_m: float = param(
        spec.HEAD_CAMERA_POS[0], help="camera ahead of the base centre", min=-1.0, max=1.0, live=True
    )
    camera_fovy_deg: float = param(
        spec.HEAD_CAMERA_FOVY_DEG, help="the camera's vertical field of view: a box's bearing", min=1.0, max=170.0
    )
    avoid_obstacles: bool = param(True, help="go to / follow (self): steer round obstacles on scan_topic", live=True)
    scan_topic: str = param("/scan", help="sensor_msgs/LaserScan in base_link for the local planner")
    odom_topic: str = param("/odom", help="nav_msgs/Odometry: the target's place while a detour hides it")
    scan_timeout_s: float = param(0.5, help="a scan older than this (s) is no scan: no planning", min=0.05, max=5.0)
    planner_margin_m: float = param(
        0.35, help="local planner: free space each side of the footprint", min=0.1, max=1.5, live=True
    )
    detour_memory_s: float = param(
        8.0, help="a detour out of view lasts this long after the last sighting (s)", min=0.0, max=60.0, live=True
    )
    control_rate_hz: float = param(20.0, help="control loop rate", min=2.0, max=100.0)
    status_period_s: float = param(1.0, help="/commander/status period besides on-change", min=0.1, max=60.0)
    decision_hold_s: float = param(3.0, help="a 'stop' decision holds still this long", min=0.1, max=60.0, live=True)
    decision_turn_rate: float = param(0.5, help="turn rate of a 'turn' decision (rad/s)", min=0.05, max=1.0, live=True)
    max_turn_deg: float = param(
        30.0, help="largest |angle| a 'turn' decision may ask for", min=0.0, max=30.0, live=True
    )

    def mission_params(self) -> MissionParams:
        return MissionParams(
            follow_control=self.follow_control,
            stop_distance_m=self.stop_distance_m,
            follow_distance_m=self.follow_distance_m,
            distance_tolerance_m=self.distance_tolerance_m,
            max_linear=self.max_linear,
            max_angular=self.max_angular,
            kp_linear=self.kp_linear,
            kp_angular=self.kp_angular,
            search_yaw_rate=self.search_yaw_rate,
            search_timeout_s=self.search_timeout_s,
            search_on_loss=self.search_on_loss,
            lost_timeout_s=self.lost_timeout_s,
            camera_forward_m=self.camera_forward_m,
            decision_hold_s=self.decision_hold_s,
            decision_turn_rate=self.decision_turn_rate,
            max_turn_deg=self.max_turn_deg,
            avoid_obstacles=self.avoid_obstacles,
            scan_timeout_s=self.scan_timeout_s,
            detour_memory_s=self.detour_memory_s,
            planner=PlannerParams(margin=self.planner_margin_m, max_angular=self.max_angular),
        )


def sighting_of(
    msg: TrackedTarget, t: float, fovy_deg: float = spec.HEAD_CAMERA_FOVY_DEG
) -> tuple[Sighting, str | None]:
    """A TrackedTarget -> a Sighting (a bad one says `lost`), and what was wrong with it, if anything."""
    state = STATE_NAMES.get(int(msg.state))
    if state is None:
        return Sighting(t, msg.label, "lost"), f"unknown state {msg.state}"
    if state != "tracking":
        return Sighting(t, msg.label, state), None
    b, w, h = msg.bbox, int(msg.image_width), int(msg.image_height)
    vals = (b.center.position.x, b.center.position.y, b.size_x, b.size_y)
    if not all(math.isfinite(v) for v in vals) or b.size_x <= 0 or b.size_y <= 0:
        return Sighting(t, msg.label, "lost"), f"a tracking report with a bad box {vals}"
    if not (0 < w <= MAX_IMAGE_SIDE and 0 < h <= MAX_IMAGE_SIDE):
        return Sighting(t, msg.label, "lost"), f"a tracking report with a bad image size {w}x{h}"
    x, _, _ = normalized_target(_xyxy(msg), w, h)
    d = msg.distance_m
    distance = float(d) if math.isfinite(d) and 0.0 <= d < 1000.0 else None
    cam = PinholeCamera.from_fovy(w, h, fovy_deg)
    bearing = -math.atan2(b.center.position.x - cam.cx, cam.fx)
    return Sighting(t, msg.label, "tracking", x, distance, msg.range_method[:32], bearing), None


def _xyxy(msg: TrackedTarget) -> tuple[float, float, float, float]:
    b = msg.bbox
    cx, cy = b.center.position.x, b.center.position.y
    return cx - b.size_x / 2, cy - b.size_y / 2, cx + b.size_x / 2, cy + b.size_y / 2


class CommanderNode(Node):
    """The ``commander`` node; its contract (topics, goals, parameters) is the module docstring."""

    name = "commander"
    Config = CommanderConfig

    def __init__(self, config: CommanderConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        cfg: CommanderConfig = self.config
        self.mission = Mission(cfg.mission_params())
        self.pub_query = self.create_publisher(String, "/target/query", QOS_LATCHED)
        self.pub_target = self.create_publisher(PointStamped, "/detected_target", QOS_DEFAULT)
        self.pub_cmd = self.create_publisher(Twist, "/behavior/cmd_vel", QOS_DEFAULT)
        self.pub_go2 = self.create_publisher(String, "/go2/command", QOS_DEFAULT)
        self.pub_status = self.create_publisher(String, "/commander/status", QOS_LATCHED)
        self.create_subscription(String, "/goal", self.on_goal, QOS_DEFAULT)
        self.create_subscription(TrackedTarget, "/target/tracked", self.on_tracked, QOS_DEFAULT)
        self.create_subscription(String, "/vlm/decision", self.on_decision, QOS_DEFAULT)
        self.create_subscription(LaserScan, cfg.scan_topic, self.on_scan, QOS_SENSOR)
        self.create_subscription(Odometry, cfg.odom_topic, self.on_odom, QOS_DEFAULT)
        self._query: str | None = None
        self._tracked: TrackedTarget | None = None  # the newest report for the goal's object, not yet relayed
        self._last_key: tuple[str, str] | None = None
        self.create_timer(1.0 / cfg.control_rate_hz, self.tick)
        self.create_timer(cfg.status_period_s, self.publish_status)
        if cfg.goal.strip():
            self.set_goal(cfg.goal)
        else:
            self.tick()
        self.log.info(f"follow_control={cfg.follow_control}")

    # -- inputs ------------------------------------------------------------------------------

    def on_params_changed(self, old: CommanderConfig, changed: frozenset[str]) -> None:
        # The mission reads its gains, speeds and timeouts from params on every step.
        self.mission.params = self.config.mission_params()

    def on_goal(self, msg: String) -> None:
        self.set_goal(msg.data)

    def set_goal(self, text: str) -> None:
        self.mission.set_goal(text, self.clock.monotonic())
        m = self.mission
        if m.state == "rejected":
            self.log.throttled("warning", 1.0, f"goal rejected: {m.reason}", key="goal")
        elif m.goal is not None:
            self.log.info(f"goal: {m.goal.describe()} ({text!r}): {m.state}")
        self.tick()

    def on_tracked(self, msg: TrackedTarget) -> None:
        sighting, bad = sighting_of(msg, self.clock.monotonic(), self.config.camera_fovy_deg)
        if bad is not None:
            n = self.count("bad_tracked")
            self.log.throttled("error", 5.0, f"ignoring a bad /target/tracked ({n} so far): {bad}", key="tracked")
        was_active = self.mission.active
        self.mission.observe(sighting)
        if sighting.tracked and sighting.label == self.mission.label:
            self._tracked = msg
        if was_active and not self.mission.active:
            self.tick()  # rejected: stop now

    def on_scan(self, msg: LaserScan) -> None:
        now = self.clock.monotonic()
        try:
            pts = frame_scan_points(
                spec.BASE_FRAME, msg.header.frame_id, msg.ranges, msg.angle_min, msg.angle_increment,
                msg.range_min, msg.range_max,
            )  # fmt: skip
        except (ValueError, TypeError, OverflowError) as exc:
            n = self.count("bad_scan")
            self.log.throttled("error", 5.0, f"ignoring a bad {self.config.scan_topic} ({n} so far): {exc}", key="scan")
            self.mission.observe_scan(None, now)
            return
        self.mission.observe_scan(pts, now)

    def on_odom(self, msg: Odometry) -> None:
        pose = msg.pose.pose
        q = pose.orientation
        self.mission.observe_pose(
            pose.position.x, pose.position.y, quat_yaw(q.w, q.x, q.y, q.z), self.clock.monotonic()
        )

    def on_decision(self, msg: String) -> None:
        before = self.mission.counters["decisions_rejected"]
        self.mission.decide(msg.data, self.clock.monotonic())
        n = self.mission.counters["decisions_rejected"]
        if n > before:
            self.log.throttled(
                "warning", 5.0, f"ignored a VLM decision outside the schema ({n} so far): {self.mission.last_decision}"
            )
        self.tick()

    # -- control -------------------------------------------------------------------------------
    def tick(self) -> None:
        intent = self.mission.step(self.clock.monotonic())
        if intent.query != self._query:
            self._query = intent.query
            self.pub_query.publish(String(data=intent.query))
        for posture in intent.postures:
            self.pub_go2.publish(String(data=posture))
        if intent.publish_cmd:
            self.pub_cmd.publish(Twist(linear=Vector3(x=float(intent.vx)), angular=Vector3(z=float(intent.wz))))
        if intent.follow_target and self._tracked is not None:
            self._relay(self._tracked)
        self._tracked = None  # each report is relayed at most once
        if (intent.state, intent.reason) != self._last_key:
            self._last_state_log(intent)
            self.publish_status()

    def _last_state_log(self, intent: Intent) -> None:
        if self._last_key is not None and intent.state != self._last_key[0]:
            self.log.info(f"{self._last_key[0]} -> {intent.state}: {intent.reason}")

    def _relay(self, msg: TrackedTarget) -> None:
        x, y, z = normalized_target(_xyxy(msg), int(msg.image_width), int(msg.image_height))
        header = Header(stamp=msg.header.stamp, frame_id=msg.header.frame_id)
        self.pub_target.publish(PointStamped(header=header, point=Point(x=x, y=y, z=z)))

    # -- status --------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        m = self.mission
        goal = m.goal
        now = self.clock.monotonic()
        seen = m.confirmed(now)
        s = m.sighting
        dist = m.base_distance(now)
        return {
            "goal": goal.text if goal else "",
            "kind": goal.kind if goal else None,
            "target": m.label or None,
            "state": m.state,
            "reason": m.reason,
            "seen": seen,
            "x": round(s.x, 4) if seen and s is not None else None,
            "distance_m": None if dist is None else round(dist, 3),
            "range_method": s.range_method if seen and s is not None else None,
            "tracker": s.state if s is not None else None,
            "cmd": [round(m.cmd[0], 4), round(m.cmd[1], 4)],
            "planner": m.planner_note,
            "decision": m.last_decision,
            "counters": {**m.counters, **self.counters},
        }

    def publish_status(self) -> None:
        self._last_key = (self.mission.state, self.mission.reason)
        self.pub_status.publish(String(data=json.dumps(self.status(), ensure_ascii=False)))

    def close(self) -> None:
        # Leave the robot still: the gate also times the input out, this is just faster.
        try:
            self.pub_cmd.publish(Twist())
        except Exception:  # noqa: BLE001 - the writer may already be gone
            pass
