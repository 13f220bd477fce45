"""The navigator's one progress checker (Nav2's simple progress checker, with heading): the robot must
move `progress_m` from where it stood, or turn `progress_deg` from the heading it had there (a turn
round in a narrow corridor is progress), within `progress_s`, else it is stalled. Pure,
timestamp-driven."""

from __future__ import annotations

import math

from go2vlm.world.poses import wrap_angle

__all__ = ["Progress"]


class Progress:
    def __init__(self) -> None:
        self.anchor: tuple[float, float, float, float] | None = None  # x, y, yaw, since when

    def reset(self) -> None:
        self.anchor = None

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
