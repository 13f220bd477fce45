"""What every strategy shares: what a strategy asks for
(`Command`), the context the mission keeps for them (`Context`: the goal, the newest observations and
the target's track), and the two protocols, `Strategy` and `SearchStrategy`. Pure: no I/O; every
method takes the time it is about."""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from go2vlm.behavior.control import ApproachParams
from go2vlm.behavior.goals import Goal
from go2vlm.behavior.navigate import Navigator, NavStep
from go2vlm.behavior.planner import Steer
from go2vlm.behavior.planner.global_path import Costmap, GlobalParams
from go2vlm.behavior.planner.route import Route
from go2vlm.behavior.sighting import Sighting
from go2vlm.behavior.strategies.latency import Answers
from go2vlm.behavior.strategies.look import Look
from go2vlm.behavior.strategies.params import MissionParams
from go2vlm.world.coverage import Coverage
from go2vlm.world.objects_msg import Remembered
from go2vlm.world.poses import Pose2D, PoseHistory, PoseUnavailable
from go2vlm.world.ranging import TargetRanging, remembered_on

__all__ = ["Command", "Context", "Pose", "SearchStrategy", "Sighting", "Strategy"]

POSES_KEPT_S = 60.0  # the mission's recent poses, to find where an answered frame was taken
VIEW_POSE_S = 0.5  # an answered frame newer than the newest pose by more than this looks at nothing


@dataclass(frozen=True)
class Command:
    """A strategy's answer for this step: a velocity (the mission clamps it to its limits), and the
    mission state with its reason. A terminal `state` (mission.TERMINAL: found, reached, done, ...)
    ends the goal."""

    vx: float
    wz: float
    state: str
    reason: str
    note: str = ""  # what the local planner did ("" = nothing)
    basis: str = ""  # what the motion is based on when not the tracker's confirmation: "memory"
    navigated: bool = False  # the navigator's (behavior/navigate/): its own checks, and it may back up

    @classmethod
    def still(cls, state: str, reason: str) -> Command:
        return cls(0.0, 0.0, state, reason)


@dataclass(frozen=True)
class Pose:
    """The robot's odometry pose and when it arrived."""

    x: float
    y: float
    yaw: float
    t: float


