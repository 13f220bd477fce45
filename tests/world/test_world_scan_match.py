"""Scan matching against the map (world/scan_match.py): a scan finds its true pose from a guess that is
off, never leaps past its search window, keeps the guess where the map knows nothing, and a walk on
drifting odometry stays on the truth. The pose algebra and the odometry jump test it rests on
(world/poses.py)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from maputil import ROOM, room_scan

from go2vlm.world.occupancy import OccupancyMap
from go2vlm.world.poses import IDENTITY, Pose2D, odometry_jump, wrap_angle
from go2vlm.world.scan_match import Corrector, LikelihoodField, MatchParams, fit, match

PARAMS = MatchParams()


def room_map() -> OccupancyMap:
    grid = OccupancyMap()
    for p in (Pose2D(0, 0, 0), Pose2D(1.5, 1.0, 1.0), Pose2D(-1.5, -1.0, 2.0), Pose2D(2.0, -1.5, -2.0)):
        grid.integrate(room_scan(p), p)
    return grid


GRID = room_map()
inside = st.builds(
    Pose2D,
    st.floats(-ROOM[0] + 1.0, ROOM[0] - 1.0),
    st.floats(-ROOM[1] + 1.0, ROOM[1] - 1.0),
    st.floats(-math.pi, math.pi),
)
small = st.tuples(st.floats(-0.08, 0.08), st.floats(-0.08, 0.08), st.floats(-0.04, 0.04))


@settings(max_examples=40, deadline=None)
@given(truth=inside, off=small)
def test_a_scan_finds_its_pose_from_a_guess_that_is_off(truth: Pose2D, off: tuple[float, float, float]) -> None:
    guess = Pose2D(truth.x + off[0], truth.y + off[1], truth.yaw + off[2])
    points = room_scan(truth).returns()
    m = match(LikelihoodField.around(GRID, guess.x, guess.y, 6.0, PARAMS.sigma_m), points, guess, PARAMS)
    assert m.ok, m
    # Within a cell: the map holds a wall at its cell's centre, up to half a cell from the surface.
    assert math.hypot(m.pose.x - truth.x, m.pose.y - truth.y) < 0.04, (m.pose, truth)
    assert abs(wrap_angle(m.pose.yaw - truth.yaw)) < math.radians(1.0), (m.pose, truth)


@settings(max_examples=40, deadline=None)
@given(truth=inside, off=st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-0.5, 0.5)))
def test_a_match_never_leaps_past_its_window(truth: Pose2D, off: tuple[float, float, float]) -> None:
    guess = Pose2D(truth.x + off[0], truth.y + off[1], truth.yaw + off[2])
    m = match(LikelihoodField.around(GRID, guess.x, guess.y, 6.0, PARAMS.sigma_m), room_scan(truth).returns(),
              guess, PARAMS)  # fmt: skip
    lim = PARAMS.search_xy_m + GRID.resolution + 1e-9
    assert abs(m.pose.x - guess.x) <= lim and abs(m.pose.y - guess.y) <= lim
    assert abs(wrap_angle(m.pose.yaw - guess.yaw)) <= PARAMS.search_yaw_rad + PARAMS.yaw_step_rad + 1e-9
    if not m.ok:
        assert m.pose == guess


def test_where_the_map_knows_nothing_the_guess_stands() -> None:
    empty = OccupancyMap()
    guess = Pose2D(0.2, 0.1, 0.3)
    field = LikelihoodField.around(empty, 0, 0, 6.0, PARAMS.sigma_m)
    assert match(field, room_scan(guess).returns(), guess, PARAMS) == match(field, np.zeros((0, 2)), guess, PARAMS)
    far = Pose2D(40.0, 40.0, 0.0)  # off the map: no returns on seen cells
    m = match(LikelihoodField.around(GRID, far.x, far.y, 6.0, PARAMS.sigma_m), room_scan(Pose2D(0, 0, 0)).returns(),
              far, PARAMS)  # fmt: skip
    assert not m.ok and m.reason == "few_points" and m.pose == far
    score, support, known = fit(LikelihoodField.around(GRID, 0, 0, 6.0, PARAMS.sigma_m), room_scan(IDENTITY).returns(),
                                IDENTITY)  # fmt: skip
    assert score > 0.8 and support > 100 and known >= support


def test_a_walk_on_drifting_odometry_stays_on_the_truth() -> None:
    """Odometry that overshoots every step by 5 % and turns 0.5 deg per metre too far: matched scan by
    scan against the map it builds, the pose stays within a few centimetres of the truth."""
    grid, corrector = OccupancyMap(), Corrector()
    odom = truth = Pose2D(-2.5, -1.5, 0.6)
    worst_odom = worst = 0.0
    for k in range(300):  # 0.05 m a step: 15 m round the room
        step = Pose2D(0.05, 0.0, 0.02 if (k // 60) % 2 else -0.02)
        truth = truth.compose(step)
        if abs(truth.x) > ROOM[0] - 1.0 or abs(truth.y) > ROOM[1] - 1.0:
            truth = Pose2D(truth.x, truth.y, truth.yaw + math.pi / 2)  # turn away from the wall
            odom = Pose2D(odom.x, odom.y, odom.yaw + math.pi / 2)
        odom = odom.compose(Pose2D(step.x * 1.05, 0.0, step.yaw + math.radians(0.5) * step.x))
        beams = room_scan(truth)
        pose, _ = corrector.locate(grid, beams.returns(), odom, True)
        grid.integrate(beams, pose)
        corrector.integrated()
        worst_odom = max(worst_odom, math.hypot(odom.x - truth.x, odom.y - truth.y))
        worst = max(worst, math.hypot(pose.x - truth.x, pose.y - truth.y))
    assert worst_odom > 0.3, "the odometry should have drifted"
    assert worst < 0.1, worst  # two cells: the odometry is off by 0.3 m and more


@settings(max_examples=100, deadline=None)
@given(a=inside, b=inside)
def test_compose_and_inverse_undo_each_other(a: Pose2D, b: Pose2D) -> None:
    back = a.compose(b).compose(b.inverse())
    assert math.hypot(back.x - a.x, back.y - a.y) < 1e-9 and abs(wrap_angle(back.yaw - a.yaw)) < 1e-9
    ident = a.compose(a.inverse())
    assert math.hypot(ident.x, ident.y) < 1e-9 and abs(ident.yaw) < 1e-9


@settings(max_examples=100, deadline=None)
@given(a=inside, dt=st.floats(0.001, 2.0), speed=st.floats(0.0, 1.0), heading=st.floats(-math.pi, math.pi),
       turn=st.floats(-1.0, 1.0))  # fmt: skip
def test_moves_the_robot_can_make_are_never_jumps(a: Pose2D, dt: float, speed: float, heading: float,
                                                   turn: float) -> None:  # fmt: skip
    """Anything within its ceilings (3.8 m/s, 4 rad/s) is a move; a teleport or a spin past them is a jump."""
    b = Pose2D(a.x + 3.8 * speed * dt * math.cos(heading), a.y + 3.8 * speed * dt * math.sin(heading),
               a.yaw + 4.0 * turn * dt)  # fmt: skip
    assert odometry_jump(dt, a, b, 3.8, 4.0) == ""
    far = Pose2D(a.x + max(0.3, 6.0 * dt) * math.cos(heading), a.y + max(0.3, 6.0 * dt) * math.sin(heading), a.yaw)
    assert "moved" in odometry_jump(dt, a, far, 3.8, 4.0)
    spun = Pose2D(a.x, a.y, a.yaw + min(math.pi - 0.01, max(0.4, 6.5 * dt)))
    assert dt > 0.48 or "turned" in odometry_jump(dt, a, spun, 3.8, 4.0)
