"""The approach's local planner (behavior/planner.py): a free way passes the command unchanged; a box
in the way turns the robot to a free heading within view of the goal; it never speeds anything up."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.behavior.planner import PlannerParams, corridor_free, steer

P = PlannerParams()


def box(cx: float, cy: float, hx: float, hy: float) -> np.ndarray:
    xs, ys = np.linspace(cx - hx, cx + hx, 11), np.linspace(cy - hy, cy + hy, 11)
    return np.array([[x, y] for x in xs for y in (cy - hy, cy + hy)] + [[x, y] for y in ys for x in (cx - hx, cx + hx)])


def test_free_way_passes_unchanged() -> None:
    s = steer(0.4, 0.1, 0.0, 3.0, box(0.0, 3.0, 0.3, 0.3), P)
    assert (s.vx, s.wz, s.note) == (0.4, 0.1, "")


def test_box_in_the_way_steers_round_it_within_view() -> None:
    pts = box(1.6, 0.05, 0.2, 0.2)
    assert corridor_free(pts, 0.0, P) < 1.0
    s = steer(0.4, 0.0, 0.0, 3.0, pts, P)
    assert s.note and abs(s.heading) <= P.max_offset + 1e-9 and s.heading != 0.0
    assert corridor_free(pts, s.heading, P) >= P.lookahead
    assert 0.0 < s.vx < 0.4 and s.wz * s.heading > 0  # slower, turning towards the free heading


def test_goal_closer_than_the_obstacle_is_not_steered() -> None:
    s = steer(0.3, 0.0, 0.0, 0.5, box(2.0, 0.0, 0.3, 0.3), P)
    assert s.note == ""


def test_wall_across_turns_in_place() -> None:
    wall = np.array([[1.0, y] for y in np.linspace(-3, 3, 61)])
    s = steer(0.4, 0.0, 0.0, 3.0, wall, P)
    assert s.vx == 0.0 and "no free way" in s.note


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3)), max_size=20),
    st.floats(0.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(-0.6, 0.6),
)
def test_never_faster_and_heading_near_the_goal(pts: list, vx: float, wz: float, bearing: float) -> None:
    s = steer(vx, wz, bearing, 3.0, np.array(pts).reshape(-1, 2), P)
    assert 0.0 <= s.vx <= vx
    assert abs(s.wz) <= max(abs(wz), P.max_angular)
    assert abs(s.heading - bearing) <= P.max_offset + 1e-9
    assert math.isfinite(s.wz)
