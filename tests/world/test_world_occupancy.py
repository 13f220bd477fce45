"""The occupancy map's pure core: scans place the world's walls where they are from any pose, free rays
never mark anything occupied, bad beams are dropped and counted, the grid holds its cap and never
moves a mapped cell, and the costmap's bands follow the footprint."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.world.occupancy import (
    FREE,
    INSCRIBED,
    LETHAL,
    UNKNOWN,
    Beams,
    CostmapParams,
    GridParams,
    OccupancyMap,
    ScanRefused,
    inflate,
)
from go2vlm.world.poses import Pose2D

ROOM = (4.0, 3.0)  # half sizes of a rectangular room about the origin (m)
BINS = 180
INC = 2 * math.pi / BINS


def room_scan(pose: Pose2D, room: tuple[float, float] = ROOM, bins: int = BINS, range_max: float = 10.0) -> Beams:
    """The exact ranges from `pose` to the walls of an axis-aligned room (inf beyond range_max)."""
    a = pose.yaw - math.pi + INC * np.arange(bins)
    dx, dy = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(dx > 0, (room[0] - pose.x) / dx, np.where(dx < 0, (-room[0] - pose.x) / dx, np.inf))
        ty = np.where(dy > 0, (room[1] - pose.y) / dy, np.where(dy < 0, (-room[1] - pose.y) / dy, np.inf))
    r = np.minimum(tx, ty)
    r[r > range_max] = np.inf
    return Beams(r.astype(np.float32), -math.pi, INC, 0.05, range_max)


def wall_distance(x: np.ndarray, y: np.ndarray, room: tuple[float, float] = ROOM) -> np.ndarray:
    """How far a point is from the room's walls (the wall segments, not their lines)."""
    ax, ay = np.abs(x), np.abs(y)
    dx, dy = ax - room[0], ay - room[1]
    inside = (dx <= 0) & (dy <= 0)
    return np.where(inside, np.minimum(-dx, -dy), np.hypot(np.maximum(dx, 0), np.maximum(dy, 0)))


poses = st.builds(
    Pose2D,
    st.floats(-ROOM[0] + 0.5, ROOM[0] - 0.5),
    st.floats(-ROOM[1] + 0.5, ROOM[1] - 0.5),
    st.floats(-math.pi, math.pi),
)


@settings(max_examples=60, deadline=None)
@given(pose=poses)
def test_a_scan_from_any_pose_puts_the_walls_where_they_are(pose: Pose2D) -> None:
    grid = OccupancyMap()
    got = grid.integrate(room_scan(pose), pose)
    assert got.hits == BINS and got.nan == got.invalid == got.beyond_cap == 0
    occ = grid.occupied_points()
    half_diag = grid.resolution * math.sqrt(2) / 2 + 1e-6
    # Every occupied cell holds a wall point (its centre within half a diagonal of a wall) ...
    assert len(occ) > 0 and (wall_distance(occ[:, 0], occ[:, 1]) <= half_diag).all()
    # ... and every free cell is inside the room.
    rows, cols = np.nonzero(grid.values() == FREE)
    cx = (cols + grid.offset[0] + 0.5) * grid.resolution
    cy = (rows + grid.offset[1] + 0.5) * grid.resolution
    assert (np.abs(cx) < ROOM[0] + half_diag).all() and (np.abs(cy) < ROOM[1] + half_diag).all()
    # The robot's own cell is free: it stands in the room.
    row, col = grid.cell_of(pose.x, pose.y)
    assert grid.values()[row, col] == FREE


@settings(max_examples=40, deadline=None)
@given(pose=poses, turn=st.floats(-math.pi, math.pi))
def test_the_same_beams_turned_in_the_scan_and_back_in_the_pose_give_the_same_cells(pose: Pose2D, turn: float) -> None:
    """A scan whose angles start `turn` later, at a pose turned `turn` back, sees the same world:
    the occupied cells agree but for beams whose end lies on a cell's edge (float rounding)."""
    beams = room_scan(pose)
    turned = Beams(beams.ranges, beams.angle_min + turn, INC, beams.range_min, beams.range_max)
    a, b = OccupancyMap(), OccupancyMap()
    a.integrate(beams, pose)
    b.integrate(turned, Pose2D(pose.x, pose.y, pose.yaw - turn))
    pa = {tuple(p) for p in np.round(a.occupied_points(), 6)}
    pb = {tuple(p) for p in np.round(b.occupied_points(), 6)}
    assert len(pa ^ pb) <= 4, (len(pa), len(pb), len(pa ^ pb))


