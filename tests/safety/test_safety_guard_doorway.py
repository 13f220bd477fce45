"""The collision guard and the clearance rule at a narrow door: the margin grows with speed (a few
centimetres at a creep), so a Go2 creeping square-on through a 0.8 m doorway is let through, and the
same creep towards a closed door stops before it touches. The robot is walked through the scans a
lidar at its pose would give (one point every 1 cm of wall), each command integrated for one tick."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from go2vlm.geometry.footprint import Clearance, rect_distance
from go2vlm.safety.guard import CollisionGuard, GuardConfig, Scan
from go2vlm.safety.limits import Limits, Velocity

LIMITS = Limits()
CFG = GuardConfig()
BINS = 720
INC = 2 * math.pi / BINS
DT = 0.1  # s: one gate tick
CREEP = Clearance().creep_mps


def doorway(door: float, closed: bool = False) -> np.ndarray:
    """World points of a 0.1 m wall across x = 0 (|y| <= 3 m) with a doorway `door` m clear round y = 0
    (or shut by a leaf in the wall's plane)."""
    ys = np.arange(-3.0, 3.0, 0.01)
    pts = [np.column_stack([np.full(len(ys), x), ys]) for x in (-0.05, 0.05)]
    pts = [p[(np.abs(p[:, 1]) >= door / 2) | closed] for p in pts]
    jamb = np.arange(-0.05, 0.05, 0.01)
    pts += [np.column_stack([jamb, np.full(len(jamb), s * door / 2)]) for s in (-1, 1)]
    return np.vstack(pts)


def scan_at(world: np.ndarray, x: float, y: float, yaw: float) -> Scan:
    """The scan of `world` from the pose (nearest return per bin, base frame)."""
    dx, dy = world[:, 0] - x, world[:, 1] - y
    c, s = math.cos(yaw), math.sin(yaw)
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    ranges = np.full(BINS, np.inf)
    i = np.round((np.arctan2(ly, lx) + math.pi) / INC).astype(int) % BINS
    np.minimum.at(ranges, i, np.hypot(lx, ly))
    return Scan("base_link", ranges.tolist(), -math.pi, INC, 0.05, 10.0)


def gap(world: np.ndarray, x: float, y: float, yaw: float) -> float:
    dx, dy = world[:, 0] - x, world[:, 1] - y
    c, s = math.cos(yaw), math.sin(yaw)
    return float(rect_distance(c * dx + s * dy, -s * dx + c * dy, CFG.half_length, CFG.half_width).min())


def walk(world: np.ndarray, y: float, ticks: int) -> tuple[float, float, list[float]]:
    """Creep along +x from x = -1.2 at lateral offset `y`: (x reached, least gap, speeds let through)."""
    guard = CollisionGuard(CFG)
    x, least, speeds = -1.2, math.inf, []
    for k in range(ticks):
        t = k * DT
        guard.scan(scan_at(world, x, y, 0.0), t)
        out = guard.limit(Velocity(CREEP), t, LIMITS)
        speeds.append(out.vx)
        x += out.vx * DT
        least = min(least, gap(world, x, y, 0.0))
    return x, least, speeds


def test_the_clearance_grows_with_speed() -> None:
    rule = Clearance()
    speeds = np.linspace(0.0, 1.5, 31)
    gaps = [rule.at(v) for v in speeds]
    assert (np.diff(gaps) >= 0).all() and gaps[0] == rule.creep_m
    assert rule.at(0.5) == rule.creep_m + rule.per_speed_s * 0.5
    assert all(rule.at(rule.speed_for(g)) <= g + 1e-12 for g in (0.1, 0.2, 0.245, 0.4))
    assert rule.speed_for(rule.creep_m * 0.9) == 0.0  # less than a standing gap: not even a creep


@given(creep=st.floats(0.0, 0.3), per=st.floats(0.0, 1.0), a=st.floats(0.0, 2.0), b=st.floats(0.0, 2.0))
def test_the_clearance_is_monotonic_in_speed(creep: float, per: float, a: float, b: float) -> None:
    rule = Clearance(creep_m=creep, per_speed_s=per)
    lo, hi = sorted((a, b))
    assert rule.creep_m <= rule.at(lo) <= rule.at(hi)
    assert rule.at(-hi) == rule.at(hi)  # backwards as fast is as far


def test_a_creep_passes_a_narrow_doorway_square_on() -> None:
    world = doorway(0.8)
    for y in (0.0, 0.08):  # centred, and 8 cm off the middle
        x, least, speeds = walk(world, y, 160)
        assert x > 0.9, f"held in the doorway at x = {x:.2f} (offset {y})"
        assert least > 0.0 and min(speeds) >= 0.5 * CREEP, speeds


def test_a_creep_stops_short_of_a_shut_door() -> None:
    world = doorway(0.8, closed=True)
    x, least, speeds = walk(world, 0.0, 160)
    assert speeds[-1] < 0.01, "still walking towards the door"
    assert least >= CFG.margin - 0.02, f"came within {least:.3f} m: the creep's margin is {CFG.margin} m"
