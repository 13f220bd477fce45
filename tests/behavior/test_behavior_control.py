"""The behaviours' control laws (behavior/control.py): the approach turns first, walks, stops at the
distance and never walks blind; align, face and search turn the right way; none ever goes backwards
or past its limits."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from go2vlm.behavior.control import (
    CENTRED_X,
    MAX_ALIGN_WZ,
    MIN_ALIGN_WZ,
    align_command,
    approach_command,
    face_command,
    search_command,
)
from go2vlm.behavior.mission import MissionParams

P = MissionParams(max_linear=0.4, max_angular=0.8).approach(0.8)


def test_approach_command_turns_first_then_walks_and_stops_at_the_distance() -> None:
    vx, wz, done = approach_command(0.8, 3.0, P)
    assert vx == 0.0 and wz < 0 and not done  # target on the right: turn right, do not walk yet
    vx, wz, done = approach_command(0.0, 3.0, P)
    assert vx == pytest.approx(0.4) and wz == 0.0 and not done
    assert approach_command(0.0, 0.84, P) == (0.0, 0.0, True)
    vx, _, _ = approach_command(0.0, None, P)
    assert vx == 0.0  # unknown distance: never walk blind


def test_align_face_and_search_turn_towards_the_target() -> None:
    assert align_command(0.05, P) == (0.0, True)  # centred
    wz, centred = align_command(0.12, P)
    assert not centred and -0.8 <= wz <= -MIN_ALIGN_WZ  # on the right: turn right, not too gently
    assert align_command(-1.0, P) == (MAX_ALIGN_WZ, False)  # far left: the ceiling (a small far object stays tracked)
    assert face_command(0.3, P) == pytest.approx(0.45) and face_command(-0.01, P) == -MIN_ALIGN_WZ
    assert search_command(0.5, 0.5, 0.8) == -0.5 and search_command(-0.5, 0.5, 0.3) == 0.3
    assert search_command(0.0, 0.5, 0.8) == 0.5  # never seen: left


@given(
    x=st.floats(-3, 3),
    d=st.none() | st.floats(0, 20),
    bearing=st.floats(-math.pi, math.pi),
    max_linear=st.floats(0, 1),
    max_angular=st.floats(0, 2),
)
def test_no_law_goes_backwards_or_past_its_limits(
    x: float, d: float | None, bearing: float, max_linear: float, max_angular: float
) -> None:
    p = MissionParams(max_linear=max_linear, max_angular=max_angular).approach(0.8)
    vx, wz, _ = approach_command(x, d, p)
    assert 0.0 <= vx <= max_linear and abs(wz) <= max_angular
    wz, centred = align_command(x, p)
    assert abs(wz) <= max_angular and centred == (abs(x) < CENTRED_X)
    assert wz * x <= 0  # towards the centre
    assert face_command(bearing, p) * bearing >= 0