@settings(max_examples=40, deadline=None)
@given(
    pose=poses,
    kinds=st.lists(st.sampled_from(["inf", "nan", "far", "-inf", "neg"]), min_size=BINS, max_size=BINS),
)
def test_free_rays_never_mark_anything_occupied(pose: Pose2D, kinds: list[str]) -> None:
    grid = OccupancyMap()
    grid.integrate(room_scan(Pose2D(0.0, 0.0, 0.0)), Pose2D(0.0, 0.0, 0.0))  # a map with walls
    before, offset = grid.logodds.copy(), grid.offset
    value = {"inf": np.inf, "nan": np.nan, "far": 25.0, "-inf": -np.inf, "neg": -1.0}
    r = np.array([value[k] for k in kinds], dtype=np.float32)
    got = grid.integrate(Beams(r, -math.pi, INC, 0.05, 10.0), pose)
    assert got.hits == 0 and got.no_return == kinds.count("inf") + kinds.count("far")
    assert got.nan == kinds.count("nan") and got.invalid == kinds.count("-inf") + kinds.count("neg")
    after = _window(grid, offset, before.shape)  # the grid may have grown round the old one
    assert (after <= before + 1e-6).all(), "a free ray raised a cell"
    assert (grid.values() == LETHAL).sum() <= (before >= grid.params.occupied_logodds).sum()


def _window(grid: OccupancyMap, offset: tuple[int, int], shape: tuple[int, ...]) -> np.ndarray:
    """The part of the grid that was a grid of `shape` at lattice `offset`."""
    r0, c0 = offset[1] - grid.offset[1], offset[0] - grid.offset[0]
    return grid.logodds[r0 : r0 + shape[0], c0 : c0 + shape[1]]


def walks(reach_m: float, n: int) -> st.SearchStrategy[list[Pose2D]]:
    """Up to `n` poses anywhere within `reach_m` of the origin."""
    xy = st.floats(-reach_m, reach_m)
    return st.lists(st.builds(Pose2D, xy, xy, st.floats(-math.pi, math.pi)), min_size=1, max_size=n)


@settings(max_examples=30, deadline=None)
@given(steps=walks(120.0, 8))
def test_the_grid_holds_its_cap(steps: list[Pose2D]) -> None:
    params = GridParams(resolution_m=0.1, max_size_m=30.0)
    grid = OccupancyMap(params)
    for pose in steps:
        ranges = np.full(BINS, 2.0, dtype=np.float32)  # a ring of returns 2 m round the robot
        before = grid.logodds.copy()
        try:
            got = grid.integrate(Beams(ranges, -math.pi, INC, 0.05, 10.0), pose)
        except ScanRefused as exc:
            assert exc.reason == "beyond_cap"
            assert np.array_equal(grid.logodds, before), "a refused scan changed the grid"
        else:
            assert got.hits == BINS
            row, col = grid.cell_of(pose.x, pose.y)
            assert 0 <= row < grid.shape[0] and 0 <= col < grid.shape[1]
        assert grid.shape[0] <= params.max_cells and grid.shape[1] <= params.max_cells


def _cells(grid: OccupancyMap) -> dict[tuple[int, int], float]:
    """Lattice cell -> log-odds, for every cell the grid has a word on."""
    rows, cols = np.nonzero(grid.logodds)
    return {(int(c) + grid.offset[0], int(r) + grid.offset[1]): float(grid.logodds[r, c])
            for r, c in zip(rows, cols, strict=True)}  # fmt: skip


@settings(max_examples=25, deadline=None)
@given(steps=walks(25.0, 6))
def test_growing_never_moves_a_cell(steps: list[Pose2D]) -> None:
    """Two grids that grow by different steps hold the same log-odds on the same world cells."""
    a = OccupancyMap(GridParams(resolution_m=0.1, max_size_m=100.0, grow_margin_m=0.3))
    b = OccupancyMap(GridParams(resolution_m=0.1, max_size_m=100.0, grow_margin_m=7.0))
    for pose in steps:
        ranges = np.full(BINS, 2.0, dtype=np.float32)
        ranges[::7] = np.inf
        for grid in (a, b):
            grid.integrate(Beams(ranges, -math.pi, INC, 0.05, 4.0), pose)
    assert _cells(a) == _cells(b)


