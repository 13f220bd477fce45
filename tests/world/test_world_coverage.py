"""Where the camera has looked (world/coverage.py): the view stops at walls, sees into what the lidar
did not map, and the unseen free space is what is left."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.robot_profile.go2 import HEAD_CAMERA_FOVY_DEG
from go2vlm.world.coverage import Coverage, CoverageParams
from go2vlm.world.placement import CameraMount

RES = 0.05
ORIGIN = (-5.0, -5.0)


def room(wall_x: float | None = None) -> np.ndarray:
    """A 10 x 10 m free costmap round the origin, with a wall across it at x = wall_x."""
    g = np.zeros((200, 200), dtype=np.int8)
    if wall_x is not None:
        c = int((wall_x - ORIGIN[0]) / RES)
        g[:, c : c + 2] = 100
    return g


def test_a_frame_looks_within_its_view_and_range_and_not_through_a_wall() -> None:
    cov = Coverage(CoverageParams(range_m=4.0))
    g = room(wall_x=2.0)
    new = cov.observe(g, RES, ORIGIN, 0.0, 0.0, 0.0, math.radians(60))
    looked = cov.looked_on(g.shape, RES, ORIGIN)
    assert new > 0 and cov.frames == 1

    def at(x: float, y: float) -> bool:
        return bool(looked[int((y - ORIGIN[1]) / RES), int((x - ORIGIN[0]) / RES)])

    assert at(1.5, 0.0) and at(1.0, 0.4)  # ahead, within the view
    assert not at(-1.0, 0.0) and not at(0.5, 1.5)  # behind, and outside the 60 degrees
    assert not at(3.0, 0.0)  # past the wall
    unseen = cov.unlooked(g, RES, ORIGIN, lethal=99)
    assert unseen[int((0 - ORIGIN[1]) / RES), int((-1.0 - ORIGIN[0]) / RES)]
    assert not unseen[int((0 - ORIGIN[1]) / RES), int((1.5 - ORIGIN[0]) / RES)]


def test_a_frame_does_not_look_at_the_floor_below_its_lower_edge() -> None:
    """A Go2's head camera, level and 0.36 m up with a 58 degree vertical view, sees the floor from
    0.65 m ahead of itself (0.98 m from the base centre): a small thing nearer is below the picture, so
    the cells there are not looked at, however long the robot stands there turning."""
    p = CoverageParams()
    mount = CameraMount()
    assert p.near_m == mount.floor_seen_from(math.radians(HEAD_CAMERA_FOVY_DEG))
    lowest = math.radians(HEAD_CAMERA_FOVY_DEG) / 2  # the lower edge's angle below the horizon
    assert math.isclose(math.tan(lowest) * (p.near_m - mount.forward_m), mount.height_m)
    cov, g = Coverage(p), room()
    for yaw in np.linspace(-math.pi, math.pi, 24, endpoint=False):
        cov.observe(g, RES, ORIGIN, 0.0, 0.0, float(yaw), math.radians(90))
    assert not cov.looked_at(0.5, 0.0) and not cov.looked_at(0.0, -0.7)
    assert cov.looked_at(1.5, 0.0) and cov.looked_at(0.0, -1.5)


def test_the_view_sees_into_the_unknown_and_a_new_goal_forgets_it() -> None:
    cov = Coverage(CoverageParams(range_m=3.0))
    g = np.full((200, 200), -1, dtype=np.int8)  # nothing mapped
    cov.observe(g, RES, ORIGIN, 0.0, 0.0, math.pi / 2, math.radians(60))
    assert cov.looked_on(g.shape, RES, ORIGIN)[int((2.0 - ORIGIN[1]) / RES), int((0 - ORIGIN[0]) / RES)]
    assert not cov.unlooked(g, RES, ORIGIN, lethal=99).any()  # unknown cells are no place to stand
    cov.reset()
    assert not cov.looked.any() and cov.frames == 0


@settings(max_examples=60, deadline=None)
@given(x=st.floats(-3, 3), y=st.floats(-3, 3), yaw=st.floats(-math.pi, math.pi), view=st.floats(0.2, 2.0))
def test_a_frame_looks_only_within_range_and_view(x: float, y: float, yaw: float, view: float) -> None:
    p = CoverageParams(range_m=3.0)
    cov = Coverage(p)
    g = room()
    cov.observe(g, RES, ORIGIN, x, y, yaw, view)
    rows, cols = np.nonzero(cov.looked_on(g.shape, RES, ORIGIN))
    px, py = ORIGIN[0] + (cols + 0.5) * RES, ORIGIN[1] + (rows + 0.5) * RES
    slack = p.cell_m * math.sqrt(2) + RES  # a lattice cell is larger than a costmap cell
    assert (np.hypot(px - x, py - y) <= p.range_m + slack).all()
    far = np.hypot(px - x, py - y) > 0.5
    off = np.abs(np.angle(np.exp(1j * (np.arctan2(py - y, px - x) - yaw))))
    assert (off[far] <= view / 2 + math.atan2(slack, 0.5)).all()


def test_bad_frames_look_at_nothing() -> None:
    cov = Coverage()
    g = room()
    assert cov.observe(g, RES, ORIGIN, math.nan, 0.0, 0.0, 1.0) == 0
    assert cov.observe(g, RES, ORIGIN, 0.0, 0.0, 0.0, 0.0) == 0
    assert not cov.looked.any()


def test_what_a_look_could_still_see_stops_at_walls_and_says_which_way_to_turn() -> None:
    """From (0, 0) facing +x with a wall at x = 1: the unseen space behind the wall does not count; the
    room behind the robot does, and once it has turned left through +y to face -x, what is left (y < 0)
    lies on its left: turning on is the short way."""
    cov = Coverage(CoverageParams(range_m=3.0))
    g = room(wall_x=1.0)
    view = math.radians(60)
    area, left, right = cov.unseen_visible(g, RES, ORIGIN, 99, 0.0, 0.0, 0.0, view)
    assert 10.0 < area < math.pi * 9  # about the 3 m half disc behind and beside it, not past the wall
    assert abs(left - right) < math.radians(3) and left > math.pi  # all round: either way is as long
    for yaw in np.arange(0.0, math.pi + 0.01, math.radians(10)):  # turn left to face -x: the left half looked at
        cov.observe(g, RES, ORIGIN, 0.0, 0.0, yaw, view)
    area2, left2, right2 = cov.unseen_visible(g, RES, ORIGIN, 99, 0.0, 0.0, math.pi, view)
    assert 0.0 < area2 < area and left2 < right2, (area2, left2, right2)
    for yaw in np.arange(math.pi, 2 * math.pi + 0.01, math.radians(10)):
        cov.observe(g, RES, ORIGIN, 0.0, 0.0, yaw, view)
    assert cov.unseen_visible(g, RES, ORIGIN, 99, 0.0, 0.0, 0.0, view) == (0.0, 0.0, 0.0)
    behind_wall = cov.unlooked(g, RES, ORIGIN, lethal=99)[int((0 - ORIGIN[1]) / RES), int((2.0 - ORIGIN[0]) / RES)]
    assert behind_wall  # unseen, but no look from here would see it
