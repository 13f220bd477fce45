"""The navigator's one progress checker.

- Moving (Nav2's simple progress checker, with heading): the robot must move `progress_m` from where
  it stood, or turn `progress_deg` from the heading it had there (a turn round in a narrow corridor is
  progress), within `progress_s`, else it is stalled.
- Nearing: the way left to go (along the route) must fall `progress_m` below its least within
  `nearing_s`, else it is stalled too: a robot that shuffles by a place it cannot reach moves all the
  time. Only nearing starts the recoveries from the first again, so that they stay bounded.
- Setbacks: the map blocks the route and the new one is longer than the way that was left on it,
  and the robot has come no nearer (`progress_m` below the least way left at the block before)
  since the block before: the map takes the way back faster than the robot wins any. Such a robot
  moves all the time and never arrives: the near way closes as it comes near and a far one opens as
  it walks off, or a marginal gap shuts and opens as it turns about before it (the first block of a
  goal, or one after nearing, is a detour, not a setback). After `setbacks` of them the goal is given
  up. Only a block counts: a replan as the map grows, or after a stray, may choose a longer way that
  costs less (the planner weighs cost, not length), and two such ways can take turns with nothing
  wrong.

Pure, timestamp-driven."""

from __future__ import annotations

import math

from go2vlm.world.poses import wrap_angle

__all__ = ["Progress"]


class Progress:
    def __init__(self) -> None:
        self.anchor: tuple[float, float, float, float] | None = None  # x, y, yaw, since when
        self.least_to_go = math.inf  # the least way left to go (m) for this goal, since its last setback
        self.neared_t: float | None = None  # when it last fell
        self.setbacks = 0
        self.best = math.inf  # the least way left for this goal, ever
        self.block_best = math.inf  # ... as it was at the last block
        self.neared_since_block = True

    def reset(self) -> None:
        """After a recovery: both clocks start again; what the goal's way has been is kept."""
        self.anchor = self.neared_t = None

    def new_goal(self) -> None:
        self.reset()
        self.least_to_go, self.setbacks = math.inf, 0
        self.best = self.block_best = math.inf
        self.neared_since_block = True

    def to_go(self, metres: float, now: float, by: float) -> bool:
        """The way left to go along the route now: is it `by` m below its least (the robot nears)?"""
        if self.neared_t is None:
            self.neared_t = now
        self.best = min(self.best, metres)
        if metres < self.block_best - by:
            self.neared_since_block = True
        if metres < self.least_to_go - by or not math.isfinite(self.least_to_go):
            nearer = math.isfinite(self.least_to_go)
            self.least_to_go, self.neared_t = metres, now
            return nearer
        return False

    def replanned(self, metres: float, now: float, blocked_left: float | None) -> bool:
        """A new route `metres` long from the robot, replanned because the map blocked the route with
        `blocked_left` m left on it (None: for another reason): is it a setback (counted; the stall
        clock is measured from it on)?"""
        if blocked_left is None or metres <= blocked_left:
            return False
        neared, self.neared_since_block, self.block_best = self.neared_since_block, False, self.best
        if neared:
            return False
        self.setbacks += 1
        self.least_to_go, self.neared_t = metres, now
        return True

    def moved(self, x: float, y: float, now: float, radius: float, yaw: float = 0.0, turn: float = math.inf) -> bool:
        """Has the robot left its anchor by `radius` m, or turned `turn` rad from its heading there (the
        anchor then moves to it)? The first call anchors."""
        a = self.anchor
        if a is None or math.hypot(x - a[0], y - a[1]) >= radius or abs(wrap_angle(yaw - a[2])) >= turn:
            self.anchor = (x, y, yaw, now)
            return a is not None
        return False

    def stalled(self, now: float, allowance: float, nearing_s: float) -> bool:
        """No move since the anchor for `allowance` s, or no nearer for `nearing_s` (both clocks restart
        when it says so)."""
        a, t = self.anchor, self.neared_t
        still = a is not None and now - a[3] >= allowance
        far = t is not None and now - t >= nearing_s
        if not (still or far):
            return False
        self.anchor = None if a is None else (a[0], a[1], a[2], now)
        self.neared_t = None if t is None else now
        return True
