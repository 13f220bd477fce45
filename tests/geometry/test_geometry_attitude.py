"""The body's pitch at a frame's stamp (geometry/attitude.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.geometry.attitude import PitchHistory
from go2vlm.geometry.rotations import quat_mul, quat_pitch, quat_yaw, yaw_quat


@settings(max_examples=50, deadline=None)
@given(pitches=st.lists(st.floats(-0.3, 0.3), min_size=1, max_size=40), t=st.floats(-1.0, 50.0))
def test_the_pitch_at_a_stamp_is_the_nearest_samples(pitches: list[float], t: float) -> None:
    h = PitchHistory(horizon_s=1000.0)
    assert h.at(t) == 0.0  # none yet: level
    for k, p in enumerate(pitches):
        assert h.add(float(k), p)
    k = min(max(round(t), 0), len(pitches) - 1)
    assert h.at(t) == pitches[k] or abs(t - round(t)) == pytest.approx(0.5)


def test_bad_old_and_restarted_samples() -> None:
    h = PitchHistory(horizon_s=5.0)
    assert h.add(10.0, 0.01) and not h.add(11.0, math.nan) and not h.add(9.0, 0.02)
    for k in range(11, 30):
        h.add(float(k), 0.02)
    assert len(h._t) <= 6  # within the horizon
    assert h.add(1.0, -0.05) and h.at(1.0) == -0.05  # the clock started again


def test_quat_pitch_is_nose_down_positive() -> None:
    a = math.radians(0.8)
    assert quat_pitch(math.cos(a / 2), 0.0, math.sin(a / 2), 0.0) == pytest.approx(a)


@settings(max_examples=50, deadline=None)
@given(yaw=st.floats(-3.0, 3.0), pitch=st.floats(-0.2, 0.2), turn=st.floats(-3.0, 3.0))
def test_a_yaw_correction_keeps_the_pitch(yaw: float, pitch: float, turn: float) -> None:
    """/map/odom turns /odom's orientation by the map's yaw correction: its pitch (the camera's, for
    the object memory's ranging) is kept, its yaw moved by the correction."""
    q = quat_mul(yaw_quat(yaw), np.array([math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0]))
    out = quat_mul(yaw_quat(turn), q)
    assert quat_pitch(*out) == pytest.approx(pitch, abs=1e-9)
    assert math.remainder(quat_yaw(*out) - yaw - turn, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
