"""The navigator's recoveries: one ordered, bounded list (params.RECOVERIES), tried one at a time
each time the progress checker says stalled, from the first again once the robot nears the goal
(moving about alone is not enough: a robot that shuffles by a place it cannot reach moves).
Pure, timestamp-driven.

- `replan`: drop the route; the next step plans anew on the newest map (the local view refreshed).
- `spin`: turn in place `spin_deg`, towards the route's side, where the footprint's sweep is clear
  (the lidar sees round the robot, and the map fills in).
- `back_up`: straight back `back_up_m` at `back_up_speed`, where that is clear.
- `wait`: hold still `wait_s` (a person or a door in the way may move).
A recovery that cannot run (no room to turn or to back) is skipped and counted as tried; each ends
when done or after `recovery_s`. When all have been tried and the robot is stalled again, the caller
gives the place up (the navigator says `failed`, with each recovery tried).
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np

from go2vlm.behavior.navigate.params import RECOVERIES, NavParams
from go2vlm.behavior.navigate.sweep import Rect, arc_clearance, fits
from go2vlm.geometry.footprint import Clearance
from go2vlm.world.poses import wrap_angle

__all__ = ["Recoveries"]


class Recoveries:
    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()  # each recovery started, over the navigator's life
        self.reset()

    def reset(self) -> None:
        """Nearer the goal (or a new one): the next stall starts from the first recovery again."""
        self.next = 0
        self.active: str | None = None
        self._t0 = 0.0
        self._start: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._yaw = 0.0
        self._turned = 0.0
        self._dir = 1.0

    @property
    def exhausted(self) -> bool:
        return self.next >= len(RECOVERIES) and self.active is None

    def tried(self) -> str:
        return ", ".join(RECOVERIES[: self.next]) or "none"

    def begin(self, pose: tuple[float, float, float], now: float, toward: float) -> str | None:
        """Start the next recovery (`toward`: rad, + left, the route's way from the heading); None: all tried."""
        if self.next >= len(RECOVERIES):
            return None
        name = RECOVERIES[self.next]
        self.next += 1
        self.counts[name] += 1
        self.active, self._t0, self._start = name, now, pose
        self._yaw, self._turned, self._dir = pose[2], 0.0, 1.0 if toward >= 0 else -1.0
        return name

    def step(
        self, pose: tuple[float, float, float], scan: np.ndarray | None, now: float, p: NavParams,
        max_angular: float, fp: Rect, rule: Clearance,
    ) -> tuple[float, float] | None:  # fmt: skip
        """The running recovery's command, or None: it is over (or there is none)."""
        name = self.active
        if name is None or now - self._t0 > p.recovery_s or name == "replan":
            self.active = None
            return None
        pts = scan if scan is not None else np.zeros((0, 2))
        here = arc_clearance(pts, 0.0, 0.0, 0.0, fp)
        if name == "spin":
            self._turned += abs(wrap_angle(pose[2] - self._yaw))
            self._yaw = pose[2]
            if self._turned >= math.radians(p.spin_deg):
                self.active = None
                return None
            wz = math.copysign(max(p.min_turn_rate, 0.5 * max_angular), self._dir)
            for w in (wz, -wz):
                if fits(pts, 0.0, w, p.horizon_s, fp, rule, here):
                    self._dir = math.copysign(1.0, w)
                    return 0.0, w
            self.active = None
            return None
        if name == "back_up":
            gone = math.hypot(pose[0] - self._start[0], pose[1] - self._start[1])
            v = -p.back_up_speed
            room = fits(pts, v, 0.0, p.horizon_s, fp, rule, here)
            if gone >= p.back_up_m or not room:
                self.active = None
                return None
            return v, 0.0
        if now - self._t0 >= p.wait_s:  # wait
            self.active = None
            return None
        return 0.0, 0.0
