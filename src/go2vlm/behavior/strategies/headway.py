"""Headway on a go to: the reactive approach (the local planner steering towards the target's bearing)
can cycle where the global planner knows the way. A go to that keeps the robot within HEADWAY_M of
one spot for HEADWAY_S walks the global route to the target's place instead (planned whether or not
the straight way looks clear), until it is ROUTE_OUT_M from where it stalled, the route ends or
cannot be planned, or ROUTE_FOR_S has passed; then the watch starts afresh. Seen through a doorway
from beside its jamb, the dining table held the local planner swinging round the jamb for 150 s,
0.3 m from the gap the route takes (rooms 45). Pure, timestamp-driven.
"""

from __future__ import annotations

import math

from go2vlm.behavior.strategies.base import Command, Context
from go2vlm.behavior.strategies.route import RouteTo, follow_waypoint

__all__ = ["HEADWAY_M", "HEADWAY_S", "ROUTE_FOR_S", "ROUTE_OUT_M", "Headway"]

HEADWAY_S = 10.0  # within HEADWAY_M of one spot this long, walking to a goal: stalled
HEADWAY_M = 0.4
ROUTE_OUT_M = 1.5  # the route taken on a stall is walked this far from where it stalled ...
ROUTE_FOR_S = 20.0  # ... for at most this long
GAP_S = 3.0  # no go-to step this long (a search, a look): the watch starts afresh


class Headway:
    """The stall watch of one go-to strategy, and its way out along the global route."""

    def __init__(self) -> None:
        self.router = RouteTo()
        self.anchor: tuple[float, float, float] | None = None  # x, y, since when within HEADWAY_M of it
        self.stalled: tuple[float, float, float] | None = None  # x, y, t of the stall being walked out of
        self.last = -math.inf  # the last step

    def reset(self) -> None:
        self.anchor = self.stalled = None
        self.router.reset()
        self.last = -math.inf

    def step(
        self, ctx: Context, target: tuple[float, float], reach_m: float, now: float
    ) -> tuple[float, float, float] | None:
        """(bearing, distance) to the next waypoint of the route out of a stall towards `target`, and
        the metres left along it; None: headway is fine, or no route (the caller steers as before)."""
        pose = ctx.fresh_pose(now)
        if pose is None:
            return None
        if now - self.last > GAP_S:
            self.reset()
        self.last = now
        if self.stalled is not None:
            sx, sy, st = self.stalled
            if math.hypot(pose.x - sx, pose.y - sy) < ROUTE_OUT_M and now - st < ROUTE_FOR_S:
                via = self.router.next(ctx, target, reach_m, now, force=True)
                if via is not None:
                    ctx.route = self.router.route
                    return via
            self.stalled = None
            self.router.reset()
            self.anchor = (pose.x, pose.y, now)
            return None
        if self.anchor is None or math.hypot(pose.x - self.anchor[0], pose.y - self.anchor[1]) > HEADWAY_M:
            self.anchor = (pose.x, pose.y, now)
            return None
        if now - self.anchor[2] < HEADWAY_S:
            return None
        self.stalled = (pose.x, pose.y, now)
        ctx.counters["stalled"] += 1
        return self.step(ctx, target, reach_m, now)

    def walk(
        self, ctx: Context, target: tuple[float, float], reach_m: float, now: float, why: str, basis: str = ""
    ) -> Command | None:
        """`step`'s way out as a command along the route (`why` opens its reason); None: carry on as before."""
        via = self.step(ctx, target, reach_m, now)
        if via is None:
            return None
        b, d, rest = via
        return follow_waypoint(ctx, b, d, rest, now, "approaching",
                               f"{why}: no headway, along the route ({rest:.1f} m left)", basis=basis)  # fmt: skip
