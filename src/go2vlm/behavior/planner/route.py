"""A global plan being followed (the global planner: planner/global_path.py). Pure, timestamp-driven.

Replanning (`Route`): the commander replans when a new costmap makes the rest of the route cross a
cell that is now lethal (or unknown, where unknown is not to be crossed), when the robot strays
more than `off_path_m` from it, and at most every `replan_period_s` as the map grows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from go2vlm.behavior.planner.global_path import (
    Costmap,
    GlobalParams,
    Plan,
    chain_cost,
    costs_of,
    line_cells,
    passable,
)

__all__ = ["BLOCKED", "GROWN", "OFF_ROUTE", "Route", "path_cost"]

GROWN = "the map has grown"  # the one replan that says nothing is wrong with the route
BLOCKED = "the route is blocked on the new map"  # the one that says the map took the way back
OFF_ROUTE = "off the route"


def path_cost(cm: Costmap, points: np.ndarray, p: GlobalParams) -> float:
    """The search's cost (as `chain_cost`) of walking the straight legs between world `points` on `cm`
    (inf: a cell on them may not be entered, or lies off the grid)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) < 2:
        return 0.0
    legs = [line_cells(cm.cell(*a), cm.cell(*b)) for a, b in zip(pts[:-1], pts[1:], strict=True)]
    cells = np.concatenate([legs[0], *(leg[1:] for leg in legs[1:])])
    h, w = cm.shape
    if not ((cells[:, 0] >= 0) & (cells[:, 0] < h) & (cells[:, 1] >= 0) & (cells[:, 1] < w)).all():
        return math.inf
    (r0, c0), (r1, c1) = cells.min(axis=0), cells.max(axis=0) + 1  # the costs of the box they lie in only
    return chain_cost(costs_of(cm.data[r0:r1, c0:c1], p), cells - (r0, c0))


@dataclass
class Route:
    """A plan being followed: the next waypoint, and when to replan (timestamp-driven).

    `reach_m`: a waypoint this near counts as passed. `target()` gives the next waypoint as
    (bearing from the robot's heading, distance), and the distance left along the route."""

    plan: Plan
    goal: tuple[float, float]
    t: float  # when it was planned
    map_stamp: float
    reach_m: float = 0.4
    index: int = 1  # the waypoint being walked to

    def advance(self, x: float, y: float) -> None:
        w = self.plan.waypoints
        while self.index < len(w) - 1 and math.hypot(w[self.index][0] - x, w[self.index][1] - y) < self.reach_m:
            self.index += 1

    @property
    def done(self) -> bool:
        return self.index >= len(self.plan.waypoints) - 1

    def target(self, x: float, y: float, yaw: float) -> tuple[float, float, float]:
        """(bearing rad + left, distance m) to the next waypoint, and the metres left to the route's end."""
        self.advance(x, y)
        w = self.plan.waypoints
        i = min(self.index, len(w) - 1)
        dx, dy = w[i][0] - x, w[i][1] - y
        bearing = math.atan2(dy, dx) - yaw
        bearing = (bearing + math.pi) % (2 * math.pi) - math.pi
        dist = math.hypot(dx, dy)
        rest = float(np.sum(np.hypot(*np.diff(w[i:], axis=0).T))) if i < len(w) - 1 else 0.0
        return bearing, dist, dist + rest

    def off_path(self, x: float, y: float) -> float:
        """Distance (m) from (x, y) to the route's remaining legs (from the one being walked)."""
        w = self.plan.waypoints
        i = max(1, min(self.index, len(w) - 1))
        best = math.inf
        for a, b in zip(w[i - 1 : -1], w[i:], strict=False):
            ab = b - a
            t = 0.0 if not ab.any() else max(0.0, min(1.0, float(np.dot((x, y) - a, ab) / np.dot(ab, ab))))
            best = min(best, math.hypot(*(a + t * ab - (x, y))))
        return best

    def blocked(self, cm: Costmap, p: GlobalParams, x: float, y: float) -> bool:
        """Does the rest of the route, from the robot at (x, y) on, cross a cell that `cm` says may
        not be entered? (Cells within `escape_m` of the robot do not count: it may stand in the
        inflation, by a wall, and the local planner and the guard see to that.)"""
        w = self.plan.waypoints
        i = max(1, min(self.index, len(w) - 1))
        legs = [(np.array((x, y)), w[i])] + list(zip(w[i:-1], w[i + 1 :], strict=False))
        for n, (a, b) in enumerate(legs):
            line = line_cells(cm.cell(*a), cm.cell(*b))
            if n == 0:
                xy = cm.world(line[:, 0], line[:, 1])
                line = line[np.hypot(xy[:, 0] - x, xy[:, 1] - y) > p.escape_m]
            if not passable(cm, line, p).all():
                return True
        return False

    def cost_left(self, cm: Costmap, p: GlobalParams, x: float, y: float) -> float:
        """The planner's cost on `cm` of the rest of the route from the robot at (x, y) on."""
        w = self.plan.waypoints
        i = max(1, min(self.index, len(w) - 1))
        return path_cost(cm, np.vstack([[x, y], w[i:]]), p)

    def needs_replan(self, cm: Costmap, x: float, y: float, now: float, p: GlobalParams) -> str:
        """Why to replan now ('' = keep the route)."""
        if self.off_path(x, y) > p.off_path_m:
            return OFF_ROUTE
        if cm.stamp != self.map_stamp:
            if self.blocked(cm, p, x, y):
                return BLOCKED
            if now - self.t >= p.replan_period_s:
                return GROWN
        return ""
