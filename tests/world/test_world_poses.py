"""The pose history answers "where was the robot at stamp t?" (world/poses.py)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.world.poses import Pose2D, PoseHistory, PoseUnavailable, wrap_angle

finite = st.floats(-50, 50, allow_nan=False)


@given(x0=finite, y0=finite, vx=st.floats(-2, 2), vy=st.floats(-2, 2), yaw0=st.floats(-10, 10),
       wz=st.floats(-3, 3), t=st.floats(0.0, 9.98))  # fmt: skip
def test_interpolates_steady_motion_exactly(x0, y0, vx, vy, yaw0, wz, t) -> None:
    h = PoseHistory(horizon_s=30.0)
    for k in range(501):  # 50 Hz for 10 s: yaw steps of at most 0.06 rad
        tk = k * 0.02
        h.add(tk, x0 + vx * tk, y0 + vy * tk, yaw0 + wz * tk)
    p = h.at(t)
    assert p.x == pytest.approx(x0 + vx * t, abs=1e-6)
    assert p.y == pytest.approx(y0 + vy * t, abs=1e-6)
    assert abs(wrap_angle(p.yaw - (yaw0 + wz * t))) < 1e-6


def test_yaw_interpolates_the_short_way_round() -> None:
    h = PoseHistory()
    h.add(0.0, 0, 0, math.pi - 0.1)
    h.add(1.0, 0, 0, -math.pi + 0.1)
    assert abs(wrap_angle(h.at(0.5).yaw - math.pi)) < 1e-9


def test_refusals_say_why() -> None:
    h = PoseHistory(horizon_s=5.0, max_gap_s=0.5)
    with pytest.raises(PoseUnavailable) as e:
        h.at(1.0)
    assert e.value.reason == "no_pose"
    for k in range(0, 100):
        h.add(k * 0.1, k * 0.1, 0.0, 0.0)
    with pytest.raises(PoseUnavailable) as e:
        h.at(4.0)  # newest 9.9, horizon 5 s
    assert e.value.reason == "older_than_history"
    with pytest.raises(PoseUnavailable) as e:
        h.at(10.5)
    assert e.value.reason == "newer_than_pose"
    assert h.at(9.9 + h.max_extrapolation_s / 2).x == pytest.approx(9.9)
    h.add(12.0, 0.0, 0.0, 0.0)  # a gap of 2.1 s
    with pytest.raises(PoseUnavailable) as e:
        h.at(11.0)
    assert e.value.reason == "pose_gap"


def test_bad_and_out_of_order_samples_are_dropped_and_counted() -> None:
    h = PoseHistory()
    assert h.add(1.0, 0, 0, 0)
    assert not h.add(0.5, 1, 1, 1)
    assert not h.add(2.0, math.nan, 0, 0)
    assert h.counters == {"out_of_order": 1, "bad_poses": 1}
    assert h.at(1.0) == Pose2D(0.0, 0.0, 0.0)


def test_a_restarted_clock_starts_again() -> None:
    h = PoseHistory(horizon_s=10.0)
    h.add(100.0, 5, 5, 0)
    h.add(1.0, 1, 1, 0)  # the sim started again
    assert h.counters["restarts"] == 1 and h.at(1.0).x == 1.0


@settings(max_examples=20, deadline=None)
@given(rate=st.sampled_from([10.0, 50.0, 1000.0]), seconds=st.integers(1, 120))
def test_bounded_whatever_the_rate(rate: float, seconds: int) -> None:
    h = PoseHistory(horizon_s=5.0, max_samples=2000)
    n = int(rate * seconds)
    for k in range(n):
        h.add(k / rate, 0.0, 0.0, 0.0)
    assert len(h) <= min(2000, 5.0 * rate + 258) + 1
