"""Walking a global route: the global planner's waypoints (behavior/planner/global_path.py) handed,
one at a time, to the approach law (behavior/control.py) and the local planner (ctx.avoid), so that
the safety gate and its collision guard keep the last word. Pure, timestamp-driven.

- `follow_waypoint`: the next waypoint as a bearing and distance: the approach law turns on the
  spot only for a waypoint more than WAYPOINT_ALIGN_STOP off, and walks at the speed the distance
  left *along the route* allows (not the waypoint's: no slowing at every corner); the local planner
  steers round what the scan shows on the way to it.
- `RouteTo`: a route to a remembered place the robot cannot see straight (the straight line crosses a
  wall, or space the map does not know): planned on the costmap preferring known free space
  (`unknown_cost`), replanned when the map blocks it, the robot strays, or the map grows; None while
  the straight way is clear (the direct approach does better there) or without a map. A route that
  still holds is walked on though the straight way clears: seen from a doorway, a look for flipped
  each second between its route and a turn to a place the camera could not see (rooms 19).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from go2vlm.behavior.control import approach_command
from go2vlm.behavior.planner.global_path import Costmap, GlobalParams, line_cells, passable, plan_path
from go2vlm.behavior.planner.route import GROWN, Route
from go2vlm.behavior.strategies.base import Command, Context
from go2vlm.world.occupancy import LETHAL

__all__ = ["DEFAULT_VIEW", "WAYPOINT_ALIGN_STOP", "RouteTo", "follow_waypoint", "line_of_sight"]

DEFAULT_VIEW = math.radians(73.0)  # the head camera's, until a tracker report has said
# A waypoint is walked to turning while it lies within WAYPOINT_ALIGN_STOP (x half the view: 44 deg),
# at full speed within WAYPOINT_ALIGN_START (11 deg). The approach's own window (15 deg) keeps a target
# centred in view, which a waypoint does not need: walks to frontiers spent 37 % of their time turning
# on the spot (rooms suite, apartment, at 7f6d3e5). The planner checks the arc, the guard has the last word.
WAYPOINT_ALIGN_START = 0.3
WAYPOINT_ALIGN_STOP = 1.2


def follow_waypoint(
    ctx: Context, bearing: float, dist: float, remaining: float, now: float, state: str, reason: str, basis: str = ""
) -> Command:
    """Walk towards a waypoint at `bearing` (rad, + left), `dist` m away, `remaining` m from the route's end."""
    ap = replace(ctx.approach_params(), stop_distance=0.0, align_start=WAYPOINT_ALIGN_START,
                 align_stop=WAYPOINT_ALIGN_STOP)  # fmt: skip
    view = ctx.view or DEFAULT_VIEW
    vx, wz, _ = approach_command(-bearing / (view / 2.0), max(remaining, dist), ap)
    st = ctx.avoid(vx, wz, ap, (bearing, dist), now)
    if st is not None and st.blocked:
        return Command.detour(st, f"{reason}: {st.note}", basis=basis, toward=bearing)
    return Command(vx, wz, state, reason, basis=basis, toward=bearing)


def line_of_sight(cm: Costmap, a: tuple[float, float], b: tuple[float, float], p: GlobalParams, skip_m: float) -> bool:
    """Is the straight way from the robot at `a` to the object at `b` known and passable on `cm`, but
    for `skip_m` round `b` (the object is itself an obstacle) and the inflation within `escape_m` of
    `a` (the robot may stand in it)? An obstacle cell (LETHAL) near the robot still blocks: a wall
    0.6 m from it, with the remembered object 1.8 m away behind it, was taken for a straight way,
    and the robot pushed at the wall for three minutes (rooms 6)."""
    line = line_cells(cm.cell(*a), cm.cell(*b))
    h, w = cm.shape
    if not ((line[:, 0] >= 0) & (line[:, 0] < h) & (line[:, 1] >= 0) & (line[:, 1] < w)).all():
        return False
    xy = cm.world(line[:, 0], line[:, 1])
    near_a = (np.hypot(xy[:, 0] - a[0], xy[:, 1] - a[1]) <= p.escape_m) & (cm.data[line[:, 0], line[:, 1]] < LETHAL)
    check = ~near_a & (np.hypot(xy[:, 0] - b[0], xy[:, 1] - b[1]) > skip_m)
    return bool(passable(cm, line[check], replace(p, unknown_cost=math.inf)).all())


class RouteTo:
    """A route to a place (a remembered object's), kept while it stays good (module docstring)."""

    def __init__(self, params: GlobalParams | None = None) -> None:
        self.params = params or GlobalParams(unknown_cost=20.0)
        self.route: Route | None = None
        self.reason = ""  # why there is no route ('' when there is one, or none is needed)

    def reset(self) -> None:
        self.route, self.reason = None, ""

    def next(
        self, ctx: Context, target: tuple[float, float], reach_m: float, now: float, force: bool = False
    ) -> tuple[float, float, float] | None:
        """(bearing, distance) to the next waypoint and the metres left along the route to `target`
        (whose surface the robot stops `reach_m` short of); None: go straight (no map, no pose, the
        straight way is clear unless `force`, or no route could be planned: `reason` says why)."""
        cm, pose = ctx.costmap, ctx.fresh_pose(now)
        if cm is None or pose is None:
            self.route = None
            return None
        p = replace(self.params, goal_tolerance_m=max(self.params.goal_tolerance_m, reach_m))
        sight = not force and line_of_sight(cm, (pose.x, pose.y), target, p, skip_m=max(p.escape_m, reach_m))
        r = self.route
        why = "" if r is not None and r.goal == target and not r.done else "new"
        if not why and r is not None:
            why = r.needs_replan(cm, pose.x, pose.y, now, p)
        if sight and why and why != GROWN:  # a route that still holds is kept: the straight way flickers (rooms 19)
            self.route, self.reason = None, ""
            return None
        if why:
            plan = plan_path(cm, (pose.x, pose.y), [target], p)
            if not plan.ok:
                self.route, self.reason = None, plan.reason
                return None
            self.route, self.reason = Route(plan, target, now, cm.stamp), ""
        assert self.route is not None
        if self.route.done:
            return None
        return self.route.target(pose.x, pose.y, pose.yaw)
