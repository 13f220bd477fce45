"""Out of the guard's way, step after step: planner/local.py `unstick` on each of the commander's
commands, with what it must remember from one step to the next. Pure, timestamp-driven.

- A turn that `unstick` sent the other way round is kept for half a turn: else the way it wanted,
  free again a few degrees on, flipped it back and forth.
- A back-away towards the way on (`toward`, behind the robot: local.py `reverse`) is kept up for
  REVERSE_HOLD_S while that way stays behind and the arc clear: else the turn, free again a few
  degrees on, was tried and held again, and the robot backed a few centimetres at a time.
"""

from __future__ import annotations

import math

import numpy as np

from go2vlm.behavior.planner.local import REVERSE_SPEED, TURN_ONLY_VX, PlannerParams, Steer, behind, reverse, unstick

__all__ = ["REVERSE_HOLD_S", "Escape"]

REVERSE_HOLD_S = 2.0  # s a back-away towards the way on is kept up


class Escape:
    def __init__(self) -> None:
        self.other_way: tuple[float, float] | None = None  # a turn the other way round: (sign, until)
        self.reverse_until = -math.inf  # backing towards a way on behind: kept up till then

    def reset(self) -> None:
        self.other_way, self.reverse_until = None, -math.inf

    def step(
        self, vx: float, wz: float, now: float, scan: np.ndarray | None, p: PlannerParams, *, max_angular: float,
        walk: float = 0.0, toward: float | None = None,
    ) -> tuple[float, float, str] | None:  # fmt: skip
        """(vx, wz, why) instead of the command (vx, wz), or None: it stands. `scan`: the fresh scan's
        points (base frame; None: none); `walk` and `toward` as local.py `unstick`'s."""
        back_on = toward is not None and behind(toward)
        if toward is not None and back_on and now < self.reverse_until and vx <= TURN_ONLY_VX:
            back = reverse(scan, toward, p, "keeping on")
            if back is not None:
                return _bounded(back, max_angular)
        self.reverse_until = -math.inf
        ow, kept = self.other_way, None
        if ow is not None and now < ow[1] and vx <= TURN_ONLY_VX and wz * ow[0] < 0:
            wz = math.copysign(abs(wz), ow[0])
            kept = (vx, wz, "keeping to the other way round")
        elif ow is not None:
            self.other_way = None
        back = unstick(vx, wz, scan, p, walk, toward)
        if back is None:
            return kept
        if back.vx < 0.0 and back_on:
            self.reverse_until = now + REVERSE_HOLD_S
        if back.vx == 0.0 and back.wz * wz < 0 and self.other_way is None:
            self.other_way = (math.copysign(1.0, back.wz), now + math.pi / max(abs(back.wz), 1e-3))
        return _bounded(back, max_angular)


def _bounded(st: Steer, max_angular: float) -> tuple[float, float, str]:
    """`st` as (vx, wz, why), backing no faster than REVERSE_SPEED and turning within max_angular."""
    return max(st.vx, -REVERSE_SPEED), max(-max_angular, min(max_angular, st.wz)), st.note
