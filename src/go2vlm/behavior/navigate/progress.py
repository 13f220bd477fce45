"""The navigator's one progress checker.

- Moving (Nav2's simple progress checker, with heading): the robot must move `progress_m` from where
  it stood, or turn `progress_deg` from the heading it had there (a turn round in a narrow corridor is
  progress), within `progress_s`, else it is stalled.
- Nearing: the way left to go (along the route) is kept at its least for the goal; a replan that
  makes it more than `setback_m` longer than that is a setback. A robot that walks and walks but whose
  route keeps growing back (the near way closes as it comes near, a far way opens as it walks off)
  moves all the time and never nears the goal: after `setbacks` of them the goal is given up.

Pure, timestamp-driven."""

from __future__ import annotations

import math

from go2vlm.world.poses import wrap_angle

__all__ = ["Progress"]


class Progress:
    def __init__(self) -> None:
        self.anchor: tuple[float, float, float, float] | None = None  # x, y, yaw, since when
        self.least_to_go = math.inf  # the least way left to go (m) for this goal
        self.setbacks = 0

    def reset(self) -> None:
        """A new anchor (after a recovery): what the goal's way has been is kept."""
        self.anchor = None

    def new_goal(self) -> None:
        self.anchor, self.least_to_go, self.setbacks = None, math.inf, 0

    def to_go(self, metres: float) -> None:
        """The way left to go along the route now."""
        self.least_to_go = min(self.least_to_go, metres)

    def replanned(self, metres: float, setback_m: float) -> bool:
        """A new route `metres` long from the robot: is it a setback (counted)?"""
        back = metres > self.least_to_go + setback_m
        self.setbacks += back
        self.to_go(metres)
        return back

    def moved(self, x: float, y: float, now: float, radius: float, yaw: float = 0.0, turn: float = math.inf) -> bool:
        """Has the robot left its anchor by `radius` m, or turned `turn` rad from its heading there (the
        anchor then moves to it)? The first call anchors."""
        a = self.anchor
        if a is None or math.hypot(x - a[0], y - a[1]) >= radius or abs(wrap_angle(yaw - a[2])) >= turn:
            self.anchor = (x, y, yaw, now)
            return a is not None
        return False

    def stalled(self, now: float, allowance: float) -> bool:
        """No move since the anchor for `allowance` s (the anchor's clock restarts when it says so)."""
        a = self.anchor
        if a is None or now - a[3] < allowance:
            return False
        self.anchor = (a[0], a[1], a[2], now)
        return True
