"""The navigator: the one way from "be near (x, y)" to a velocity. Pure, timestamp-driven; the only
caller of the global planner in behavior/ for the places it is handed.

    nav = Navigator(NavParams(), GlobalParams())
    step = nav.step((x, y), tolerance, costmap, (px, py, yaw), scan_points, now,
                    max_linear=0.4, max_angular=0.8, body=0.0)
    step.vx, step.wz, step.status  # moving | arrived | recovering | failed | waiting

It owns, as Nav2 keeps them apart:
- the route (behavior/planner/route.Route over planner/global_path.plan_path): planned for a new
  goal (one that moved more than `goal_moved_m`: a remembered place that shifts by centimetres with
  each answer keeps its route), replanned when the newest map blocks it, when the robot strays
  from it, or as the map grows (then kept unless the new route costs `reroute_gain` less);
- the controller (navigate/controller.py: regulated pure pursuit, footprint-checked);
- one progress checker (navigate/progress.py: moving `progress_m` within `progress_s`, nearing the goal
  by as much within `nearing_s`, and a way left to go that does not keep growing back: `setbacks`);
- the recoveries (navigate/recovery.py: replan, spin, back up, wait, each bounded), tried in order
  on a stall; all tried and stalled again: `failed`, and the caller gives the place up.
`steering` steers towards a bearing and a distance where there is no route to follow (the local
planner, steer.py). `turn` makes a strategy's turn in place (a look round, facing a target) with the controller's
footprint check and driver's turn: nothing else in behavior/ turns the robot where it cannot sweep.
A caller choosing among places (the explorer, among frontiers) asks the navigator too: `costs`
(the path cost to each, one search) and `choose` (a plan to the nearest, which becomes the route).
`line_of_sight` asks the costmap whether a place is in plain view (a strategy that looks at a place
rather than walks to it asks it first).
`arrived`: within `tolerance` of the goal, or within `arrive_m` of the route's end (the passable cell
the plan reached); and once there, for as long as it is no farther from the goal (less `arrive_m`)
than where it arrived: a caller that closes the last of the way itself (the approach law, to the
stop distance) walks past the route's end, and a navigator that took that for "not there" backed it
to the end again. For a planner with `goal_in_sight` (a place to look at), each of these holds only
while the place is in sight on the map (no obstacle cell between but its own, within `body` of it,
planner/global_path.py `in_sight`): a robot that arrived and was then turned or pushed behind a
wall is no longer there, and the navigator walks it back into sight. `failed` also when no route can
be planned (the planner's reason).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, replace

import numpy as np

from go2vlm.behavior.navigate.controller import Leg, Rect, pursue, turn_in_place
from go2vlm.behavior.navigate.params import NavParams
from go2vlm.behavior.navigate.progress import Progress
from go2vlm.behavior.navigate.recovery import Recoveries
from go2vlm.behavior.navigate.steer import Avoider
from go2vlm.behavior.planner.global_path import (
    Costmap,
    GlobalParams,
    Plan,
    goal_costs,
    in_sight,
    line_cells,
    passable,
    plan_path,
)
from go2vlm.behavior.planner.route import BLOCKED, GROWN, Route
from go2vlm.geometry.footprint import Clearance
from go2vlm.world.occupancy import LETHAL

__all__ = ["NavStep", "Navigator", "in_view", "line_of_sight"]


def line_of_sight(cm: Costmap, a: tuple[float, float], b: tuple[float, float], p: GlobalParams, skip_m: float) -> bool:
    """Is the straight way from the robot at `a` to the object at `b` known and passable on `cm`, but
    for `skip_m` round `b` (the object is itself an obstacle) and the inflation within `escape_m` of
    `a` (the robot may stand in it)? An obstacle cell (LETHAL) near the robot still blocks: a wall
    0.6 m from it, with the remembered object 1.8 m away behind it, was taken for a straight way,
    and the robot pushed at the wall for three minutes."""
    line = line_cells(cm.cell(*a), cm.cell(*b))
    h, w = cm.shape
    if not ((line[:, 0] >= 0) & (line[:, 0] < h) & (line[:, 1] >= 0) & (line[:, 1] < w)).all():
        return False
    xy = cm.world(line[:, 0], line[:, 1])
    near_a = (np.hypot(xy[:, 0] - a[0], xy[:, 1] - a[1]) <= p.escape_m) & (cm.data[line[:, 0], line[:, 1]] < LETHAL)
    check = ~near_a & (np.hypot(xy[:, 0] - b[0], xy[:, 1] - b[1]) > skip_m)
    return bool(passable(cm, line[check], replace(p, unknown_cost=math.inf)).all())


def in_view(cm: Costmap, a: tuple[float, float], b: tuple[float, float], p: GlobalParams, body: float) -> bool:
    """Could a camera at `a` see the object at `b` on `cm`: does the straight line cross no obstacle
    cell but the object's own (within `body`, and pieces wholly within `body + p.goal_own_m`)? A wall
    just short of the object hides it, however near (`line_of_sight` skips that stretch)."""
    res = cm.resolution
    seen = in_sight(cm.data, np.array([cm.cell(*a)]), cm.cell(*b), body / res, p.goal_own_m / res)
    return bool(seen[0])


@dataclass(frozen=True)
class NavStep:
    vx: float
    wz: float
    status: str  # moving | arrived | recovering | failed | waiting
    reason: str
    note: str = ""  # what regulated or held the controller ("" = nothing)


class Navigator:
    def __init__(self, params: NavParams | None = None, planner: GlobalParams | None = None,
                 footprint: Rect | None = None) -> None:  # fmt: skip
        self.params = params or NavParams()
        self.planner = planner or GlobalParams()
        self.footprint = footprint or Rect()
        self.clearance = Clearance()  # the planners' and the guard's rule (the host sets its own)
        self.counters: Counter[str] = Counter()  # plans, failures: the commander's status
        self.recoveries = Recoveries()
        self.steering = Avoider()  # towards a bearing where there is no route (steer.py): its own reset
        self.progress = Progress()
        self.goal: tuple[float, float] | None = None
        self.route: Route | None = None
        self._index = 0
        self._speed = 0.0
        self._leg: Leg | None = None  # the controller's driver's-turn leg, handed back to it each step
        self._turn_leg: Leg | None = None  # ... and a strategy's turn's (`turn`)
        self._left = math.inf  # the way left along the route at the last step (m)
        self._there: float | None = None  # how far from the goal it was when it arrived (m)

    def reset(self) -> None:
        """Forget the goal and its route (a new goal, or the strategy gave the place up)."""
        self.goal, self.route, self._index, self._speed, self._leg = None, None, 0, 0.0, None
        self._turn_leg = None
        self._left = math.inf
        self._there = None
        self.progress.new_goal()
        self.recoveries.reset()

    def costs(self, cm: Costmap, start: tuple[float, float], goals: list[tuple[float, float]],
              planner: GlobalParams) -> np.ndarray:  # fmt: skip
        """The path cost from `start` to each of `goals` (inf: no way there), in one search."""
        self.counters["cost_searches"] += 1
        return goal_costs(cm, start, goals, planner)

    def choose(self, cm: Costmap, start: tuple[float, float], goals: list[tuple[float, float]],
               planner: GlobalParams, now: float) -> Plan:  # fmt: skip
        """A plan to the nearest of `goals` by path cost (`plan.goal_index` says which). When there is
        one, it becomes the route: the next `step` towards that goal follows it, unplanned again."""
        plan = self._plan(cm, start, goals, planner)
        if not plan.ok:
            return plan
        self.reset()
        self.goal = goals[plan.goal_index]
        self.route = Route(plan, self.goal, now, cm.stamp)
        return plan

    def _plan(self, cm: Costmap, start: tuple[float, float], goals: list[tuple[float, float]],
              planner: GlobalParams) -> Plan:  # fmt: skip
        """The global planner's plan, counted (`plans`, `plan_failures`: the commander's status)."""
        plan = plan_path(cm, start, goals, planner)
        self.counters["plans"] += 1
        self.counters["plans_tight"] += plan.tight
        if not plan.ok:
            self.counters["plan_failures"] += 1
        return plan

    def step(
        self, goal: tuple[float, float], tolerance: float, cm: Costmap | None, pose: tuple[float, float, float] | None,
        scan: np.ndarray | None, now: float, *, max_linear: float, max_angular: float, body: float = 0.0,
    ) -> NavStep:  # fmt: skip
        p = self.params
        if cm is None or pose is None:
            self._speed = 0.0
            return NavStep(0.0, 0.0, "waiting", "no map" if cm is None else "no fresh pose")
        if self.goal is None or math.hypot(goal[0] - self.goal[0], goal[1] - self.goal[1]) > p.goal_moved_m:
            self.reset()
        self.goal = goal
        x, y, yaw = pose
        end = self.route.plan.waypoints[-1] if self.route is not None else None
        off = math.hypot(goal[0] - x, goal[1] - y)
        near = off <= tolerance
        nearer = self._there is not None and off <= self._there + p.arrive_m  # nearer than where it arrived
        there = near or nearer or (end is not None and math.hypot(end[0] - x, end[1] - y) <= p.arrive_m)
        if there and self.planner.goal_in_sight:  # a place to look at: there only while in sight of it
            own = self.planner.goal_own_m / cm.resolution
            there = bool(in_sight(cm.data, np.array([cm.cell(x, y)]), cm.cell(*goal), body / cm.resolution, own)[0])
        if there:
            self._speed = 0.0
            self._there = off if self._there is None else min(self._there, off)
            return NavStep(0.0, 0.0, "arrived", "there")
        if self.recoveries.active is not None:
            cmd = self.recoveries.step(pose, scan, now, p, max_angular, self.footprint, self.clearance)
            if cmd is not None:
                self._speed = abs(cmd[0])
                return NavStep(cmd[0], cmd[1], "recovering", f"recovering: {self.recoveries.active}")
            self.progress.reset()
        self.progress.moved(x, y, now, p.progress_m, yaw, math.radians(p.progress_deg))
        why = "" if self.route is None else self.route.needs_replan(cm, x, y, now, self.planner)
        if self.route is None or why:
            self.counters["replans_blocked"] += why == BLOCKED
            tol = max(self.planner.goal_tolerance_m, tolerance)
            plan = self._plan(cm, (x, y), [goal], replace(self.planner, goal_tolerance_m=tol, goal_body_m=body))
            if not plan.ok:
                self.route = None
                return NavStep(0.0, 0.0, "failed", f"no route: {plan.reason}")
            new = Route(plan, goal, now, cm.stamp)
            if why == GROWN and self.route is not None and not self._better(new, cm, x, y):
                self.route.t, self.route.map_stamp, why = now, cm.stamp, ""  # kept: asked again a period on
                self.counters["routes_kept"] += 1
            else:
                self.route, self._index = new, 0
                if self.progress.replanned(plan.length, now, self._left if why == BLOCKED else None):
                    self.counters["setbacks"] += 1
                    if self.progress.setbacks >= p.setbacks:
                        return self._give_up(f"the way there grew back {p.setbacks} times, no nearer in between "
                                             f"({self.progress.best:.1f} m to go at the least)")  # fmt: skip
        if self.progress.stalled(now, p.progress_s, p.nearing_s):
            toward = self._toward(pose)
            name = self.recoveries.begin(pose, now, toward)
            if name is None:
                tried = self.recoveries.tried()
                return self._give_up(f"no progress (moving {p.progress_m:g} m in {p.progress_s:g} s, or nearing in "
                                     f"{p.nearing_s:g} s) after every recovery ({tried})")  # fmt: skip
            self.counters[f"recovery_{name}"] += 1
            if name == "replan":
                self.route = None
                self.recoveries.active = None
                return self.step(goal, tolerance, cm, pose, scan, now, max_linear=max_linear, max_angular=max_angular,
                                 body=body)  # fmt: skip
            return self.step(goal, tolerance, cm, pose, scan, now, max_linear=max_linear, max_angular=max_angular,
                             body=body)  # fmt: skip
        d = pursue(self.route.plan.waypoints, pose, scan, self._speed, p, max_linear, max_angular, self._index,
                   self.footprint, self.clearance, self._leg, now)  # fmt: skip
        self._index, self._speed, self._leg, self._left = d.index, d.vx, d.leg, d.remaining
        self.route.index = max(self.route.index, d.index + 1)  # Route.off_path and .blocked start there
        if self.progress.to_go(d.remaining, now, p.progress_m):
            self.recoveries.reset()  # nearer: the next stall starts from the first recovery again
        reason = f"{d.remaining:.1f} m along the route"
        tight = "tight" if self.route.plan.tight else ""  # the planner's: a gap walked at a crawl
        notes = ", ".join(n for n in (tight, d.note, f"replanned: {why}" if why else "") if n)
        return NavStep(d.vx, d.wz, "moving", f"{reason} ({notes})" if notes else reason, d.note)

    def turn(self, wz: float, scan: np.ndarray | None, now: float, *, max_linear: float, max_angular: float,
             angle: float = math.pi / 2) -> NavStep:  # fmt: skip
        """A turn in place at `wz` that a strategy asks for (a look round, facing its target), `angle`
        still to turn: the controller's `turn_in_place`, with the footprint and the clearance rule the
        routes keep; where there is no room to turn, a driver's turn (`moving`), or none (`waiting`:
        counted)."""
        d = turn_in_place(wz, scan, self.params, max_linear, max_angular, self.footprint, self.clearance,
                          self._turn_leg, now, angle)  # fmt: skip
        prev, self._turn_leg = self._turn_leg, d.leg
        if d.mode == "blocked":
            self.counters["turns_held"] += 1
            return NavStep(0.0, 0.0, "waiting", d.note, d.note)
        self.counters["turn_legs"] += d.leg is not None and d.leg is not prev
        return NavStep(d.vx, d.wz, "moving", d.note or "turning", d.note)

    def _better(self, new: Route, cm: Costmap, x: float, y: float) -> bool:
        """Is `new` worth leaving the route being walked for (the map has grown, nothing is wrong with
        it): cheaper by `reroute_gain`, both costed on `cm` from the robot? Two ways of about one cost
        took turns as the robot moved, and it walked back and forth between them."""
        assert self.route is not None
        keep = self.route.cost_left(cm, self.planner, x, y)
        return new.cost_left(cm, self.planner, x, y) < (1.0 - self.params.reroute_gain) * keep

    def _give_up(self, reason: str) -> NavStep:
        """`failed` for the goal (counted), and forget it: the caller gives the place up."""
        self.counters["failures"] += 1
        self.reset()
        return NavStep(0.0, 0.0, "failed", reason)

    def _toward(self, pose: tuple[float, float, float]) -> float:
        """The route's way from the robot's heading (rad, + left); 0 without a route."""
        if self.route is None:
            return 0.0
        w = self.route.plan.waypoints
        tx, ty = w[min(self._index + 1, len(w) - 1)]
        a = math.atan2(ty - pose[1], tx - pose[0]) - pose[2]
        return (a + math.pi) % (2 * math.pi) - math.pi

    def status(self) -> dict[str, object]:
        return {
            "goal": None if self.goal is None else [round(v, 2) for v in self.goal],
            "route_m": None if self.route is None else round(self.route.plan.length, 2),
            "recovering": self.recoveries.active,
            "recoveries": dict(self.recoveries.counts),
            **{k: v for k, v in self.counters.items()},
        }
