"""The navigator's one progress checker (Nav2's simple progress checker): the robot must move
`progress_m` from where it stood within `progress_s`, else it is stalled. Pure, timestamp-driven."""

from __future__ import annotations

import math

__all__ = ["Progress"]


class Progress:
    def __init__(self) -> None:
        self.anchor: tuple[float, float, float] | None = None  # x, y, since when

    def reset(self) -> None:
        self.anchor = None

    def moved(self, x: float, y: float, now: float, radius: float) -> bool:
        """Has the robot left its anchor by `radius` (the anchor then moves to it)? The first call anchors."""
        a = self.anchor
        if a is None or math.hypot(x - a[0], y - a[1]) >= radius:
            self.anchor = (x, y, now)
            return a is not None
        return False

    def stalled(self, now: float, allowance: float) -> bool:
        """No move since the anchor for `allowance` s (the anchor's clock restarts when it says so)."""
        a = self.anchor
        if a is None or now - a[2] < allowance:
            return False
        self.anchor = (a[0], a[1], now)
        return True
