"""The global planner (behavior/planner/global_path.py): the path never enters a lethal cell, costs no
more than the straight line where that is free, goes through the doorway between two rooms, keeps to
known space when told to, refuses with a reason, and a route replans when the map blocks it."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from go2vlm.behavior.planner.global_path import (
    Costmap,
    GlobalParams,
    cell_costs,
    chain_cost,
    in_sight,
    line_cells,
    plan_path,
)
from go2vlm.behavior.planner.route import Route
from go2vlm.world.occupancy import CIRCUMSCRIBED

RES = 0.05
P = GlobalParams()


def two_rooms(door: bool = True) -> Costmap:
    """12 x 7 m, origin (-6, -3.5): walls round, a middle wall at x = 0 with a 1.2 m door at |y| < 0.6;
    lethal 100 on the walls, 99 within 0.2 m of them, a gradient to 0 at 0.6 m."""
    from scipy import ndimage

    g = np.zeros((140, 240), np.int8)
    g[0, :] = g[-1, :] = 100
    g[:, 0] = g[:, -1] = 100
    g[:, 119:121] = 100
    if door:
        g[58:82, 119:121] = 0
    d = ndimage.distance_transform_edt(g < 100) * RES
    cost = np.clip((0.6 - d) / 0.4 * 98, 0, 98).astype(np.int8)
    cost[d <= 0.2] = 99
    cost[g == 100] = 100
    return Costmap(cost, RES, (-6.0, -3.5), 1.0)


def crosses_lethal(cm: Costmap, waypoints: np.ndarray, lethal: int = 99, skip_first: bool = True) -> bool:
    for i, (a, b) in enumerate(zip(waypoints[:-1], waypoints[1:], strict=False)):
        line = line_cells(cm.cell(*a), cm.cell(*b))
        if skip_first and i == 0:
            line = line[1:]
        if (cm.data[line[:, 0], line[:, 1]] >= lethal).any():
            return True
    return False


def test_through_the_doorway() -> None:
    cm = two_rooms()
    plan = plan_path(cm, (3.0, -2.0), [(-4.8, -2.6)], P)
    assert plan.ok, plan.reason
    w = plan.waypoints
    assert tuple(w[0]) == (3.0, -2.0)
    assert math.hypot(w[-1][0] + 4.8, w[-1][1] + 2.6) <= P.goal_tolerance_m + RES
    # It crosses x = 0 through the door, and only there.
    crossings = [
        a + (b - a) * (0 - a[0]) / (b[0] - a[0]) for a, b in zip(w[:-1], w[1:], strict=False) if a[0] * b[0] < 0
    ]
    assert crossings and all(abs(c[1]) < 0.6 for c in crossings)
    assert not crosses_lethal(cm, w)
    assert plan.length >= math.hypot(3.0 + 4.8, -2.0 + 2.6) - P.goal_tolerance_m


@pytest.mark.parametrize("body", [0.0, 0.3])
def test_near_enough_is_also_in_sight(body: float) -> None:
    """A goal 0.4 m behind the middle wall with 1 m to spare: the cells on the near side of the wall
    are within reach but do not see it, so the path goes round through the door to its side. An
    object's own cells (`goal_body_m`) hide nothing: a goal inside a block is reached beside it."""
    cm = two_rooms()
    plan = plan_path(
        cm, (1.0, -2.5), [(-0.4, -2.5)], GlobalParams(goal_tolerance_m=1.0, goal_in_sight=True, goal_body_m=body)
    )
    assert plan.ok, plan.reason
    end = plan.waypoints[-1]
    assert end[0] < -0.05 and math.hypot(end[0] + 0.4, end[1] + 2.5) <= 1.0 + RES, plan.waypoints
    frontier = plan_path(cm, (1.0, -2.5), [(-0.4, -2.5)], GlobalParams(goal_tolerance_m=1.0))
    assert frontier.ok and frontier.waypoints[-1][0] > 0.05  # not asked: the near side of the wall
    g = cm.data.copy()
    g[20:26, 100:106] = 100  # a block, centre (-0.85, -2.35), beside the wall
    blocked = Costmap(g, RES, cm.origin, 1.0)
    inside = plan_path(
        blocked, (1.0, -2.5), [(-0.85, -2.35)], GlobalParams(goal_tolerance_m=1.0, goal_in_sight=True, goal_body_m=0.25)
    )
    assert inside.ok and inside.waypoints[-1][0] < -0.05, inside.reason