@dataclass
class Context:
    """What the mission knows, kept for the strategies: its parameters and goal, the newest
    observations (a sighting, the odometry pose, the scan, the object memory, the answers' latency,
    the camera's view) and the target's track (when and where it was last confirmed). The mission
    writes the observations; strategies read them and use the shared tools (`look`, `navigator`)."""

    params: MissionParams
    counters: Counter[str] = field(default_factory=Counter)
    goal: Goal | None = None
    sighting: Sighting | None = None  # the newest one for the goal's object
    pose: Pose | None = None
    scan: tuple[np.ndarray, float] | None = None  # obstacle points (base frame), arrival
    memory: list[Remembered] | None = None  # None: no object memory heard of
    answers: Answers = field(default_factory=Answers)
    view: float | None = None  # the camera's horizontal field of view (rad), from the tracker's reports
    target_obj: Remembered | None = None  # the remembered object the goal goes to / looks at this step
    last_seen: float | None = None  # arrival of the last confirmed sighting
    seen_since: float | None = None  # since when confirmed without a gap longer than lost_timeout_s
    last_x: float = 0.0  # its offset x (a search turns that way)
    goal_xy: tuple[float, float] | None = None  # the target's last confirmed place (odometry frame)
    look: Look = field(default_factory=Look)
    costmap: Costmap | None = None  # the map's newest inflated costmap (/map/costmap), for the global planner
    route: Route | None = None  # the global route being walked (explore, or a remembered place out of sight): /plan
    coverage: Coverage = field(default_factory=Coverage)  # where the camera has looked during this goal
    navigator: Navigator = field(default_factory=Navigator)  # the one way to a place (behavior/navigate/)
    poses: PoseHistory = field(  # the odometry poses, on the mission's clock: where an answered frame was taken
        default_factory=lambda: PoseHistory(horizon_s=POSES_KEPT_S, max_extrapolation_s=VIEW_POSE_S)
    )
    viewed_through: float = -math.inf  # the newest answered frame already in `coverage`
    ranging: TargetRanging = field(default_factory=TargetRanging)  # the target's range (world/ranging.py)
    align_since: float | None = None  # when a look for's turn to centre a confirmed target began

    # -- the goal ------------------------------------------------------------------------------
    @property
    def label(self) -> str:
        return self.goal.target.label if self.goal is not None and self.goal.target is not None else ""

    def new_goal(self, goal: Goal) -> None:
        """A new goal: forget the target's track (the observations of the world stay)."""
        self.goal = goal
        self.sighting = None
        self.last_seen = self.seen_since = None
        self.last_x = 0.0
        self.goal_xy = None
        self.align_since = None
        self.route = None
        self.navigator.reset()
        self.navigator.steering.reset()
        self.look.forget()
        self.coverage.reset()
        self.viewed_through = self.answers.through if self.answers.through is not None else -math.inf
        self.ranging.forget()

    def observe_view(self) -> None:
        """The newest answered frame has looked at the world (world/coverage.py), from the pose the
        robot had at its stamp: a frame counts once an answer about it came back, so a slow model's
        unanswered frames look at nothing. Needs the camera's view and a costmap (walls stop it)."""
        through, cm = self.answers.through, self.costmap
        if through is None or through <= self.viewed_through or cm is None or self.view is None:
            return
        self.viewed_through = through
        try:
            at = self.poses.at(through)
        except PoseUnavailable:
            return
        self.coverage.observe(cm.data, cm.resolution, cm.origin, at.x, at.y, at.yaw, self.view)

    def approach_params(self) -> ApproachParams:
        p = self.params
        follow = self.goal is not None and self.goal.kind == "follow"
        return p.approach(p.follow_distance_m if follow else p.stop_distance_m)

    @property
    def place_planner(self) -> GlobalParams:
        """The global planner's settings for a walk to a place (not a frontier): unknown space at
        the navigator's `unknown_cost`, and there only where it is in sight (the obstacle within
        `place_error_m` of the place being the object's own)."""
        nav = self.params.nav
        return replace(GlobalParams(), unknown_cost=nav.unknown_cost, goal_in_sight=True, goal_own_m=nav.place_error_m)

    def _navigator(self) -> Navigator:
        """The navigator with the mission's newest parameters and clearance rule (both live)."""
        nav, p = self.navigator, self.params
        nav.params, nav.clearance = p.nav, p.planner.clearance
        return nav

    def navigate(
        self, goal: tuple[float, float], tolerance: float, now: float, planner: GlobalParams, body: float = 0.0
    ) -> NavStep:
        """The navigator's step towards `goal` (odometry frame; `tolerance` m and in sight counts as there,
        the obstacle cells within `body` m being the goal's own), planning with `planner` on the newest
        costmap, at up to `nav.max_speed` and the mission's turn rate; `route` is its route."""
        nav, p = self._navigator(), self.params
        nav.planner = planner
        pose = self.fresh_pose(now)
        out = nav.step(goal, tolerance, self.costmap, None if pose is None else (pose.x, pose.y, pose.yaw),
                       self.fresh_scan(now), now, max_linear=p.nav.max_speed, max_angular=p.max_angular,
                       body=body)  # fmt: skip
        self.route = nav.route
        return out

    # -- observations --------------------------------------------------------------------------
    def fresh_pose(self, now: float) -> Pose | None:
        pose = self.pose
        return pose if pose is not None and 0.0 <= now - pose.t <= self.params.pose_timeout_s else None

    def fresh_scan(self, now: float) -> np.ndarray | None:
        scan = self.scan
        return scan[0] if scan is not None and 0.0 <= now - scan[1] <= self.params.scan_timeout_s else None

    def confirmed(self, now: float) -> bool:
        """The newest sighting of the goal's object says tracking, and is fresh."""
        s = self.sighting
        return s is not None and s.tracked and 0.0 <= now - s.t < self.params.lost_timeout_s

    @property
    def ranged_by(self) -> str:
        """What base_distance took last: the tracker's method, lidar or memory."""
        return self.ranging.ranged_by

    @property
    def overruled(self) -> tuple[float, float] | None:
        """When the memory last overruled the range, and its range."""
        return self.ranging.overruled

    @overruled.setter
    def overruled(self, value: tuple[float, float] | None) -> None:
        self.ranging.overruled = value

    def base_distance(self, now: float) -> float | None:
        """Base centre -> the object's surface, while confirmed and ranged: the tracker's range fused
        with the fresh scan and the object memory (world/ranging.py)."""
        s, p = self.sighting, self.params
        if not self.confirmed(now) or s is None:
            return None
        pose, mem = self.fresh_pose(now), None
        if pose is not None and self.memory and self.label and p.use_memory:
            at = Pose2D(pose.x, pose.y, pose.yaw)
            mem = remembered_on(p.ranging, s, now, at, self.memory, self.label, p.memory_confirm_confidence)
        return self.ranging.base_distance(p.ranging, s, now, self.fresh_scan(now), p.camera_forward_m, mem)

    def capped_distance(self, now: float, cap: float) -> float | None:
        """`base_distance` as the go-to `cap` (m) judges it: a range by the object's size beyond the cap
        counts only once such ranges have held (None until then)."""
        d, s = self.base_distance(now), self.sighting
        return self.ranging.capped(self.params.ranging, d, s.range_method if s is not None else "", cap, now)

    def seen_in_base(self, s: Sighting) -> tuple[float, float] | None:
        """The sighted surface point in the base frame (x forward, y left), if ranged and with a bearing."""
        d, b = s.distance, s.bearing
        if d is None or not (math.isfinite(d) and math.isfinite(b)):
            return None
        return self.params.camera_forward_m + d * math.cos(b), d * math.sin(b)

    def saw(self, s: Sighting) -> None:
        """A confirmed sighting: keep when and where (in the odometry frame, if ranged) it was."""
        if self.last_seen is None or self.seen_since is None or s.t - self.last_seen > self.params.lost_timeout_s:
            self.seen_since = s.t
        self.last_seen = s.t
        self.last_x = s.x
        pose = self.fresh_pose(s.t)
        rel = self.seen_in_base(s)
        if pose is None or rel is None:
            return
        bx, by = rel
        c, sn = math.cos(pose.yaw), math.sin(pose.yaw)
        self.goal_xy = (pose.x + c * bx - sn * by, pose.y + sn * bx + c * by)

    def last_place_in_base(self, now: float) -> tuple[float, float] | None:
        """The target's last confirmed place as (bearing, distance) from the base now, if the pose is fresh."""
        pose = self.fresh_pose(now)
        if pose is None or self.goal_xy is None:
            return None
        dx, dy = self.goal_xy[0] - pose.x, self.goal_xy[1] - pose.y
        c, sn = math.cos(pose.yaw), math.sin(pose.yaw)
        return math.atan2(-sn * dx + c * dy, c * dx + sn * dy), math.hypot(dx, dy)

    def where(self) -> str:
        """Where the goal's object is in the world, as a reason's tail: the memory's place for it, else
        where the last ranged sighting put it ('' when neither is known)."""
        o = self.target_obj
        if o is not None:
            return f", at ({o.x:.2f}, {o.y:.2f}) in the odometry frame (memory, {o.confidence:.2f})"
        if self.goal_xy is not None:
            return f", at ({self.goal_xy[0]:.2f}, {self.goal_xy[1]:.2f}) in the odometry frame (its near side)"
        return ""

    # -- shared tools --------------------------------------------------------------------------
    def avoid(self, vx: float, wz: float, ap: ApproachParams, goal: tuple[float, float], now: float) -> Steer | None:
        """The planner's way round the fresh scan towards `goal` (bearing, base distance), or None (no
        planning: avoid_obstacles off, or no fresh scan)."""
        scan = self.fresh_scan(now) if self.params.avoid_obstacles else None
        return self.navigator.steering.steer(scan, self.params.planner, vx, wz, ap, goal, now)

    def turn(self, wz: float, state: str, reason: str, now: float, basis: str = "", note: str = "",
             angle: float = math.pi / 2) -> Command:  # fmt: skip
        """A turn in place at `wz` (rad/s), `angle` (rad) still to turn (a look round: a quarter turn at
        a time), made by the navigator (`Navigator.turn`: the routes' footprint and clearance rule; a
        driver's turn where there is no room); as asked with avoid_obstacles off (the guard alone
        holds it)."""
        p = self.params
        if not p.avoid_obstacles:
            return Command(0.0, wz, state, reason, note=note, basis=basis)
        nav = self._navigator()
        top = min(p.max_linear, p.nav.max_speed)  # a leg's creep: no faster than the mission's own walk
        out = nav.turn(wz, self.fresh_scan(now), now, max_linear=top, max_angular=p.max_angular, angle=angle)
        why = f"{reason}: {out.note}" if out.note else reason
        return Command(out.vx, out.wz, state, why, note=out.note or note, basis=basis, navigated=True)

    def detour(self, st: Steer, reason: str, now: float, basis: str = "") -> Command:
        """The local planner's way round an obstacle (`st` blocked); a turn in place, the navigator's."""
        if st.vx == 0.0 and st.wz != 0.0:
            return self.turn(st.wz, "detouring", reason, now, basis, st.note)
        return Command(st.vx, st.wz, "detouring", reason, note=st.note, basis=basis)

    def look_at(self, key: object, now: float) -> str:
        """Hold still and look at `key` (look.Look.check with the mission's settings and answers)."""
        p = self.params
        return self.look.check(
            key, now, settle_s=p.look_settle_s, timeout_s=p.look_timeout_s, answered=self.answers.through,
            latency=self.answers.latency,
        )  # fmt: skip


class Strategy(Protocol):
    """One way of getting closer to the goal. `step` answers for this step: a Command, or None when
    it has nothing to do now (the mission asks the next one). It may keep state of its own; `reset`
    forgets it when a new goal starts."""

    def reset(self, now: float) -> None: ...

    def step(self, ctx: Context, now: float) -> Command | None: ...


class SearchStrategy(Strategy, Protocol):
    """A search, asked when the target is neither confirmed by the tracker nor remembered (the
    mission's search chain, Mission.searches, in order). `step` returns None once it is exhausted
    (nothing more to try): the next one in the chain is asked, and when all are, the goal ends
    `not_found`. `pause` says that something else drove the robot this step ('seen': the tracker
    confirmed the target; 'memory': a remembered object), so a later search starts afresh."""

    name: str

    def pause(self, now: float, cause: str) -> None: ...
