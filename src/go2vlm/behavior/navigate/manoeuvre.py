"""The driver's turn: where the footprint has no room to turn in place towards the route, a short
breadth-first search over legs (creep on or back, turning either way or straight, `turn_leg_s` each,
at most `turn_legs` of them) for a pose from which it can turn in place to face the carrot and walk
on towards it, keeping its clearance (the carrot is held where it is: the search is short). Every
leg keeps the clearance rule for its whole length, as the controller's commands do (sweep.py `fits`).

Pure: scan points and the carrot in the base frame in, the first leg of the fewest out. The caller
drives that leg and holds it while it keeps its clearance, up to `turn_leg_s`: chosen afresh at each
step, the moves of a driver's turn swapped as the carrot crossed 90 degrees and the robot rocked on
the spot (160 flips in a corridor).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from go2vlm.behavior.navigate.params import NavParams
from go2vlm.behavior.navigate.sweep import Rect, arc_clearance, fits
from go2vlm.geometry.footprint import Clearance

__all__ = ["Leg", "first_leg"]

_GRID_M, _GRID_RAD = 0.02, math.radians(5)  # poses nearer than this are one


@dataclass(frozen=True)
class Leg:
    """A leg of a driver's turn, held by the caller while it keeps its clearance."""

    vx: float
    wz: float
    until: float  # the caller's time the leg ends
    how: str  # what it is, for the status
    more: bool = False  # the search's plan has legs after this one: the turn goes on with its next


def _moved(x: float, y: float, th: float, vx: float, wz: float, t: float) -> tuple[float, float, float]:
    """The pose after driving (vx, wz) for `t` from (x, y, th)."""
    if abs(wz) > 1e-9:
        r = vx / wz
        return (
            x + r * (math.sin(th + wz * t) - math.sin(th)),
            y - r * (math.cos(th + wz * t) - math.cos(th)),
            th + wz * t,
        )
    return x + vx * t * math.cos(th), y + vx * t * math.sin(th), th


def first_leg(pts: np.ndarray, carrot: tuple[float, float], p: NavParams, fp: Rect, rule: Clearance,
              max_linear: float, max_angular: float) -> tuple[float, float, int] | None:  # fmt: skip
    """The first leg (vx, wz) of the fewest that bring the robot where it can turn to `carrot` (base
    frame), and how many legs that takes; None: no such pose within `turn_legs` legs."""
    creep, back = min(p.min_speed, max_linear), -p.back_up_speed
    rate = min(p.min_turn_rate, max_angular)
    if creep <= 0 or rate <= 0 or p.turn_legs < 1:
        return None
    leg_s, horizon = p.turn_leg_s, max(p.turn_leg_s, p.horizon_s)
    toward = math.copysign(rate, math.atan2(carrot[1], carrot[0]))
    # only what the legs can come near: their reach, the footprint's corner and the widest clearance
    reach = p.turn_legs * leg_s * max(creep, -back) + fp.corner + rule.at(max(creep, -back) + rate * fp.corner) + 0.5
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= reach]
    moves = [(creep, toward), (back, toward), (creep, -toward), (back, -toward), (back, 0.0)]
    ahead = abs(math.atan2(carrot[1], carrot[0])) <= math.pi / 2  # ahead: on straight first (out of a doorway)
    moves = [(creep, 0.0), *moves] if ahead else [*moves, (creep, 0.0)]

    def local(x: float, y: float, th: float) -> np.ndarray:
        c, s = math.cos(th), math.sin(th)
        dx, dy = pts[:, 0] - x, pts[:, 1] - y
        return np.column_stack((c * dx + s * dy, -s * dx + c * dy))

    def can_turn(at: np.ndarray, x: float, y: float, th: float) -> bool:
        """Can it turn in place to face the carrot here, and walk on from there?"""
        cx, cy = carrot[0] - x, carrot[1] - y
        alpha = math.atan2(-math.sin(th) * cx + math.cos(th) * cy, math.cos(th) * cx + math.sin(th) * cy)
        w = math.copysign(rate, alpha)
        here = arc_clearance(at, 0.0, 0.0, 0.0, fp)
        if not (fits(at, 0.0, w, p.horizon_s, fp, rule, here) and fits(at, 0.0, w, abs(alpha) / rate, fp, rule, here)):
            return False
        c, s = math.cos(alpha), math.sin(alpha)
        faced = np.column_stack((c * at[:, 0] + s * at[:, 1], -s * at[:, 0] + c * at[:, 1]))
        return fits(faced, creep, 0.0, p.horizon_s, fp, rule)

    seen = {(0, 0, 0)}
    todo: deque[tuple[float, float, float, int, tuple[float, float]]] = deque([(0.0, 0.0, 0.0, 0, (0.0, 0.0))])
    tried = 0
    while todo and tried < p.turn_search_moves:
        x, y, th, depth, first = todo.popleft()
        at = local(x, y, th)
        here = arc_clearance(at, 0.0, 0.0, 0.0, fp)
        for vx, wz in moves:
            tried += 1
            if not fits(at, vx, wz, horizon, fp, rule, here):
                continue
            nx, ny, nth = _moved(x, y, th, vx, wz, leg_s)
            key = (round(nx / _GRID_M), round(ny / _GRID_M), round(nth / _GRID_RAD))
            if key in seen:
                continue
            seen.add(key)
            lead = first if depth else (vx, wz)
            if can_turn(local(nx, ny, nth), nx, ny, nth):
                return lead[0], lead[1], depth + 1
            if depth + 1 < p.turn_legs:
                todo.append((nx, ny, nth, depth + 1, lead))
    return None