@settings(max_examples=60, deadline=None)
@given(off=st.floats(0.1, 0.3), side=st.floats(-0.05, 0.05))
def test_a_remembered_place_off_its_object_is_in_sight_past_the_object_but_never_through_a_wall(
    off: float, side: float
) -> None:
    """The memory places a mug `off` metres past where its cells are on the map (its ranging erred):
    from a stand 1 m before it the line to the place crosses the mug's own cells, a piece lying wholly
    within its radius plus `goal_own_m`, so the stand sees it; without `goal_own_m` it does not. A wall
    as near the place hides it all the same: it runs on past that reach."""
    g = np.zeros((80, 80), np.int8)
    place = (40, 40)
    mug = (40 - round(off / RES), 40 + round(side / RES))  # rows: y; the stand lies at lower rows
    g[mug[0] - 1 : mug[0] + 2, mug[1] - 1 : mug[1] + 2] = 100  # 0.15 m across
    stand = np.array([[20, 40]])
    body, own = 0.08 / RES, 0.3 / RES
    assert not in_sight(g, stand, place, body)[0]
    assert in_sight(g, stand, place, body, own)[0]
    walled = g.copy()
    walled[mug[0], :] = 100  # a wall through the mug's row, across the room
    assert not in_sight(walled, stand, place, body, own)[0]


def test_refusals_say_why() -> None:
    cm = two_rooms(door=False)
    assert "unreachable" in plan_path(cm, (3.0, -2.0), [(-4.8, -2.6)], P).reason
    assert "outside the map" in plan_path(cm, (30.0, 0.0), [(-4.8, -2.6)], P).reason
    assert "outside the map" in plan_path(cm, (3.0, -2.0), [(-40.0, 0.0)], P).reason
    assert "inside an obstacle" in plan_path(cm, (3.0, -2.0), [(0.0, -2.5)], GlobalParams(goal_tolerance_m=0.1)).reason
    boxed = Costmap(np.full((40, 40), 100, np.int8), RES, (0.0, 0.0))
    assert "boxed in" in plan_path(boxed, (1.0, 1.0), [(0.2, 0.2)], P).reason
    assert "no goal" in plan_path(cm, (3.0, -2.0), [], P).reason
    assert not plan_path(cm, (math.nan, 0.0), [(1.0, 1.0)], P).ok


def test_a_start_inside_the_inflation_escapes() -> None:
    cm = two_rooms()
    plan = plan_path(cm, (0.15, -2.0), [(3.0, -2.0)], P)  # beside the middle wall, in its inflation
    assert plan.ok, plan.reason
    assert cm.data[cm.cell(*plan.waypoints[1])] < 99  # the first leg leaves the inflation ...
    assert not crosses_lethal(cm, plan.waypoints[1:], skip_first=False)  # ... and the rest keeps out


def test_unknown_space_policy() -> None:
    cm = two_rooms()
    data = cm.data.copy()
    data[:, 140:200] = -1  # the kitchen's middle is unknown, a known corridor along its north wall
    data[120:128, 140:200] = 0
    unk = Costmap(data, RES, cm.origin)
    start, goal = (0.5, -2.0), (5.0, -2.0)
    never = plan_path(unk, start, [goal], GlobalParams(unknown_cost=math.inf))
    cheap = plan_path(unk, start, [goal], GlobalParams(unknown_cost=1.5))
    assert never.ok and cheap.ok
    assert cheap.length < never.length  # the straight way through the unknown
    assert not (unk.data[never.cells[:, 0], never.cells[:, 1]] == -1).any()
    data[120:128, 140:200] = -1
    cut = plan_path(Costmap(data, RES, cm.origin), start, [goal], GlobalParams(unknown_cost=math.inf))
    assert not cut.ok and "unknown" in cut.reason


def test_nearest_of_several_goals() -> None:
    cm = two_rooms()
    goals = [(-4.0, 2.0), (4.0, 2.0), (5.0, -3.0)]
    plan = plan_path(cm, (3.0, 1.5), goals, P)
    assert plan.ok and plan.goal_index == 1


@settings(max_examples=40, deadline=None)
@example([(6, 31, 1, 6)], (1, 1), (6, 37), 0)  # a diagonal step past an obstacle's corner
@given(
    st.lists(st.tuples(st.integers(5, 54), st.integers(5, 54), st.integers(1, 6), st.integers(1, 6)), max_size=8),
    st.tuples(st.integers(1, 58), st.integers(1, 58)),
    st.tuples(st.integers(1, 58), st.integers(1, 58)),
    st.integers(0, CIRCUMSCRIBED - 1),  # 90..98 mean "within the circumscribed radius of an obstacle"
)
def test_paths_are_safe_and_never_dearer_than_a_free_straight_line(boxes, a, b, floor) -> None:
    g = np.full((60, 60), floor, np.int8)
    for r, c, h, w in boxes:
        g[r : r + h, c : c + w] = 100
    cm = Costmap(g, 0.1, (0.0, 0.0))
    p = GlobalParams(goal_tolerance_m=0.0, escape_m=0.0)
    start, goal = cm.world(np.array([a[0]]), np.array([a[1]]))[0], cm.world(np.array([b[0]]), np.array([b[1]]))[0]
    plan = plan_path(cm, tuple(start), [tuple(goal)], p)
    c = cell_costs(cm, p)
    if not np.isfinite(c[a]) or not np.isfinite(c[b]):
        assert not plan.ok
        return
    straight = line_cells(a, b)
    free = np.isfinite(c[straight[:, 0], straight[:, 1]]).all()
    if free:
        assert plan.ok
        assert plan.cost <= chain_cost(c, straight) * cm.resolution + 1e-6
    if plan.ok:
        assert not (g[plan.cells[:, 0], plan.cells[:, 1]] >= p.lethal).any()
        assert not crosses_lethal(cm, plan.waypoints, skip_first=False)
        assert plan.length <= plan.cost + 1e-6  # a cell costs at least 1 per cell crossed
        assert tuple(plan.cells[-1]) == b


