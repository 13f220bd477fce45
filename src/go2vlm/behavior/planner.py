"""A local planner for the go-to approach: steer round what /scan shows between the robot and its goal.

Pure (no DDS), a vector-field-histogram idea cut to what the approach needs: candidate headings
around the robot's own, each a straight corridor as wide as the footprint plus `margin`; the free
length of a corridor is how far the robot could drive that way before its front meets a scan point.
If the corridor towards the goal is free for `lookahead` (or up to the goal), the approach's command
passes unchanged. Otherwise the planner picks the free heading closest to the goal's bearing, but
only within `max_offset` of it, so that the goal stays in the camera's view (the tracker must keep
seeing it), turns towards it and slows with the angle. No free heading: turn in place towards the
freest one that keeps the goal in view, and say so. The safety gate's collision guard still has the
last word on every command; the planner only keeps the approach out of the guard's way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from go2vlm.robots.go2.spec import FOOTPRINT_LENGTH, FOOTPRINT_WIDTH

__all__ = ["PlannerParams", "Steer", "corridor_free", "steer"]


@dataclass(frozen=True)
class PlannerParams:
    margin: float = 0.35  # m each side of the footprint (a little more than the guard's 0.3)
    lookahead: float = 1.0  # m of free corridor that counts as free
    max_offset: float = math.radians(35.0)  # how far from the goal's bearing it may head (head camera ~37 deg)
    step: float = math.radians(5.0)
    kp: float = 1.5  # rad/s per rad of heading error
    max_angular: float = 0.8
    half_length: float = FOOTPRINT_LENGTH / 2
    half_width: float = FOOTPRINT_WIDTH / 2


@dataclass(frozen=True)
class Steer:
    vx: float
    wz: float
    heading: float  # rad, the chosen heading (robot frame, + left)
    note: str  # "" when the approach's own command passed


def corridor_free(points: np.ndarray, heading: float, p: PlannerParams) -> float:
    """How far (m) the footprint's front can go along `heading` before it is within `margin` of a point."""
    if len(points) == 0:
        return math.inf
    c, s = math.cos(heading), math.sin(heading)
    along = points[:, 0] * c + points[:, 1] * s
    across = -points[:, 0] * s + points[:, 1] * c
    block = (np.abs(across) < p.half_width + p.margin) & (along > 0)
    if not block.any():
        return math.inf
    return max(0.0, float(along[block].min()) - p.half_length - p.margin)


def steer(vx: float, wz: float, bearing: float, goal_m: float | None, points: np.ndarray, p: PlannerParams) -> Steer:
    """The approach's (vx, wz) towards a goal at `bearing` (rad, + left) and `goal_m` from the base
    (None: unknown), adjusted round the scan `points` ((N, 2), base frame)."""
    need = p.lookahead if goal_m is None else max(0.0, min(p.lookahead, goal_m))
    if vx <= 0.0 or corridor_free(points, bearing, p) >= need:
        return Steer(vx, wz, bearing, "")
    n = int(p.max_offset / p.step)
    cands = sorted((bearing + k * p.step for k in range(-n, n + 1)), key=lambda h: abs(h - bearing))
    free = [(h, corridor_free(points, h, p)) for h in cands]
    ok = [h for h, f in free if f >= need]
    if ok:
        h = ok[0]  # the closest to the goal's bearing
        turn = max(-p.max_angular, min(p.max_angular, p.kp * h))
        return Steer(
            vx * max(0.0, math.cos(h)), turn, h, f"steering {math.degrees(h - bearing):+.0f} deg round an obstacle"
        )
    h, _ = max(free, key=lambda hf: hf[1])
    turn = max(-p.max_angular, min(p.max_angular, p.kp * h))
    return Steer(0.0, turn, h, "no free way within view of the goal: turning")
