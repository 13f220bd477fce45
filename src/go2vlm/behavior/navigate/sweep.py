"""The footprint swept along a command's arc: the one check of the navigator's controller, its
driver's turn and its recoveries. Pure."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from go2vlm.geometry.footprint import Clearance, rect_distance
from go2vlm.robot_profile.go2 import FOOTPRINT_LENGTH, FOOTPRINT_WIDTH

__all__ = ["Rect", "arc_clearance", "fits"]

ARC_SAMPLES = 12  # poses checked along a command's arc


@dataclass(frozen=True)
class Rect:
    """The robot's rectangle (half sizes, m) about its base centre."""

    half_length: float = FOOTPRINT_LENGTH / 2
    half_width: float = FOOTPRINT_WIDTH / 2

    @property
    def corner(self) -> float:
        return math.hypot(self.half_length, self.half_width)

    def need(self, rule: Clearance, vx: float, wz: float) -> float:
        """The gap (m) a command (vx, wz) keeps: the rule at the footprint's fastest point."""
        return rule.at(abs(vx) + abs(wz) * self.corner)


def arc_clearance(scan: np.ndarray, vx: float, wz: float, duration: float, fp: Rect) -> float:
    """The least clearance (m) of the footprint to the scan points (base frame) along the arc that
    (vx, wz) drives for `duration`, its start included."""
    if len(scan) == 0:
        return math.inf
    reach = abs(vx) * duration + fp.corner + 1.0
    pts = scan[np.hypot(scan[:, 0], scan[:, 1]) <= reach]
    if len(pts) == 0:
        return math.inf
    t = np.linspace(0.0, duration, ARC_SAMPLES if duration > 0 else 1)[:, None]  # all poses at once
    th = wz * t
    if abs(wz) > 1e-6:
        px, py = vx / wz * np.sin(th), vx / wz * (1.0 - np.cos(th))
    else:
        px, py = vx * t, np.zeros_like(t)
    c, s = np.cos(th), np.sin(th)
    dx, dy = pts[None, :, 0] - px, pts[None, :, 1] - py
    return float(rect_distance(c * dx + s * dy, -s * dx + c * dy, fp.half_length, fp.half_width).min())


def fits(pts: np.ndarray, vx: float, wz: float, duration: float, fp: Rect, rule: Clearance,
         here: float | None = None) -> bool:  # fmt: skip
    """Does the arc (vx, wz) for `duration` keep the clearance its speed needs (`rule` at the
    footprint's fastest point), or, where the footprint is nearer than that already (inside a
    doorway), bring it no nearer? `pts`: obstacles in the base frame; `here`: the footprint's
    clearance where it stands, when the caller has it (a step checks several arcs from one pose)."""
    if here is None:
        here = arc_clearance(pts, 0.0, 0.0, 0.0, fp)
    return arc_clearance(pts, vx, wz, duration, fp) >= min(fp.need(rule, vx, wz), here) - 1e-3