def test_coarsened_plans_stay_safe() -> None:
    cm = two_rooms()
    p = GlobalParams(max_cells=cm.data.size // 4)  # plans at 2 x the resolution
    plan = plan_path(cm, (3.0, -2.0), [(-4.8, -2.6)], p)
    assert plan.ok and plan.stride == 2
    assert not crosses_lethal(cm, plan.waypoints)


def test_route_follows_and_replans_when_blocked() -> None:
    cm = two_rooms()
    plan = plan_path(cm, (3.0, -2.0), [(-4.8, -2.6)], P)
    route = Route(plan, (-4.8, -2.6), 0.0, cm.stamp)
    bearing, dist, rest = route.target(3.0, -2.0, 0.0)
    w = plan.waypoints
    assert dist == pytest.approx(math.hypot(*(w[1] - w[0])))
    assert rest == pytest.approx(plan.length)
    assert route.needs_replan(cm, 3.0, -2.0, 0.5, P) == ""
    assert route.needs_replan(cm, 3.0, 2.0, 0.5, P) == "off the route"
    data = cm.data.copy()
    data[50:90, 115:125] = 100  # the door shut
    shut = Costmap(data, RES, cm.origin, 2.0)
    assert "blocked" in route.needs_replan(shut, 3.0, -2.0, 0.5, P)
    grown = Costmap(cm.data, RES, cm.origin, 3.0)
    assert route.needs_replan(grown, 3.0, -2.0, 0.5, P) == ""
    assert route.needs_replan(grown, 3.0, -2.0, 5.0, P) == "the map has grown"
    # Walking the waypoints passes them.
    for wx, wy in w[1:]:
        route.target(float(wx), float(wy), 0.0)
    assert route.done


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(ValueError):
        GlobalParams(unknown_cost=0.5)
    with pytest.raises(ValueError):
        GlobalParams(unknown_cost=math.nan)
    with pytest.raises(ValueError):
        GlobalParams(lethal=0)
    with pytest.raises(ValueError):
        Costmap(np.zeros((0, 3), np.int8), RES, (0.0, 0.0))


@settings(max_examples=50, deadline=None)
@given(
    st.lists(st.sampled_from([-1, 0, 40, 98, 99, 100]), min_size=100, max_size=100),
    st.sampled_from([math.inf, 3.0]),
    st.lists(st.tuples(st.integers(-3, 12), st.integers(-3, 12)), min_size=1, max_size=20),
)
def test_passable_agrees_with_the_cost_grid(cells, unknown_cost, probe) -> None:
    from go2vlm.behavior.planner.global_path import passable

    cm = Costmap(np.array(cells, np.int8).reshape(10, 10), 0.1, (0.0, 0.0))
    p = GlobalParams(unknown_cost=unknown_cost)
    c = cell_costs(cm, p)
    rc = np.array(probe)
    inside = (rc >= 0).all(axis=1) & (rc < 10).all(axis=1)
    want = np.zeros(len(rc), bool)
    want[inside] = np.isfinite(c[rc[inside, 0], rc[inside, 1]])
    assert (passable(cm, rc, p) == want).all()


def test_a_stand_to_look_round_from_is_where_the_footprint_turns() -> None:
    """A goal just past a doorway (its cells in the band: the footprint fits there at some headings
    only): the plain search ends in the doorway, the nearest cell within the tolerance; a stand to
    look round from (`goal_turnable`) ends past it, where the footprint may turn in place; and where
    no such cell is near, any passable one is the goal still."""
    data = np.zeros((40, 40), np.int8)
    data[:, 20] = 100
    data[17:23, 19:22] = 95  # the doorway, in the band
    cm = Costmap(data, 0.05, (0.0, 0.0), 1.0)
    p = replace(P, goal_tolerance_m=0.25)
    plain = plan_path(cm, (0.3, 1.0), [(1.23, 1.01)], p)
    stand = plan_path(cm, (0.3, 1.0), [(1.23, 1.01)], replace(p, goal_turnable=True))
    assert plain.ok and stand.ok
    assert plain.goal is not None and stand.goal is not None
    assert cm.data[cm.cell(*plain.goal)] >= CIRCUMSCRIBED  # in the doorway
    assert cm.data[cm.cell(*stand.goal)] < CIRCUMSCRIBED and stand.goal[0] > 1.05
    inside = plan_path(cm, (0.3, 1.0), [(1.03, 1.01)], replace(P, goal_tolerance_m=0.05, goal_turnable=True))
    assert inside.ok and inside.goal is not None and cm.data[cm.cell(*inside.goal)] >= CIRCUMSCRIBED
