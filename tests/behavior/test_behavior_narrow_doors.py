"""Footprint-true geometry on narrow doors: the costmap (world/occupancy.py `inflate`) leaves a 0.8 m
doorway open and closes a 0.4 m gap, and the global planner crosses the doorway square-on, at full
resolution and when the map is planned coarse first. Real costmaps from a wall's cells, no mocks."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.behavior.planner.by_heading import footprint_free, path_headings, turn_free, turn_reach
from go2vlm.behavior.planner.global_path import Costmap, GlobalParams, footprint_fits, line_cells, plan_path
from go2vlm.behavior.strategies.explore_params import ExploreParams
from go2vlm.geometry.footprint import rect_distance
from go2vlm.robot_profile.go2 import FOOTPRINT_LENGTH, FOOTPRINT_WIDTH
from go2vlm.world.occupancy import CIRCUMSCRIBED, FREE, INSCRIBED, LETHAL, CostmapParams, inflate

RES = 0.05
ORIGIN = (-4.0, -3.0)


def wall_with_door(door_m: float, centre_y: float = 0.0, wall_x: float = 0.0) -> np.ndarray:
    """8 x 6 m (origin -4, -3) of free space, walled round, a 0.1 m wall across at x = wall_x with a
    doorway `door_m` clear centred on y = centre_y: the OccupancyGrid values (0 free, 100 occupied)."""
    g = np.full((120, 160), FREE, np.int8)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = LETHAL
    cols = slice(int(round((wall_x - 0.05 - ORIGIN[0]) / RES)), int(round((wall_x + 0.05 - ORIGIN[0]) / RES)))
    ys = ORIGIN[1] + (np.arange(g.shape[0]) + 0.5) * RES
    g[np.abs(ys - centre_y) > door_m / 2, cols] = LETHAL
    return g


def costmap(door_m: float, centre_y: float = 0.0) -> Costmap:
    values = wall_with_door(door_m, centre_y)
    return Costmap(inflate(values, RES, CostmapParams.for_footprint(FOOTPRINT_LENGTH, FOOTPRINT_WIDTH)), RES, ORIGIN)


def test_only_the_inscribed_radius_is_lethal() -> None:
    params = CostmapParams.for_footprint(FOOTPRINT_LENGTH, FOOTPRINT_WIDTH)
    values = np.full((61, 61), FREE, np.int8)
    values[30, 30] = LETHAL
    cost = inflate(values, RES, params)
    rows, cols = np.indices(values.shape)
    d = np.hypot(rows - 30, cols - 30) * RES
    assert cost[30, 30] == LETHAL
    assert (cost[(d > 0) & (d <= params.inscribed_m)] == INSCRIBED).all()
    band = (d > params.inscribed_m) & (d <= params.circumscribed_m)
    assert ((cost[band] >= CIRCUMSCRIBED) & (cost[band] < INSCRIBED)).all(), "the band costs, it does not block"
    assert (cost[d > params.circumscribed_m] < CIRCUMSCRIBED).all()


@pytest.mark.parametrize("door", [0.8, 0.9])
def test_a_narrow_doorway_stays_passable(door: float) -> None:
    cm = costmap(door)
    col = cm.cell(0.0, 0.0)[1]
    passable = cm.data[:, col] < INSCRIBED
    assert passable.any(), "the doorway's middle is passable"
    plan = plan_path(cm, (-2.0, 1.5), [(2.0, -1.5)], GlobalParams())
    assert plan.ok, plan.reason


def test_a_forty_centimetre_gap_is_closed() -> None:
    cm = costmap(0.4)
    col = cm.cell(0.0, 0.0)[1]
    assert (cm.data[:, col] >= INSCRIBED).all(), "0.045 m each side of a 0.31 m robot: less than the standing clearance"
    plan = plan_path(cm, (-2.0, 1.5), [(2.0, -1.5)], GlobalParams())
    assert not plan.ok and "cut the goal off" in plan.reason


def door_headings(cm: Costmap, cells: np.ndarray, half: float = 0.3) -> np.ndarray:
    """The path's heading (rad) at each of its cells within `half` m of the wall's plane (x = 0)."""
    xy = cm.world(cells[:, 0], cells[:, 1])
    inside = np.nonzero(np.abs(xy[:, 0]) <= half)[0]
    a, b = cells[np.maximum(inside - 2, 0)], cells[np.minimum(inside + 2, len(cells) - 1)]
    return np.arctan2(b[:, 0] - a[:, 0], b[:, 1] - a[:, 1])


@settings(max_examples=12, deadline=None)
@given(
    door=st.sampled_from([0.8, 0.9]),
    centre=st.floats(-1.0, 1.0),
    start=st.tuples(st.floats(-3.0, -1.5), st.floats(-2.2, 2.2)),
    goal=st.tuples(st.floats(1.5, 3.0), st.floats(-2.2, 2.2)),
)
def test_the_planner_crosses_a_narrow_doorway_square_on(
    door: float, centre: float, start: tuple[float, float], goal: tuple[float, float]
) -> None:
    cm = costmap(door, centre)
    p = GlobalParams()
    plan = plan_path(cm, start, [goal], p)
    assert plan.ok, plan.reason
    heads = door_headings(cm, plan.cells)
    assert len(heads) and (np.abs(np.degrees(heads)) <= 10.0).all(), np.degrees(heads)
    # the waypoints' legs through the band keep the footprint clear at their own heading
    w = plan.waypoints
    for a, b in zip(w[:-1], w[1:], strict=True):
        line = line_cells(cm.cell(*a), cm.cell(*b))
        v = cm.data[line[:, 0], line[:, 1]]
        band = line[(v >= CIRCUMSCRIBED) & (v < INSCRIBED)]
        heading = math.atan2(b[1] - a[1], b[0] - a[0])
        assert footprint_fits(cm, band, np.full(len(band), heading), p).all()


def test_a_coarse_plan_never_closes_a_doorway() -> None:
    cm = costmap(0.8, 0.33)
    p = GlobalParams(max_cells=cm.data.size // 9 + 10)  # a coarse guide at 3 cells (0.15 m)
    plan = plan_path(cm, (-2.5, -2.0), [(2.5, 2.0)], p)
    assert plan.ok and plan.stride == 3, plan.reason
    heads = door_headings(cm, plan.cells)
    assert (np.abs(np.degrees(heads)) <= 10.0).all()
    assert (cm.data[plan.cells[:, 0], plan.cells[:, 1]] < INSCRIBED).all()


def test_the_footprint_check_is_the_rectangle_at_its_heading() -> None:
    cm = costmap(0.8)
    cell = np.array([cm.cell(0.0, 0.0)])
    p = GlobalParams()
    assert footprint_fits(cm, cell, np.array([0.0]), p).all(), "square-on: 0.245 m each side"
    assert not footprint_fits(cm, cell, np.array([math.pi / 2]), p).any(), "along the wall: the body in the jambs"


def three_by_three_rooms(door: float) -> Costmap:
    """Nine 6 m rooms (walls 0.1 m) with a doorway `door` m clear in the middle of every inner wall."""
    n, step, half = 362, 120, int(round(door / RES / 2))
    g = np.full((n, n), FREE, np.int8)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = LETHAL
    for k in range(step, n - 2, step):
        g[k : k + 2, :] = LETHAL
        g[:, k : k + 2] = LETHAL
        for j in range(step // 2, n, step):
            g[k : k + 2, j - half : j + half] = FREE
            g[j - half : j + half, k : k + 2] = FREE
    return Costmap(inflate(g, RES, CostmapParams.for_footprint(FOOTPRINT_LENGTH, FOOTPRINT_WIDTH)), RES, (0.0, 0.0))


@pytest.mark.parametrize("door", [0.8, 0.9])
def test_through_rooms_every_door_is_crossed_square_on(door: float) -> None:
    cm = three_by_three_rooms(door)
    p = GlobalParams()
    plan = plan_path(cm, (2.0, 2.5), [(15.5, 16.0)], p)  # corner room to corner room: four doors
    assert plan.ok, plan.reason
    xy = cm.world(plan.cells[:, 0], plan.cells[:, 1])
    walls = np.array([6.05, 12.05])
    near = np.abs(xy[:, :, None] - walls[None, None, :]).min(axis=2) <= 0.3  # (N, 2): near a wall at x / at y
    crossing = near[:, 0] ^ near[:, 1]
    heads = np.degrees(np.arctan2(*np.diff(plan.cells[np.clip(np.arange(len(xy))[:, None] + [-2, 2], 0, len(xy) - 1)],
                                          axis=1)[:, 0].T))  # fmt: skip
    along_x = np.minimum(np.abs(heads), 180 - np.abs(heads))  # off the x axis
    along_y = np.abs(90 - np.abs(heads))
    assert (along_x[crossing & near[:, 0]] <= 10).all() and (along_y[crossing & near[:, 1]] <= 10).all()
    assert crossing.sum() >= 4 * 8, "four doors crossed"


def recorded(name: str) -> tuple[Costmap, tuple[float, float]]:
    """A costmap the map node drew (tests/data/NAME.npz), and where the Go2 stood in it."""
    from pathlib import Path

    z = np.load(Path(__file__).parents[1] / "data" / f"{name}.npz")
    x, y = (float(v) for v in z["start"][:2])
    return Costmap(z["data"], float(z["resolution"]), (float(z["origin"][0]), float(z["origin"][1]))), (x, y)


def recorded_doorway() -> tuple[Costmap, tuple[float, float]]:
    """A costmap the map node drew (tests/data/doorway_costmap.npz: 4 x 4 m of house 1002's, the houses
    suite's episode 2), and where the Go2 stood in it: at the kitchen's mouth of its 0.8 m door to the
    living room, 0.15 m off the door's middle, turned 40 degrees off its axis, the jamb's inscribed
    cells beside it."""
    return recorded("doorway_costmap")


@pytest.mark.parametrize("goal", [(4.89, 4.77), (5.5, 4.8), (6.0, 4.8)])
def test_a_robot_standing_in_a_doorway_off_its_middle_plans_on(goal: tuple[float, float]) -> None:
    """Where the robot stands, at whatever heading, neither search checks the rectangle within its
    turn_reach (by_heading.py): the search by heading once held it to its own cell, where no line
    fits, and a frontier round the corner beyond the door was 'unreachable'."""
    cm, start = recorded_doorway()
    p = ExploreParams().global_params  # as the explorer plans
    assert not footprint_fits(cm, np.array([cm.cell(*start)]), np.array([math.pi / 2]), p).any(), "off the middle"
    plan = plan_path(cm, start, [goal], p)
    assert plan.ok, plan.reason
    assert (cm.data[plan.cells[:, 0], plan.cells[:, 1]] < INSCRIBED).all()
    xy = cm.world(plan.cells[:, 0], plan.cells[:, 1])
    assert xy[-1, 1] > 4.2, "through the door into the living room"


@pytest.mark.parametrize("goal", [(5.6, 6.6), (5.7, 6.8), (5.8, 7.0)])
def test_among_furniture_a_path_turns_where_the_rectangle_sweeps_clear(goal: tuple[float, float]) -> None:
    """tests/data/cluttered_doorway_costmap.npz: 4.2 x 2.7 m of the houses suite's house 1037, drawn
    by the map node: a kitchen with a fridge, a tray and a mug on the floor before its 0.8 m door
    (x 4.56, y 6.38-7.18), the Go2 at its start west of them. Nowhere between it and the door does
    the circumscribed disc fit, so a search that turned only where the disc fits found no way to
    the bedroom; the Go2 turns in place where its rectangle sweeps clear, and goes through square-on."""
    cm, start = recorded("cluttered_doorway_costmap")
    p = ExploreParams().global_params  # as the explorer plans
    plan = plan_path(cm, start, [goal], p)
    assert plan.ok, plan.reason
    cells = plan.cells
    assert (cm.data[cells[:, 0], cells[:, 1]] < INSCRIBED).all()
    xy = cm.world(cells[:, 0], cells[:, 1])
    assert xy[-1, 0] > 4.7, "through the door into the bedroom"
    # past the start's turn_reach and before the goal's, the disc fits or the rectangle along a line
    # does, and the path turns in the band only where the rectangle sweeps clear
    skip = turn_reach(p, cm.resolution)
    inner = cells[skip : len(cells) - skip]
    disc = cm.data[inner[:, 0], inner[:, 1]] < CIRCUMSCRIBED
    assert (disc | footprint_free(cm, p)[:, inner[:, 0], inner[:, 1]].any(axis=0)).all()
    step = np.diff(cells, axis=0)
    turned = (step[1:] != step[:-1]).any(axis=1)  # the path's direction changes at cells[1:-1]
    band = ~(cm.data[cells[:, 0], cells[:, 1]] < CIRCUMSCRIBED)
    at = cells[1:-1][turned & band[:-2] & band[1:-1] & band[2:]]
    assert len(at) and turn_free(cm, p)[:, at[:, 0], at[:, 1]].any(axis=0).all()
    heads = path_headings(cells)
    door = np.abs(xy[:, 0] - 4.56) < 0.1
    assert door.any() and (np.abs(xy[door, 1] - 6.78) < 0.2).all(), "in the door's middle"
    assert (np.abs(np.sin(heads[door])) < 0.2).all(), "square-on"


@settings(max_examples=60, deadline=None)
@given(dr=st.integers(-9, 9), dc=st.integers(-9, 9), k=st.integers(0, 3))
def test_a_turn_in_place_is_free_where_no_obstacle_lies_in_its_sweep(dr: int, dc: int, k: int) -> None:
    """turn_free against the rectangles at 91 headings across the turn: an obstacle cell the sweep
    (plus the clearance) covers blocks the turn; one clear of it by a millimetre does not."""
    p = GlobalParams()
    data = np.zeros((41, 41), np.int8)
    data[20 + dr, 20 + dc] = LETHAL
    free = bool(turn_free(Costmap(data, RES, (0.0, 0.0)), p)[k, 20, 20])
    x, y = dc * RES, dr * RES
    th = k * math.pi / 4 + np.linspace(0.0, math.pi / 4, 91)
    d = rect_distance(np.cos(th) * x + np.sin(th) * y, -np.sin(th) * x + np.cos(th) * y, p.half_length, p.half_width)
    if d.min() < p.clearance_m - 1e-3:
        assert not free
    if d.min() > p.clearance_m + 1e-3:
        assert free


def test_a_gap_too_narrow_at_a_creep_is_planned_tight_at_a_crawl() -> None:
    """A 0.48 m gap: the rectangle (0.31 m) keeps the creep's clearance (0.11 m a side) in 0.53 m only,
    so the plan keeps the rule standing (0.05 m, the costmap's own padding) and says so ("tight"); the
    controller and the guard walk it at the speed the gap allows. A 0.38 m gap is refused even so."""
    p = GlobalParams()
    assert p.tight_clearance_m < p.clearance_m
    plan = plan_path(costmap(0.48), (-2.0, 0.0), [(2.0, 0.0)], p)
    assert plan.ok and "tight" in plan.reason, plan.reason
    assert not plan_path(costmap(0.48), (-2.0, 0.0), [(2.0, 0.0)], replace(p, tight_clearance_m=p.clearance_m)).ok
    assert not plan_path(costmap(0.38), (-2.0, 0.0), [(2.0, 0.0)], p).ok
    wide = plan_path(costmap(0.8), (-2.0, 0.0), [(2.0, 0.0)], p)
    assert wide.ok and "tight" not in wide.reason


def test_the_navigator_says_when_its_route_is_tight() -> None:
    """The route through the 0.48 m gap is the planner's tight one: the navigator's step says so in its
    reason (the status line), and counts it."""
    from go2vlm.behavior.navigate import Navigator

    nav = Navigator()
    step = nav.step((2.0, 0.0), 0.3, costmap(0.48), (-2.0, 0.0, 0.0), None, 0.0, max_linear=0.4, max_angular=0.8)
    assert step.status == "moving" and "tight" in step.reason, step
    assert nav.counters["plans_tight"] == 1
    wide = Navigator()
    step = wide.step((2.0, 0.0), 0.3, costmap(0.8), (-2.0, 0.0, 0.0), None, 0.0, max_linear=0.4, max_angular=0.8)
    assert step.status == "moving" and "tight" not in step.reason and wide.counters["plans_tight"] == 0
