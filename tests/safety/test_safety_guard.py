"""The collision guard (safety/guard.py), property-tested: whatever the obstacles and the command, the
robot can stop short of every obstacle less the margin; the guard never raises a command; a scan that
is missing, stale or garbage caps the speed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from go2vlm.geometry.footprint import rect_distance
from go2vlm.safety.guard import CollisionGuard, GuardConfig, Scan
from go2vlm.safety.limits import Limits, Velocity

LIMITS = Limits(1.0, 1.0, 1.0, 2.0, 1.0, 3.0)
CFG = GuardConfig()
BINS = 180
INC = 2 * math.pi / BINS


def scan_of(points: list[tuple[float, float]], frame: str = "base_link") -> Scan:
    ranges = np.full(BINS, np.inf)
    for x, y in points:
        i = int(round((math.atan2(y, x) + math.pi) / INC)) % BINS
        ranges[i] = min(ranges[i], math.hypot(x, y))
    return Scan(frame, ranges.tolist(), -math.pi, INC, 0.05, 10.0)


def points_of(scan: Scan) -> np.ndarray:
    r = np.asarray(scan.ranges)
    i = np.nonzero(np.isfinite(r))[0]
    a = scan.angle_min + i * scan.angle_increment
    return np.column_stack([r[i] * np.cos(a), r[i] * np.sin(a)])


def min_clearance_while_stopping(v: Velocity, pts: np.ndarray, reaction: float, limits: Limits) -> np.ndarray:
    """Euler-integrate the robot commanded `v` that keeps going for `reaction` s, then brakes at the
    limits' deceleration (linear and angular together), and return each point's least clearance."""
    lin = math.hypot(v.vx, v.vy)
    t_brake = max(lin / limits.accel_linear, abs(v.wz) / limits.accel_angular)
    dt = 2e-4
    x = y = th = 0.0
    least = rect_distance(pts[:, 0], pts[:, 1], CFG.half_length, CFG.half_width)
    t = 0.0
    while True:
        f = 1.0 if t < reaction else 1.0 - (t - reaction) / t_brake if t_brake > 0 else 0.0
        if f <= 0:
            break
        c, s = math.cos(th), math.sin(th)
        x += (c * v.vx - s * v.vy) * f * dt
        y += (s * v.vx + c * v.vy) * f * dt
        th += v.wz * f * dt
        t += dt
        dx, dy = pts[:, 0] - x, pts[:, 1] - y
        lx, ly = math.cos(th) * dx + math.sin(th) * dy, -math.sin(th) * dx + math.cos(th) * dy
        least = np.minimum(least, rect_distance(lx, ly, CFG.half_length, CFG.half_width))
    return least


coord = st.floats(-3.0, 3.0, allow_nan=False)
obstacles = st.lists(st.tuples(coord, coord), min_size=1, max_size=12)
speeds = st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-2.0, 2.0))


@settings(max_examples=150, deadline=None)
@given(obstacles, speeds, st.floats(0.0, 0.3))
def test_never_a_command_that_cannot_stop_short_of_the_margin(
    obs: list[tuple[float, float]], vel: tuple[float, float, float], age: float
) -> None:
    scan = scan_of(obs)
    pts = points_of(scan)
    d0 = rect_distance(pts[:, 0], pts[:, 1], CFG.half_length, CFG.half_width)
    assume((d0 > 0.02).all())  # a point inside the robot is its own leg, not a case here
    guard = CollisionGuard(CFG)
    guard.scan(scan, 10.0)
    v = Velocity(*vel)
    out = guard.limit(v, 10.0 + age, LIMITS)
    if out.is_zero:
        return
    least = min_clearance_while_stopping(out, pts, CFG.reaction_s + age, LIMITS)
    # The documented guarantee: never closer than the margin, or than the robot already is, less one step.
    assert least.min() >= min(CFG.margin, d0.min()) - CFG.step - 2e-3, (out, guard.state)


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.none(), obstacles), speeds, st.floats(0.0, 2.0))
def test_never_raises_and_keeps_the_direction(
    obs: list[tuple[float, float]] | None, vel: tuple[float, float, float], age: float
) -> None:
    guard = CollisionGuard(CFG)
    if obs is not None:
        guard.scan(scan_of(obs), 0.0)
    v = Velocity(*vel)
    out = guard.limit(v, age, LIMITS)
    scale = guard.state.scale
    assert 0.0 <= scale <= 1.0
    for a, b in ((out.vx, v.vx), (out.vy, v.vy), (out.wz, v.wz)):
        assert abs(a) <= abs(b) + 1e-12 and a * b >= 0.0
        assert out.is_zero or a == pytest.approx(b * scale, abs=1e-9)


@pytest.mark.parametrize(
    "bad",
    [
        Scan("base_link", [float("nan")] * BINS, -math.pi, INC, 0.05, 10.0),
        Scan("base_link", [1.0] * (BINS - 1) + [float("-inf")], -math.pi, INC, 0.05, 10.0),
        Scan("base_link", [-1.0] * BINS, -math.pi, INC, 0.05, 10.0),
        Scan("base_link", [], -math.pi, INC, 0.05, 10.0),
        Scan("base_link", [5.0] * BINS, -math.pi, float("inf"), 0.05, 10.0),
        Scan("base_link", [5.0] * BINS, float("nan"), INC, 0.05, 10.0),
        Scan("base_link", [5.0] * BINS, -math.pi, INC, 0.05, float("nan")),
        Scan("odom", [5.0] * BINS, -math.pi, INC, 0.05, 10.0),
        Scan("utlidar_lidar", [5.0] * BINS, -math.pi, INC, 0.05, 10.0),
    ],
)
def test_garbage_scans_cap_the_speed(bad: Scan) -> None:
    guard = CollisionGuard(CFG)
    guard.scan(scan_of([(5.0, 5.0)]), 0.0)
    assert guard.limit(Velocity(1.0), 0.0, LIMITS) == Velocity(1.0)  # a good scan, nothing in the way
    assert guard.scan(bad, 0.1) is not None
    out = guard.limit(Velocity(1.0, 0.0, 1.0), 0.1, LIMITS)
    assert guard.state.mode == "blind" and "rejected" in guard.state.reason
    assert math.hypot(out.vx, out.vy) + abs(out.wz) * CFG.corner <= CFG.blind_speed + 1e-9


def test_no_scan_and_stale_scan_cap_the_speed() -> None:
    guard = CollisionGuard(CFG)
    out = guard.limit(Velocity(0.5), 0.0, LIMITS)
    assert out.vx == pytest.approx(CFG.blind_speed) and guard.state.reason.endswith("no scan yet")
    guard.scan(scan_of([(8.0, 0.0)]), 1.0)
    assert guard.limit(Velocity(0.5), 1.2, LIMITS) == Velocity(0.5)
    out = guard.limit(Velocity(0.5), 1.0 + CFG.scan_timeout_s + 0.01, LIMITS)
    assert out.vx == pytest.approx(CFG.blind_speed) and guard.state.mode == "blind"
    assert guard.limit(Velocity(0.1), 5.0, LIMITS) == Velocity(0.1)  # under the cap: as it is


def test_wall_ahead_slows_then_stops_at_the_margin() -> None:
    guard = CollisionGuard(CFG)
    wall = [(x, y) for x in (2.0,) for y in np.linspace(-2, 2, 81)]
    guard.scan(scan_of(wall), 0.0)
    assert guard.limit(Velocity(0.5), 0.0, LIMITS) == Velocity(0.5)  # 1.65 m ahead: room to stop
    near = [(CFG.half_length + CFG.margin + 0.05, y) for y in np.linspace(-1, 1, 41)]
    guard.scan(scan_of(near), 0.0)
    out = guard.limit(Velocity(0.5), 0.0, LIMITS)
    assert 0.0 <= out.vx < 0.5 and guard.state.mode == "limited"
    at = [(CFG.half_length + CFG.margin - 0.01, y) for y in np.linspace(-1, 1, 41)]
    guard.scan(scan_of(at), 0.0)
    assert guard.limit(Velocity(0.5), 0.0, LIMITS).is_zero
    assert guard.limit(Velocity(-0.5), 0.0, LIMITS) == Velocity(-0.5)  # backing away is free
    guard.scan(scan_of([(0.0, CFG.half_width + CFG.margin / 2)]), 0.0)  # a post beside, inside the margin
    assert guard.limit(Velocity(0.5), 0.0, LIMITS) == Velocity(0.5)  # driving past it: never closer
    assert guard.limit(Velocity(0.0, 0.3), 0.0, LIMITS).is_zero  # towards it: no


def test_turning_in_place_sweeps_the_corners() -> None:
    guard = CollisionGuard(CFG)
    # A post just off the front-left corner: outside the footprint (and its margin standing), but
    # inside its turning circle.
    guard.scan(scan_of([(CFG.half_length + 0.01, CFG.half_width + CFG.margin + 0.01)]), 0.0)
    assert guard.limit(Velocity(0.0, 0.0, 1.0), 0.0, LIMITS).is_zero  # turning left swings into it
    guard.scan(scan_of([(0.0, CFG.half_width + 0.5)]), 0.0)  # beside the middle: the turn is free
    assert guard.limit(Velocity(0.0, 0.0, 1.0), 0.0, LIMITS) == Velocity(0.0, 0.0, 1.0)


def test_disabled_guard_passes_everything() -> None:
    guard = CollisionGuard(CFG, enabled=False)
    assert guard.limit(Velocity(2.0, 0.5, 1.0), 0.0, LIMITS) == Velocity(2.0, 0.5, 1.0)
    assert guard.state.mode == "off"
