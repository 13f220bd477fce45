"""The commander's logic without any I/O: a language goal, the target_tracker's sightings and the VLM's
scene decisions in; a velocity intent, posture commands, the query for the tracker and a state with
its reason out. Driven by explicit timestamps so it can be tested exhaustively.

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
- Speeds stay within 0 <= vx <= max_linear and |wz| <= max_angular (never backwards).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from go2vlm.behavior.approach import ApproachParams, approach_command
from go2vlm.behavior.decisions import DecisionRejected, parse_decision
from go2vlm.behavior.goals import TIMED_KINDS, Goal, GoalParseError, parse_goal
from go2vlm.behavior.planner import PlannerParams, Steer, steer
from go2vlm.robot_profile import go2 as spec

__all__ = ["TERMINAL", "Intent", "Mission", "MissionParams", "Sighting"]

TERMINAL = ("idle", "stopped", "rejected", "done", "reached", "found", "not_found", "sat")
ZERO_BURST_S = 0.5  # zeros sent after a goal ends, then /behavior/cmd_vel goes quiet
CENTRED_X = 0.1  # look for: |x| below this counts as found
MIN_ALIGN_WZ = 0.15  # look for: at least this gentle a turn, so a slow search does not stall near the centre


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

    def __post_init__(self) -> None:
        if self.follow_control not in ("follower", "self"):
            raise ValueError(f"follow_control {self.follow_control!r} is not follower or self")
        if not 0.0 <= self.max_turn_deg <= 30.0:
            raise ValueError(f"max_turn_deg {self.max_turn_deg} must be within 0..30")

    def approach(self, stop_distance: float) -> ApproachParams:
        return ApproachParams(
            stop_distance=stop_distance,
            tolerance=self.distance_tolerance_m,
            kp_linear=self.kp_linear,
            kp_angular=self.kp_angular,
            max_linear=self.max_linear,
            min_linear=min(0.08, self.max_linear),
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
        """A target_tracker report; reports about another label are ignored."""
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
    def _fresh(item: tuple | None, now: float, timeout: float) -> tuple | None:
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
            vx, wz, speed, bearing, dist, scan[0], self.params.planner, reach_m=dist - ap.stop_distance, side=side
        )
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
        if seen:
            self._t_search = now
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
                if abs(x) < CENTRED_X:
                    self._enter("found", f"the {self.label} is straight ahead", now)
                    return 0.0, 0.0, True, False
                wz = max(-p.max_angular, min(p.max_angular, -p.kp_angular * x))
                wz = math.copysign(min(p.max_angular, max(abs(wz), MIN_ALIGN_WZ)), wz)
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
        if self._last_seen is not None and (now - self._last_seen < 2 * p.lost_timeout_s or not p.search_on_loss):
            self._set("lost", "target not in view: stopped", now)
            return 0.0, 0.0, True, False
        return self._search(now)

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
        if now - self._t_search > p.search_timeout_s:
            self._enter("not_found", f"no {self.label} in view after {p.search_timeout_s:g} s", now)
            return 0.0, 0.0, True, False
        direction = -1.0 if self._last_x > 0 else 1.0  # towards where it was last seen; left by default
        self._set("searching", f"turning in place to find the {self.label}", now)
        return 0.0, direction * min(p.search_yaw_rate, p.max_angular), True, False
