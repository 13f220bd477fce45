"""The commander's logic without any I/O: a language goal, the target_tracker's sightings and the VLM's
scene decisions in; a velocity intent, posture commands, the query for the tracker and a state with
its reason out. Driven by explicit timestamps so it can be tested exhaustively. It orchestrates:
the control laws it runs (approach, align, face, search) are behavior/control.py's, beside the
follower's, and its local planner is behavior/planner.py.

    mission = Mission(MissionParams())
    mission.set_goal("go to the blue cylinder", now)
    mission.observe(Sighting(now, "blue cylinder", "tracking", x=0.1, distance=2.0, range_method="bottom"))
    mission.decide('{"action": "stop"}', now)      # a raw VLM answer; parsed against the whitelist here
    intent = mission.step(now)                    # what goes on /behavior/cmd_vel, /go2/command, ...

Rules
- Goals (behavior/goals.py): follow | go to | look for <object>, stop, sit, stand, turn (|angle| <=
  30 deg: turns in place at the decisions' turn rate, then `done`). Text it cannot
  parse is `rejected`: zero velocity, the reply in `reason`, nothing moves. A goal that is already
  running, sent again, carries on.
- The query is the goal's object while a motion goal runs, else '': the target_tracker grounds and
  tracks exactly that.
- The target is *confirmed* while the newest sighting for the goal's object says `tracking` and is
  younger than `lost_timeout_s`. Only a confirmed target is approached or followed: no forward
  speed and no /detected_target otherwise. A sighting for another label is ignored; a sighting that
  says lost ends the confirmation at once. A tracker that cannot ground the object (`ungroundable`)
  rejects the goal.
- Not confirmed after having been: zero (`lost`) for `lost_timeout_s`, then go to / look for (and
  follow with follow_control=self) search if `search_on_loss`: turn in place at `search_yaw_rate`
  towards where it was last seen, until found or `search_timeout_s` -> `not_found`.
- Decisions (behavior/decisions.py, the whitelist: stop | continue | turn |angle| <= max_turn_deg |
  sit; anything else is counted and ignored) act only on a running motion goal: stop holds still for
  `decision_hold_s`, continue ends the hold, turn turns in place at `decision_turn_rate` for
  |angle| / rate seconds, sit sends "sit" and ends the goal. Text never becomes a velocity.
- Terminal states (idle, stopped, rejected, done, reached, found, not_found, sat) output zero: a
  burst of zeros for ZERO_BURST_S, then /behavior/cmd_vel goes quiet.
- Obstacles (`avoid_obstacles`, behavior/planner.py): go to and follow (self) steer round what the
  newest scan (`observe_scan`, base frame, fresh for `scan_timeout_s`) shows between the robot and
  the target (`detouring`). With the pose (`observe_pose`, odometry, fresh for `pose_timeout_s`) the
  target's last confirmed place is kept in the odometry frame; a detour that takes the target out of
  view carries on towards that place for up to `detour_memory_s` after the last confirmation, but only
  while the direct way is blocked: a free direct way with the target unseen turns in place towards
  where it was (no forward speed), and then the lost/search rules apply. No fresh scan: no planning,
  the straight approach (the safety gate's collision guard still stops it short of anything).
- The world (`observe_memory`: the object memory's remembered objects from /objects, and the stamp
  of the newest answer it has taken in, on this clock): go to and look for use the most confident
  remembered object of the goal's label (at least `memory_min_confidence`) while the tracker does not
  confirm the target, once a tracker report has said how wide the camera's view is (`hfov`). Go to
  turns to it, then approaches its remembered place with the local planner, but only once the memory
  confirms it (at least `memory_confirm_confidence`: two answers that agree on its place); less
  sure, it holds still facing it and looks. At its remembered place it stops and
  looks: `reached` only when an answer about a frame taken there (its stamp after the stop) placed the
  object within reach (stop_distance_m + distance_tolerance_m + `reach_slack_m`), or the tracker
  confirms it within reach. Look for turns to face it and ends `found` when an answer about a frame
  taken facing it saw it. `confirm_looks` answered looks without it: that object is given up (until
  it is seen again) and the search goes on. A goal for an object already remembered goes straight there.
- Search, with a memory whose answers are so slow that turning at `search_yaw_rate` would turn more
  than `search_view_per_answer` of the view between two answers (the latency is measured: the stamps
  of the answers against when the memory had them; the view is the tracker reports' `hfov`, and
  unknown counts as too slow): stop and look. Hold still until an answer about a
  frame taken at this heading has come back (a frame `look_settle_s` after the stop; at most 2.5 x the
  answer latency + 1 s, or `look_timeout_s` before any answer), then turn `search_step_deg` at
  `search_step_rate` and look again. A faster grounder (or no memory) turns continuously at
  `search_yaw_rate`, as before. With stop and look, `not_found` also needs one whole turn looked at.
- Speeds stay within 0 <= vx <= max_linear and |wz| <= max_angular (never backwards).
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from go2vlm.behavior.control import (
    ApproachParams,
    align_command,
    approach_command,
    face_command,
    search_command,
)
from go2vlm.behavior.decisions import DecisionRejected, parse_decision
from go2vlm.behavior.goals import TIMED_KINDS, Goal, GoalParseError, parse_goal
from go2vlm.behavior.planner import PlannerParams, Steer, steer
from go2vlm.robot_profile import go2 as spec
from go2vlm.world.labels import label_fits
from go2vlm.world.objects_msg import Remembered

__all__ = ["TERMINAL", "Intent", "Mission", "MissionParams", "Sighting"]

TERMINAL = ("idle", "stopped", "rejected", "done", "reached", "found", "not_found", "sat")
ZERO_BURST_S = 0.5  # zeros sent after a goal ends, then /behavior/cmd_vel goes quiet


@dataclass(frozen=True)
class MissionParams:
    follow_control: str = "follower"  # follower: /detected_target for the follower; self: own control
    stop_distance_m: float = 0.8  # go to: base -> surface
    follow_distance_m: float = 1.2  # follow_control=self
    distance_tolerance_m: float = 0.05
    max_linear: float = 0.4
    max_angular: float = 0.8
    kp_linear: float = 0.8
    kp_angular: float = 1.5
    search_yaw_rate: float = 0.5
    search_timeout_s: float = 30.0
    search_on_loss: bool = True
    lost_timeout_s: float = 1.0
    camera_forward_m: float = spec.HEAD_CAMERA_POS[0]  # camera ahead of the base centre
    decision_hold_s: float = 3.0
    decision_turn_rate: float = 0.5
    max_turn_deg: float = 30.0
    avoid_obstacles: bool = True
    scan_timeout_s: float = 0.5  # a scan older than this is no scan: no planning
    pose_timeout_s: float = 0.5  # an odometry pose older than this places nothing
    detour_memory_s: float = 8.0  # a detour out of the target's view lasts this long after the last sighting
    planner: PlannerParams = field(default_factory=PlannerParams)
    use_memory: bool = True  # go to / look for the object memory's remembered objects
    memory_min_confidence: float = 0.3  # worth turning to (one sighting: 0.5; then three empty looks: 0.32)
    memory_confirm_confidence: float = 0.7  # ... and this sure worth walking to (two that agree: 0.73)
    reach_slack_m: float = 0.25  # a remembered place within reach: stop distance + tolerance + this
    confirm_looks: int = 3  # answered looks without the object before it is given up
    search_step_deg: float = 50.0  # stop and look: the turn between two looks (the view is 73 deg wide)
    search_view_per_answer: float = 0.5  # turning on would turn more of the view than this per answer: stop and look
    search_step_rate: float = 0.5  # stop and look: rad/s of the turn between two looks
    look_settle_s: float = 0.3  # after a stop, frames this much later are taken at the new heading
    look_timeout_s: float = 8.0  # before the first answer, a look waits this long (then 2.5 x the latency + 1 s)

    def __post_init__(self) -> None:
        if self.follow_control not in ("follower", "self"):
            raise ValueError(f"follow_control {self.follow_control!r} is not follower or self")
        if not 0.0 <= self.max_turn_deg <= 30.0:
            raise ValueError(f"max_turn_deg {self.max_turn_deg} must be within 0..30")
        if not 0.0 < self.memory_min_confidence <= self.memory_confirm_confidence <= 1.0:
            raise ValueError("need 0 < memory_min_confidence <= memory_confirm_confidence <= 1")

    def approach(self, stop_distance: float) -> ApproachParams:
        return ApproachParams(
            stop_distance=stop_distance,
            tolerance=self.distance_tolerance_m,
            kp_linear=self.kp_linear,
            kp_angular=self.kp_angular,
            max_linear=self.max_linear,
            max_angular=self.max_angular,
        )


@dataclass(frozen=True)
class Sighting:
    """One target_tracker report (a TrackedTarget), as it arrived."""

    t: float  # arrival time on the node's clock
    label: str  # what the tracker tracks
    state: str  # idle | searching | tracking | lost | ungroundable
    x: float = math.nan  # box centre, -1..1 from the image centre (geometry/target.py); NaN without a box
    distance: float | None = None  # camera -> near surface (m)
    range_method: str = "none"
    bearing: float = math.nan  # rad from the camera's axis, + left (NaN: not known)
    hfov: float = math.nan  # the camera's horizontal field of view (rad) the tracker's bearings come from

    @property
    def tracked(self) -> bool:
        return self.state == "tracking" and math.isfinite(self.x) and abs(self.x) <= 2.0


@dataclass(frozen=True)
class Intent:
    """What the commander does now."""

    vx: float = 0.0
    wz: float = 0.0
    publish_cmd: bool = False  # send (vx, wz) on /behavior/cmd_vel
    follow_target: bool = False  # relay the confirmed target on /detected_target (follow, follower mode)
    postures: tuple[str, ...] = ()  # "sit" / "stand" for /go2/command, issued since the last step
    query: str = ""  # what the target_tracker should track
    state: str = "idle"
    reason: str = ""


@dataclass
class Mission:
    params: MissionParams = field(default_factory=MissionParams)

    def __post_init__(self) -> None:
        self.goal: Goal | None = None
        self.state = "idle"
        self.reason = "no goal yet"
        self.counters: Counter[str] = Counter()
        self.last_decision: dict[str, Any] | None = None
        self.sighting: Sighting | None = None  # the newest one for the goal's object
        self.cmd = (0.0, 0.0)
        self._postures: list[str] = []
        self._last_seen: float | None = None  # arrival of the last confirmed sighting
        self._last_x = 0.0
        self._t_search = 0.0
        self._zero_until = -math.inf
        self._hold_until = -math.inf
        self._turn_until = -math.inf
        self._turn_dir = 0.0
        self.planner_note = ""  # what the local planner did on the last step ("" = nothing)
        self._scan: tuple[np.ndarray, float] | None = None  # obstacle points (base frame), arrival
        self._pose: tuple[float, float, float, float] | None = None  # odometry x, y, yaw, arrival
        self._goal_xy: tuple[float, float] | None = None  # the target's last confirmed place (odometry)
        self._detour_t: float | None = None  # when the planner last had to steer round something
        self._side = 0.0  # the side it went round on (+1 left, -1 right)
        self._side_t = -math.inf
        self.memory: list[Remembered] | None = None  # None: no object memory heard of
        self.answered_through: float | None = None  # the newest answer's frame, on this clock
        self._latency: deque[float] = deque(maxlen=20)
        self._given_up: dict[str, float] = {}  # remembered object id -> its last_seen when given up
        self._look_key: object = None  # what the current look is for
        self._still_since = math.inf  # frames from this time on are taken at the current heading
        self._failed_looks = 0
        self._search_phase = "look"  # stop and look: look | turn
        self._turn_t0 = 0.0  # when this step's turn began
        self._turn_yaw: float | None = None  # the yaw the step started from
        self._turned = 0.0  # rad turned (in steps) since the search began
        self.basis = ""  # what the current motion is based on: tracker | memory | ""
        self.target_obj: Remembered | None = None
        self.view: float | None = None  # the camera's horizontal field of view (rad), from the tracker's reports

    # -- inputs ------------------------------------------------------------------------------
    def set_goal(self, text: str, now: float) -> None:
        try:
            goal = parse_goal(text)
        except GoalParseError as exc:
            self.counters["rejected_goals"] += 1
            self.goal = Goal("stop", None, str(text)[:200])
            self._enter("rejected", str(exc), now)
            return
        cur = self.goal
        if goal.moves and cur is not None and (cur.kind, cur.target) == (goal.kind, goal.target) and self.active:
            return  # the same goal again (a UI re-sending it): carry on, don't restart
        self.goal = goal
        self.sighting = None
        self._last_seen = None
        self._last_x = 0.0
        self._goal_xy, self._detour_t, self._side = None, None, 0.0
        self._hold_until = self._turn_until = -math.inf
        self._given_up.clear()
        self._look_key, self._failed_looks = None, 0
        self._search_phase, self._turned, self._turn_yaw = "look", 0.0, None
        if goal.kind == "stop":
            self._enter("stopped", "stop requested", now)
        elif goal.kind in ("sit", "stand"):
            self._postures.append(goal.kind)
            self._enter("done", f"sent {goal.kind!r} on /go2/command", now)
        elif goal.kind == "turn":  # the whitelisted turn of a VLM decision, asked for as a goal
            self._start_turn(goal.angle_deg, now)
            self._enter("turning", f"turning {goal.angle_deg:+g} deg in place", now)
        else:
            self._t_search = now
            label = self.label
            if goal.kind == "follow" and self.params.follow_control == "follower":
                self._enter("waiting", f"waiting for the {label} to come into view", now)
            else:
                self._enter("searching", f"looking for the {label}", now)

    def observe(self, s: Sighting) -> None:
        """A target_tracker report; reports about another label are ignored (but for the camera's view)."""
        if math.isfinite(s.hfov) and 0.0 < s.hfov < math.pi:
            self.view = s.hfov
        if not self.active or s.label != self.label:
            self.counters["sightings_ignored"] += 1
            return
        self.sighting = s
        if s.state == "ungroundable":
            self._enter(
                "rejected",
                f"the target_tracker cannot ground {s.label!r}: its colour-shape grounder knows "
                "red/green/blue/yellow ball/box/cylinder; run the vlm node (mode=detect) and the "
                "target_tracker with grounding=vlm for other objects",
                s.t,
            )
        elif s.tracked:
            self._last_seen = s.t
            self._last_x = s.x
            self._remember(s)

    def observe_scan(self, points: np.ndarray | None, now: float) -> None:
        """Obstacle points ((N, 2), base frame, x forward) from a scan; None: the scan was garbage."""
        if points is None:
            self._scan = None
            return
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        self._scan = (pts[np.isfinite(pts).all(axis=1)], now)

    def observe_pose(self, x: float, y: float, yaw: float, now: float) -> None:
        """The robot's odometry pose (a NaN one is dropped)."""
        self._pose = (x, y, yaw, now) if all(math.isfinite(v) for v in (x, y, yaw)) else None

    def observe_memory(self, objects: list[Remembered], answered_through: float | None, now: float) -> None:
        """The object memory's newest /objects: every remembered object, and the stamp of the newest
        answer it has taken in, both on this clock (None: no answer yet)."""
        self.memory = list(objects)
        if answered_through is not None and (self.answered_through is None or answered_through > self.answered_through):
            self.answered_through = answered_through
            self._latency.append(max(0.0, now - answered_through))

    @property
    def answer_latency(self) -> float | None:
        """The measured answer latency (s): the 80th percentile of the last answers, None before any."""
        if not self._latency:
            return None
        lat = sorted(self._latency)
        return lat[min(len(lat) - 1, int(0.8 * len(lat)))]

    def _remember(self, s: Sighting) -> None:
        """Keep where a confirmed, ranged sighting puts the target, in the odometry frame."""
        pose = self._fresh(self._pose, s.t, self.params.pose_timeout_s)
        rel = self._seen_in_base(s)
        if pose is None or rel is None:
            return
        x, y, yaw = pose[:3]
        bx, by = rel
        c, sn = math.cos(yaw), math.sin(yaw)
        self._goal_xy = (x + c * bx - sn * by, y + sn * bx + c * by)

    def decide(self, text: str, now: float) -> None:
        """A raw VLM scene decision: applied if it is inside the whitelist, else counted and ignored."""
        try:
            d = parse_decision(text, self.params.max_turn_deg)
        except DecisionRejected as rej:
            self.counters["decisions_rejected"] += 1
            self.counters[f"decisions_rejected.{rej.reason}"] += 1
            self.last_decision = {"accepted": False, "reason": rej.reason, "answer": str(text)[:120]}
            return
        self.counters["decisions_accepted"] += 1
        self.last_decision = {"accepted": True, **d.to_dict()}
        if not self.active:
            return
        p = self.params
        if d.action == "stop":
            self._hold_until = now + p.decision_hold_s
        elif d.action == "continue":
            self._hold_until = -math.inf
        elif d.action == "turn":
            self._start_turn(d.angle_deg, now)
        elif d.action == "sit":
            self._postures.append("sit")
            self._enter("sat", "a VLM decision said sit: sent 'sit' on /go2/command", now)

    def _start_turn(self, angle_deg: float, now: float) -> None:
        rate = self._turn_rate
        self._turn_dir = math.copysign(1.0, angle_deg) if angle_deg else 0.0
        self._turn_until = now + (math.radians(abs(angle_deg)) / rate if rate > 0 else 0.0)

    # -- state ---------------------------------------------------------------------------------
    @property
    def active(self) -> bool:
        return self.goal is not None and self.goal.kind in TIMED_KINDS and self.state not in TERMINAL

    @property
    def label(self) -> str:
        return self.goal.target.label if self.goal is not None and self.goal.target is not None else ""

    @property
    def _turn_rate(self) -> float:
        return min(self.params.decision_turn_rate, self.params.max_angular)

    def confirmed(self, now: float) -> bool:
        """The newest sighting of the goal's object says tracking, and is fresh."""
        s = self.sighting
        return s is not None and s.tracked and 0.0 <= now - s.t < self.params.lost_timeout_s

    def base_distance(self, now: float) -> float | None:
        """Base centre -> the object's surface, while confirmed and ranged."""
        s = self.sighting
        if not self.confirmed(now) or s is None or s.distance is None or not math.isfinite(s.distance):
            return None
        return s.distance + self.params.camera_forward_m

    @staticmethod
    def _fresh(item: tuple[Any, ...] | None, now: float, timeout: float) -> tuple[Any, ...] | None:
        return item if item is not None and 0.0 <= now - item[-1] <= timeout else None

    def _seen_in_base(self, s: Sighting) -> tuple[float, float] | None:
        """The sighted surface point in the base frame (x forward, y left), if ranged and with a bearing."""
        d, b = s.distance, s.bearing
        if d is None or not (math.isfinite(d) and math.isfinite(b)):
            return None
        return self.params.camera_forward_m + d * math.cos(b), d * math.sin(b)

    def _remembered_in_base(self, now: float) -> tuple[float, float] | None:
        """The target's last confirmed place as (bearing, distance) from the base now, if the pose is fresh."""
        pose = self._fresh(self._pose, now, self.params.pose_timeout_s)
        if pose is None or self._goal_xy is None:
            return None
        x, y, yaw = pose[:3]
        dx, dy = self._goal_xy[0] - x, self._goal_xy[1] - y
        c, sn = math.cos(yaw), math.sin(yaw)
        return math.atan2(-sn * dx + c * dy, c * dx + sn * dy), math.hypot(dx, dy)

    def _approach_params(self, goal: Goal) -> ApproachParams:
        p = self.params
        return p.approach(p.follow_distance_m if goal.kind == "follow" else p.stop_distance_m)

    def _avoid(self, vx: float, wz: float, ap: ApproachParams, goal: tuple[float, float], now: float) -> Steer | None:
        """The planner's way round the fresh scan towards `goal` (bearing, base distance), or None (no
        planning: off, or no fresh scan)."""
        scan = self._fresh(self._scan, now, self.params.scan_timeout_s)
        if not self.params.avoid_obstacles or scan is None:
            return None
        bearing, dist = goal
        speed, _, _ = approach_command(0.0, dist, ap)
        side = self._side if now - self._side_t < 3.0 else 0.0
        st = steer(
            vx, wz, speed, bearing, dist, scan[0], self.params.planner, max_angular=ap.max_angular,
            reach_m=dist - ap.stop_distance, side=side,
        )  # fmt: skip
        if st.blocked:
            self._detour_t = now
            if st.vx > 0.0 and abs(st.heading - bearing) > 1e-6:
                self._side, self._side_t = math.copysign(1.0, st.heading - bearing), now
        return st

    def _enter(self, state: str, reason: str, now: float) -> None:
        self.state, self.reason = state, reason
        if state in TERMINAL:
            self._zero_until = now + ZERO_BURST_S

    def _set(self, state: str, reason: str, now: float) -> None:
        if state != self.state or reason != self.reason:
            self._enter(state, reason, now)

    # -- output --------------------------------------------------------------------------------
    def step(self, now: float) -> Intent:
        postures, self._postures = tuple(self._postures), []
        self.planner_note = ""
        vx, wz, publish, follow = self._control(now)
        vx = min(max(vx, 0.0), self.params.max_linear) if math.isfinite(vx) else 0.0
        wz = max(-self.params.max_angular, min(self.params.max_angular, wz)) if math.isfinite(wz) else 0.0
        if publish:
            self.cmd = (vx, wz)
        return Intent(vx, wz, publish, follow, postures, self.label if self.active else "", self.state, self.reason)

    def _control(self, now: float) -> tuple[float, float, bool, bool]:
        """(vx, wz, publish on /behavior/cmd_vel, relay /detected_target)."""
        goal = self.goal
        if goal is None or not self.active:
            return 0.0, 0.0, now < self._zero_until, False
        p = self.params
        if now < self._hold_until:
            self._set("holding", "a VLM decision said stop", now)
            return 0.0, 0.0, True, False
        if goal.kind == "turn":
            if now < self._turn_until:
                self._set("turning", f"turning {goal.angle_deg:+g} deg in place", now)
                return 0.0, self._turn_dir * self._turn_rate, True, False
            self._enter("done", f"turned {goal.angle_deg:+g} deg", now)
            return 0.0, 0.0, True, False
        if now < self._turn_until:
            self._set("turning", "a VLM decision said turn", now)
            return 0.0, self._turn_dir * self._turn_rate, True, False
        seen = self.confirmed(now)
        self.basis = "tracker" if seen else ""
        self.target_obj = self._remembered_target()
        if seen:
            self._t_search = now
            self._look_key = None
        if goal.kind == "follow" and p.follow_control == "follower":
            if seen:
                self._set("tracking", "target in view: /detected_target for the follower", now)
                return 0.0, 0.0, False, True
            if self._last_seen is not None:
                self._set("lost", "target not in view: the follower stops on its own timeout", now)
            else:
                self._set("waiting", "target not in view yet", now)
            return 0.0, 0.0, False, False
        if seen:
            assert self.sighting is not None
            x = self.sighting.x
            if goal.kind == "look_for":
                wz, centred = align_command(x, self._approach_params(goal))
                if centred:
                    self._enter("found", f"the {self.label} is straight ahead{self._where()}", now)
                    return 0.0, 0.0, True, False
                self._set("aligning", "target in view: turning to face it", now)
                return 0.0, wz, True, False
            follow = goal.kind == "follow"
            dist = self.base_distance(now)
            ap = self._approach_params(goal)
            vx, wz, reached = approach_command(x, dist, ap)
            how = "unknown" if dist is None else f"{dist:.2f} m ({self.sighting.range_method})"
            if reached and not follow:
                self._enter("reached", f"{dist:.2f} m from the {self.label} ({self.sighting.range_method})", now)
                return 0.0, 0.0, True, False
            rel = self._seen_in_base(self.sighting)
            if rel is not None and not reached:
                st = self._avoid(vx, wz, ap, (math.atan2(rel[1], rel[0]), math.hypot(*rel)), now)
                if st is not None and st.blocked:
                    self.planner_note = st.note
                    self._set("detouring", f"target at {how}: {st.note}", now)
                    return st.vx, st.wz, True, False
            if follow:
                self._set("tracking", "target in view: following", now)
            else:
                self._set("approaching", f"target at {how}", now)
            return vx, wz, True, False
        detour = self._detour_unseen(now)
        if detour is not None:
            return detour
        remembered = self._memory_control(now)
        if remembered is not None:
            self._t_search = now
            self._search_phase = "look"  # a search after this starts with a look where it then faces
            return remembered
        if self._last_seen is not None and (now - self._last_seen < 2 * p.lost_timeout_s or not p.search_on_loss):
            self._set("lost", "target not in view: stopped", now)
            return 0.0, 0.0, True, False
        return self._search(now)

    # -- the world: the object memory ------------------------------------------------------------
    def _remembered_target(self) -> Remembered | None:
        """The most confident remembered object of the goal's label worth going to (not given up)."""
        p = self.params
        if not p.use_memory or not self.memory or not self.label:
            return None
        best: tuple[int, float] | None = None
        pick = None
        for o in self.memory:
            fit = label_fits(self.label, o.label)
            if fit == 0 or o.confidence < p.memory_min_confidence:
                continue
            if o.id in self._given_up and o.last_seen <= self._given_up[o.id]:
                continue
            key = (fit, o.confidence)
            if best is None or key > best:
                best, pick = key, o
        return pick

    def relative(self, o: Remembered, now: float) -> tuple[float, float] | None:
        """(bearing from the base, base centre -> the object's surface) of a remembered object, with a
        fresh pose; None without one. Where the fresh scan has returns on it (within its bearings, no
        nearer than its remembered near side less 0.4 m), the nearest one is its surface: the lidar
        knows a box's face better than the memory knows its size."""
        pose = self._fresh(self._pose, now, self.params.pose_timeout_s)
        if pose is None:
            return None
        x, y, yaw = pose[:3]
        dx, dy = o.x - x, o.y - y
        bearing = math.atan2(math.sin(math.atan2(dy, dx) - yaw), math.cos(math.atan2(dy, dx) - yaw))
        centre = math.hypot(dx, dy)
        surface = centre - o.radius
        scan = self._fresh(self._scan, now, self.params.scan_timeout_s)
        if scan is not None and len(scan[0]) and centre > o.radius:
            pts = scan[0]
            off = np.abs(np.angle(np.exp(1j * (np.arctan2(pts[:, 1], pts[:, 0]) - bearing))))
            d = np.hypot(pts[:, 0], pts[:, 1])
            on = (off <= math.asin(min(1.0, o.radius / centre))) & (d <= centre) & (d >= surface - 0.4)
            if on.any():
                surface = float(d[on].min())
        return bearing, surface

    def _look(self, key: object, now: float) -> str:
        """Hold still and look: 'waiting' until an answer about a frame taken after the stop has come
        back ('answered'), or 'timeout'. A new `key` (what is looked at) starts a new look."""
        p = self.params
        if key != self._look_key:
            self._look_key = key
            self._still_since = now + p.look_settle_s
        if self.answered_through is not None and self.answered_through >= self._still_since:
            return "answered"
        lat = self.answer_latency
        limit = p.look_timeout_s if lat is None else 2.5 * lat + 1.0
        return "timeout" if now - self._still_since > limit else "waiting"

    def _where(self) -> str:
        """Where the goal's object is in the world, as a reason's tail: the memory's place for it, else
        where the last ranged sighting put it ('' when neither is known)."""
        o = self.target_obj
        if o is not None:
            return f", at ({o.x:.2f}, {o.y:.2f}) in the odometry frame (memory, {o.confidence:.2f})"
        if self._goal_xy is not None:
            return f", at ({self._goal_xy[0]:.2f}, {self._goal_xy[1]:.2f}) in the odometry frame (its near side)"
        return ""

    def _give_up(self, o: Remembered, now: float, why: str) -> None:
        self._given_up[o.id] = o.last_seen
        self.counters["remembered_given_up"] += 1
        self._look_key, self._failed_looks = None, 0
        self._set("searching", f"the remembered {o.label} ({o.id}) was not there: {why}", now)

    def _looked_without(self, o: Remembered, now: float) -> bool:
        """After an answered look that did not see `o`: count it; True when `o` is given up."""
        self._failed_looks += 1
        self._look_key = None  # look again: a new look waits for a newer frame
        if self._failed_looks >= self.params.confirm_looks:
            self._give_up(o, now, f"{self._failed_looks} looks without it")
            return True
        return False

    def _memory_control(self, now: float) -> tuple[float, float, bool, bool] | None:
        """Go to / look for on a remembered object while the tracker does not confirm it (the module
        docstring's rules); None: no remembered target (search)."""
        p, goal, o, view = self.params, self.goal, self.target_obj, self.view
        if goal is None or goal.kind not in ("go_to", "look_for") or o is None or view is None:
            return None
        rel = self.relative(o, now)
        if rel is None:
            return None
        bearing, surface = rel
        where = f"the remembered {o.label} at ({o.x:.2f}, {o.y:.2f})"
        ap = self._approach_params(goal)
        x = -bearing / (view / 2.0)
        vx, wz, at_place = approach_command(x, surface, ap)
        key = (o.id, "look")
        if self._look_key == key:  # looking at it: has an answer about a frame taken since the stop seen it?
            seen_here = o.last_seen >= self._still_since
            if goal.kind == "look_for" and seen_here:
                self._enter("found", f"the {self.label} is straight ahead, {where} ({surface:.2f} m)", now)
                return 0.0, 0.0, True, False
            if goal.kind == "go_to" and seen_here and surface - ap.stop_distance <= ap.tolerance + p.reach_slack_m:
                self._enter("reached", f"{surface:.2f} m from the {self.label}: an answer about this view "
                            f"placed it here ({where})", now)  # fmt: skip
                return 0.0, 0.0, True, False
        if goal.kind == "go_to" and o.confidence >= p.memory_confirm_confidence and not at_place:
            # Walk: the approach turns before it walks, the planner steers round what is in the way.
            self._look_key, self._failed_looks = None, 0
            self.basis = "memory"
            st = self._avoid(vx, wz, ap, (bearing, surface), now)
            if st is not None and st.blocked:
                self.planner_note = st.note
                self._set("detouring", f"{where}, {surface:.2f} m (memory): {st.note}", now)
                return st.vx, st.wz, True, False
            self._set("approaching", f"{where}, {surface:.2f} m away (memory, confidence {o.confidence:.2f})", now)
            return vx, wz, True, False
        facing = p.planner.step if goal.kind == "look_for" else 0.25
        if abs(bearing) > facing:  # turn to it (looks are only taken facing it)
            self._look_key = None
            wz = face_command(bearing, ap)
            self._set("aligning" if goal.kind == "look_for" else "approaching", f"turning to {where}", now)
            return 0.0, wz, True, False
        # Hold still facing it (not sure enough to walk, or at its place) and look.
        look = self._look(key, now)
        if look == "answered":  # an answer about this view came back without it
            if self._looked_without(o, now):
                return None
        elif look == "timeout":
            self._look_key = None  # no answer at all: look again (the search's timeout still runs)
        why = "confirming it is there" if at_place or goal.kind == "look_for" else "looking again before walking"
        state = "aligning" if goal.kind == "look_for" else "approaching"
        self._set(state, f"holding still facing {where} ({surface:.2f} m): {why}", now)
        return 0.0, 0.0, True, False

    def _detour_unseen(self, now: float) -> tuple[float, float, bool, bool] | None:
        """Out of view during a detour (go to, follow self): on round the obstacle towards where the
        target was, while the direct way stays blocked; a free way turns back towards it. None: the
        detour is over (no detour, memory too old, no pose or no scan)."""
        p, goal = self.params, self.goal
        last = self._last_seen
        if goal is None or goal.kind == "look_for" or (goal.kind == "follow" and p.follow_control == "follower"):
            return None
        if last is None or self._detour_t is None or self._detour_t < last - p.lost_timeout_s:
            return None
        if now - last > p.detour_memory_s:
            return None
        rel = self._remembered_in_base(now)
        if rel is None:
            return None
        bearing, dist = rel
        ap = self._approach_params(goal)
        turn = max(-p.max_angular, min(p.max_angular, p.planner.kp * bearing))
        st = self._avoid(0.0, turn, ap, rel, now)
        if st is None:
            return None
        if st.blocked:
            self.planner_note = st.note
            self._set("detouring", f"the {self.label} is out of view: {st.note}", now)
            return st.vx, st.wz, True, False
        if abs(bearing) < p.planner.step:
            return None  # facing where it was, and still not seen: lost, then search
        self.planner_note = "turning back towards the target"
        self._set("detouring", f"turning back towards where the {self.label} was last seen ({dist:.1f} m)", now)
        return 0.0, turn, True, False

    def _search(self, now: float) -> tuple[float, float, bool, bool]:
        p = self.params
        lat = self.answer_latency
        view = self.view
        fast = lat is not None and view is not None and lat * p.search_yaw_rate <= p.search_view_per_answer * view
        stop_and_look = self.memory is not None and p.use_memory and not fast
        full_turn = self._turned >= 2 * math.pi - 1e-6
        if now - self._t_search > p.search_timeout_s and (not stop_and_look or full_turn):
            self._enter("not_found", f"no {self.label} in view after {p.search_timeout_s:g} s", now)
            return 0.0, 0.0, True, False
        if not stop_and_look:
            self._set("searching", f"turning in place to find the {self.label}", now)
            return 0.0, search_command(self._last_x, p.search_yaw_rate, p.max_angular), True, False
        if self._search_phase == "look":
            look = self._look(("search", self._turned), now)
            if look == "waiting":
                how = "answer latency unknown" if lat is None else f"answers take {lat:.1f} s"
                self._set("searching", f"holding still, looking for the {self.label} ({how})", now)
                return 0.0, 0.0, True, False
            self._search_phase, self._turn_t0, self._turn_yaw = "turn", now, None
        wz = search_command(self._last_x, p.search_step_rate, p.max_angular)
        pose = self._fresh(self._pose, now, p.pose_timeout_s)
        if pose is not None:  # how far this step has turned, by odometry
            if self._turn_yaw is None:
                self._turn_yaw = pose[2]
            done = abs(math.atan2(math.sin(pose[2] - self._turn_yaw), math.cos(pose[2] - self._turn_yaw)))
        else:  # no odometry: by time
            self._turn_yaw = None
            done = abs(wz) * (now - self._turn_t0)
        if done >= math.radians(p.search_step_deg) - 0.02:
            self._turned += math.radians(p.search_step_deg)
            self._search_phase = "look"
            self._look(("search", self._turned), now)
            self._set("searching", f"holding still, looking for the {self.label}", now)
            return 0.0, 0.0, True, False
        self._set("searching", f"turning {p.search_step_deg:g} deg to look for the {self.label}", now)
        return 0.0, wz, True, False
