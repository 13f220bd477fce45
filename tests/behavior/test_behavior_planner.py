"""The approach's local planner (behavior/planner/local.py): a free way passes the command unchanged; a box
in the way turns the robot to a free heading; the goal itself is no obstacle; it never speeds anything
up nor drives backwards."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.behavior.planner import PlannerParams, corridor_free, steer

P = PlannerParams()
W = 0.8  # the approach's turn rate ceiling


def box(cx: float, cy: float, hx: float, hy: float) -> np.ndarray:
    xs, ys = np.linspace(cx - hx, cx + hx, 11), np.linspace(cy - hy, cy + hy, 11)
    return np.array([[x, y] for x in xs for y in (cy - hy, cy + hy)] + [[x, y] for y in ys for x in (cx - hx, cx + hx)])


def test_free_way_passes_unchanged() -> None:
    s = steer(0.4, 0.1, 0.4, 0.0, 3.0, box(0.0, 3.0, 0.3, 0.3), P, max_angular=W)
    assert (s.vx, s.wz, s.blocked, s.note) == (0.4, 0.1, False, "")


def test_box_in_the_way_steers_round_it() -> None:
    pts = box(1.6, 0.05, 0.2, 0.3)
    assert corridor_free(pts, 0.0, P) < P.lookahead
    s = steer(0.0, 0.0, 0.4, 0.0, 3.5, pts, P, max_angular=W)
    assert s.blocked and s.note and s.heading != 0.0
    assert corridor_free(pts, s.heading, P) >= P.lookahead
    assert 0.0 < s.vx < 0.4 and s.wz * s.heading > 0  # slower, turning towards the free heading


def test_the_goal_is_not_its_own_obstacle() -> None:
    # The cylinder itself, 1.2 m ahead, with the robot to stop 0.8 m from it: no detour.
    cyl = np.array([[1.2 + 0.3 - 0.3 * math.cos(a), 0.3 * math.sin(a)] for a in np.linspace(-1.2, 1.2, 13)])
    s = steer(0.2, 0.0, 0.2, 0.0, 1.2, cyl, P, max_angular=W, reach_m=0.4)
    assert not s.blocked and (s.vx, s.wz) == (0.2, 0.0)


def test_goal_closer_than_the_obstacle_is_not_steered() -> None:
    s = steer(0.3, 0.0, 0.3, 0.0, 0.5, box(2.5, 0.0, 0.3, 0.3), P, max_angular=W)
    assert not s.blocked


def test_keeps_to_the_side_it_chose() -> None:
    pts = box(1.5, 0.0, 0.2, 0.3)  # dead ahead: either side is as good
    left = steer(0.0, 0.0, 0.4, 0.0, 3.5, pts, P, max_angular=W, side=1.0)
    right = steer(0.0, 0.0, 0.4, 0.0, 3.5, pts, P, max_angular=W, side=-1.0)
    assert left.heading > 0 > right.heading


def test_boxed_in_turns_in_place() -> None:
    # 0.75 m round: not even a creep's way (0.16 m each side) is min_free long (0.9 m is, at a creep)
    ring = np.array([[0.75 * math.cos(a), 0.75 * math.sin(a)] for a in np.linspace(-math.pi, math.pi, 180)])
    s = steer(0.4, 0.0, 0.4, 0.0, 3.0, ring, P, max_angular=W)
    assert s.blocked and s.vx == 0.0 and "no free way" in s.note and abs(s.wz) >= W / 2


def test_a_short_free_way_is_still_progress() -> None:
    # Nothing free for the 1.2 m it would like, but 0.5 m ahead-left is: creep that way, slower.
    ring = np.array([[1.2 * math.cos(a), 1.2 * math.sin(a)] for a in np.linspace(-math.pi, math.pi, 180)])
    s = steer(0.0, 0.0, 0.4, 0.0, 3.0, ring, P, max_angular=W)
    assert s.blocked and 0.0 < s.vx < 0.4 * 0.5


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3)), max_size=20),
    st.floats(0.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(0.0, 1.0),
    st.floats(-math.pi, math.pi),
    st.one_of(st.none(), st.floats(0.0, 6.0)),
    st.sampled_from([-1.0, 0.0, 1.0]),
)
def test_never_faster_never_backwards(
    pts: list, vx: float, wz: float, speed: float, bearing: float, goal: float | None, side: float
) -> None:
    s = steer(vx, wz, speed, bearing, goal, np.array(pts).reshape(-1, 2), P, max_angular=W, side=side)
    if not s.blocked:  # the approach's own command; slowed where only a slower speed's clearance is free
        assert s.wz == wz and (s.vx == vx or (0.0 <= s.vx < vx and "slowed" in s.note))
    else:
        assert 0.0 <= s.vx <= speed
        assert abs(s.wz) <= W
        assert abs(math.remainder(s.heading - bearing, 2 * math.pi)) <= P.max_offset + 1e-9
        if s.vx > 0 and goal is None:  # it only drives along a corridor that is free
            free = corridor_free(np.array(pts).reshape(-1, 2), s.heading, P)
            assert free > 0.0
    assert math.isfinite(s.vx) and math.isfinite(s.wz)


def test_a_narrow_doorway_is_walked_through_slowly_and_a_gap_too_narrow_is_not() -> None:
    """A pocket whose way out, 0.6 m ahead, is a doorway, the robot a few centimetres off its middle.
    With the clearance rule (a creep keeps 0.16 m, 0.4 m/s 0.26 m) a 0.8 m doorway straight ahead is
    walked through slower, not steered away from; with the goal off to one side the doorway is the way
    taken, at a creep; a 0.45 m gap is no way (it turns away in place)."""
    rule = PlannerParams()
    off = 0.04  # the robot stands this far right of the gap's middle

    def pocket(gap: float) -> np.ndarray:
        half = gap / 2
        xs, back = np.arange(0.6, 1.2, 0.01), np.arange(-1.0, 0.6, 0.01)
        side = np.linspace(half, 0.9, 30)
        walls = np.vstack([np.c_[xs, np.full_like(xs, half)], np.c_[xs, np.full_like(xs, -half)],
                           np.c_[np.full(30, 0.6), side], np.c_[np.full(30, 0.6), -side],
                           np.c_[back, np.full_like(back, 0.9)], np.c_[back, np.full_like(back, -0.9)]])  # fmt: skip
        return walls + (0.0, off)

    door = pocket(0.8)
    ahead = steer(0.4, 0.0, 0.4, 0.0, 3.0, door, rule, max_angular=W)
    assert not ahead.blocked and 0.0 < ahead.vx < 0.4 and "slowed" in ahead.note, ahead
    assert corridor_free(door, 0.0, rule, rule.clearance.at(ahead.vx)) >= rule.lookahead
    aside = steer(0.4, 0.0, 0.4, math.radians(25), 3.0, door, rule, max_angular=W)
    assert aside.blocked and 0.0 < aside.vx <= rule.creep_mps and abs(aside.heading) < math.radians(10), aside
    narrow = steer(0.4, 0.0, 0.4, 0.0, 3.0, pocket(0.45), rule, max_angular=W)
    assert narrow.blocked and narrow.vx == 0.0 and abs(narrow.heading) > math.radians(45), narrow  # not into it


def test_keeps_near_the_way_it_chose_while_that_stays_free() -> None:
    """Rooms 28: a way just right of the goal and one 95 deg left were free in turn as it turned, and
    it swung between them on the spot for two minutes. Near the way chosen last (`keep_window`) wins
    while it is free; with that way blocked the nearest free way is taken as before."""
    p = PlannerParams(margin=0.35, margin_per_speed_s=0.0)  # the clearance this spot was measured with
    wall = np.array([[1.5, y] for y in np.linspace(-0.2, 3.0, 65)])  # ahead and to the left; open right
    first = steer(0.0, 0.0, 0.4, 0.0, 3.5, wall, p, max_angular=W)
    assert first.blocked and first.heading < 0  # the nearest free way: round the wall's right end
    kept = steer(0.0, 0.0, 0.4, 0.0, 3.5, wall, p, max_angular=W, keep=math.radians(95))
    assert kept.blocked and abs(kept.heading - math.radians(95)) <= p.keep_window + 1e-9
    left_shut = np.vstack([wall, [[x, 0.8] for x in np.linspace(-1.5, 1.5, 61)]])
    again = steer(0.0, 0.0, 0.4, 0.0, 3.5, left_shut, p, max_angular=W, keep=math.radians(95))
    assert again.blocked and again.heading < 0