def test_a_scan_that_reaches_past_the_cap_keeps_what_is_inside() -> None:
    grid = OccupancyMap(GridParams(resolution_m=0.1, max_size_m=10.0))
    grid.integrate(room_scan(Pose2D(0, 0, 0), room=(2.0, 2.0)), Pose2D(0, 0, 0))
    got = grid.integrate(room_scan(Pose2D(0, 0, 0), room=(9.0, 1.0)), Pose2D(0, 0, 0))
    assert got.beyond_cap > 0 and grid.shape[1] == 100
    with pytest.raises(ScanRefused, match="beyond_cap"):
        grid.integrate(room_scan(Pose2D(0, 0, 0)), Pose2D(30.0, 0.0, 0.0))


@pytest.mark.parametrize(
    "beams",
    [
        Beams(np.ones(BINS, np.float32), math.nan, INC, 0.05, 10.0),
        Beams(np.ones(BINS, np.float32), -math.pi, 0.0, 0.05, 10.0),
        Beams(np.ones(BINS, np.float32), -math.pi, INC, 5.0, 1.0),
        Beams(np.ones(0, np.float32), -math.pi, INC, 0.05, 10.0),
        Beams(np.ones(400, np.float32), -math.pi, INC, 0.05, 10.0),
    ],
)
def test_a_bad_geometry_is_refused_whole(beams: Beams) -> None:
    grid = OccupancyMap()
    grid.integrate(room_scan(Pose2D(0, 0, 0)), Pose2D(0, 0, 0))
    before = grid.logodds.copy()
    with pytest.raises(ScanRefused, match="bad_geometry"):
        grid.integrate(beams, Pose2D(0, 0, 0))
    assert np.array_equal(grid.logodds, before)


def test_a_moved_object_is_cleared_after_a_few_scans() -> None:
    grid = OccupancyMap()
    near = room_scan(Pose2D(0, 0, 0), room=(1.0, 3.0))  # a wall 1 m ahead ...
    for _ in range(20):
        grid.integrate(near, Pose2D(0, 0, 0))
    assert grid.values()[grid.cell_of(1.0, 0.02)] == LETHAL
    far = room_scan(Pose2D(0, 0, 0))  # ... taken away: the rays pass through
    for _ in range(10):  # (max_logodds - free_logodds) / miss: one second of a 10 Hz lidar
        grid.integrate(far, Pose2D(0, 0, 0))
    assert grid.values()[grid.cell_of(1.0, 0.02)] == FREE


def test_the_costmap_bands_follow_the_footprint() -> None:
    params = CostmapParams.for_footprint(0.70, 0.31, padding_m=0.0, inflation_m=0.8)
    assert params.inscribed_m == pytest.approx(0.155) and params.circumscribed_m == pytest.approx(0.3828, abs=1e-4)
    values = np.full((81, 81), FREE, dtype=np.int8)
    values[:, :5] = UNKNOWN
    values[40, 40] = LETHAL
    cost = inflate(values, 0.05, params)
    rows, cols = np.indices(values.shape)
    d = np.hypot(rows - 40, cols - 40) * 0.05
    assert (cost[d <= params.inscribed_m] == LETHAL).all()
    assert (cost[(d > params.inscribed_m) & (d <= params.circumscribed_m)] == INSCRIBED).all()
    falling = (d > params.circumscribed_m) & (d <= params.inflation_m)
    assert ((cost[falling] >= 1) & (cost[falling] <= 98)).all()
    order = np.argsort(d[falling])
    assert (np.diff(cost[falling][order].astype(int)) <= 0).all(), "the cost must fall with distance"
    assert (cost[(d > params.inflation_m) & (values == FREE)] == FREE).all()
    assert (cost[values == UNKNOWN] == UNKNOWN).all()
    assert (inflate(np.full((5, 5), UNKNOWN, np.int8), 0.05, params) == UNKNOWN).all()
