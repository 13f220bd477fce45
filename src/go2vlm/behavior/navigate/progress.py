"""The navigator's one progress checker.

- Moving (Nav2's simple progress checker, with heading): the robot must move `progress_m` from where
  it stood, or turn `progress_deg` from the heading it had there (a turn round in a narrow corridor is
  progress), within `progress_s`, else it is stalled.
- Nearing: the way left to go (along the route) must fall `progress_m` below its least within
  `nearing_s`, else it is stalled too: a robot that shuffles by a place it cannot reach moves all the
  time. Only nearing starts the recoveries from the first again, so that they stay bounded.
- Setbacks: a replan because the map blocked the route, whose new route is more than `setback_m`
  longer than the way that was left on the blocked one, is a setback (the way is measured from the
  new route on). A robot whose route keeps growing back (the near way closes as it comes near, a far
  way opens as it walks off) nears along every route and never arrives: after `setbacks` of them the
  goal is given up. Only a block counts: a replan as the map grows, or after a stray, may choose a
  longer way that costs less (the planner weighs cost, not length), and two such ways can take turns
  with nothing wrong; their nearing is still measured against the least way left.

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

    def reset(self) -> None:
        """After a recovery: both clocks start again; what the goal's way has been is kept."""
        self.anchor = self.neared_t = None

    def new_goal(self) -> None:
        self.reset()
        self.least_to_go, self.setbacks = math.inf, 0

    def to_go(self, metres: float, now: float, by: float) -> bool:
        """The way left to go along the route now: is it `by` m below its least (the robot nears)?"""
        if self.neared_t is None:
            self.neared_t = now
        if metres < self.least_to_go - by or not math.isfinite(self.least_to_go):
            nearer = math.isfinite(self.least_to_go)
            self.least_to_go, self.neared_t = metres, now
            return nearer
        return False

    def replanned(self, metres: float, now: float, setback_m: float, blocked_left: float | None) -> bool:
        """A new route `metres` long from the robot, replanned because the map blocked the route with
        `blocked_left` m left on it (None: for another reason): is it a setback (counted; the way is
        measured from it on)?"""
        if blocked_left is None or metres <= blocked_left + setback_m:
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
