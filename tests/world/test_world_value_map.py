"""VLFM's value map (world/value_map.py): a scored view lies over what the camera could see, inside
its cone and short of the first wall; views blend by confidence, strongest on the optical axis; a
place no view covered is `unscored`; bad input places nothing."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.behavior.planner.grid import Costmap
from go2vlm.world.value_map import ValueMap

VIEW = math.radians(73)


def wall_at_x(x: float) -> Costmap:
    """Free space 20 x 20 m round the origin with a wall across it at `x`."""
    g = np.zeros((400, 400), np.int8)
    g[:, int(round((x + 10.0) / 0.05))] = 100
    return Costmap(g, 0.05, (-10.0, -10.0))


@settings(max_examples=60, deadline=None)
@given(yaw=st.floats(-math.pi, math.pi), r=st.floats(0.5, 7.0), off=st.floats(-1.5, 1.5),
       score=st.sampled_from([0.0, 0.5, 1.0]))  # fmt: skip
def test_a_view_covers_its_cone_and_nothing_behind_the_robot(yaw: float, r: float, off: float, score: float) -> None:
    v = ValueMap()
    v.observe(0.0, 0.0, yaw, VIEW, score, None)
    x, y = r * math.cos(yaw + off), r * math.sin(yaw + off)
    if abs(off) < VIEW / 2 - 0.25 and r < v.range_m - v.radius_m:
        assert v.at(x, y) == score
    if abs(off) > VIEW / 2 + 0.5 and r > 2.0:
        assert v.at(x, y) == v.unscored
    assert v.at(-3.0 * math.cos(yaw), -3.0 * math.sin(yaw)) == v.unscored  # behind


def test_a_wall_stops_the_view() -> None:
    v = ValueMap()
    assert v.observe(0.0, 0.0, 0.0, VIEW, 1.0, wall_at_x(2.0)) > 0
    assert v.at(1.2, 0.0) == 1.0
    assert v.at(3.5, 0.0) == v.unscored  # behind the wall: the view says nothing of it
    v.observe(0.0, 0.0, 0.0, VIEW, 1.0, None)  # no map: the whole cone
    assert v.at(3.5, 0.0) == 1.0


def test_views_blend_by_confidence_and_the_axis_outweighs_the_edge() -> None:
    v = ValueMap()
    v.observe(0.0, 0.0, 0.0, VIEW, 1.0, None)  # (4, 0) on its axis: likely
    v.observe(0.0, 0.0, VIEW / 2 - 0.15, VIEW, 0.0, None)  # (4, 0) near this one's edge: unlikely
    assert 0.75 < v.at(4.0, 0.0) < 1.0
    again = ValueMap()
    again.observe(0.0, 0.0, 0.0, VIEW, 0.0, None)
    again.observe(0.0, 0.0, 0.0, VIEW, 1.0, None)  # the same view, the opposite answer: halfway
    assert again.at(4.0, 0.0) == 0.5


def test_bad_input_places_nothing() -> None:
    v = ValueMap()
    for args in [(math.nan, 0.0, 0.0, VIEW, 1.0), (0.0, 0.0, math.inf, VIEW, 1.0), (0.0, 0.0, 0.0, 0.0, 1.0),
                 (0.0, 0.0, 0.0, VIEW, 1.5), (0.0, 0.0, 0.0, VIEW, -0.1)]:  # fmt: skip
        assert v.observe(*args, None) == 0
    assert not v.cells and v.views == 0
