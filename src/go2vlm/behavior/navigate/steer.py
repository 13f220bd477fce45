"""The navigator's steering where there is no route to follow (a follow, a go to without a map, the
last bit to a remembered object, a detour out of view): the local planner (behavior/planner/local.py)
towards a bearing and a distance, with what it keeps from one step to the next: when it last had to
steer round something, the side it went round on and the way it chose, so that an obstacle dead
ahead is not passed left and right in turn. Pure, timestamp-driven; the navigator owns it
(`Navigator.steering`), and nothing else in behavior/ calls the local planner."""

from __future__ import annotations

import math

import numpy as np

from go2vlm.behavior.control import ApproachParams, approach_command
from go2vlm.behavior.planner import PlannerParams, Steer, steer

__all__ = ["Avoider"]


class Avoider:
    def __init__(self) -> None:
        self.detour_t: float | None = None  # when the planner last had to steer round something
        self.side = 0.0  # the side it went round on (+1 left, -1 right)
        self.side_t = -math.inf
        self.keep: float | None = None  # the way it chose last (rad from the goal's bearing), turning or walking
        self.keep_t = -math.inf

    def reset(self) -> None:
        self.detour_t, self.side, self.keep = None, 0.0, None

    def steer(
        self, points: np.ndarray | None, planner: PlannerParams, vx: float, wz: float, ap: ApproachParams,
        goal: tuple[float, float], now: float,
    ) -> Steer | None:  # fmt: skip
        """The planner's way round the scan `points` (base frame; None: no fresh scan, no planning)
        towards `goal` (bearing, base distance to its surface), given the approach's own (vx, wz)."""
        if points is None:
            return None
        bearing, dist = goal
        speed, _, _ = approach_command(0.0, dist, ap)
        side = self.side if now - self.side_t < planner.keep_s else 0.0
        keep = self.keep if now - self.keep_t < planner.keep_s else None
        st = steer(
            vx, wz, speed, bearing, dist, points, planner, max_angular=ap.max_angular,
            reach_m=dist - ap.stop_distance, side=side, keep=keep,
        )  # fmt: skip
        if st.blocked:
            self.detour_t = now
            if st.vx > 0.0 and abs(st.heading - bearing) > 1e-6:
                self.side, self.side_t = math.copysign(1.0, st.heading - bearing), now
            if st.way:
                self.keep, self.keep_t = st.heading - bearing, now
        return st
