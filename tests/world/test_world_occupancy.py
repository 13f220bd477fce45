"""The occupancy map's pure core: scans place the world's walls where they are from any pose, free rays
never mark anything occupied, bad beams are dropped and counted, the grid holds its cap and never
moves a mapped cell, and the costmap's bands follow the footprint."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from maputil import BINS, INC, ROOM, room_scan, wall_distance

from go2vlm.world.occupancy import (
    CIRCUMSCRIBED,
    FREE,
    GAP_ANGLE,
    INSCRIBED,
    LETHAL,
    UNKNOWN,
    Beams,
    CostmapParams,
    GridParams,
    OccupancyMap,
    ScanRefused,
    bounded_distance,
    inflate,
)
from go2vlm.world.poses import Pose2D

OPEN = int(GAP_ANGLE / INC) + 1  # beams in a run without a return that is an opening, not a gap
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
@example(pose=Pose2D(0.0, 0.0, 0.0), turn=-1.049556665215586)  # three axis beams fell the other side
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
    # The 4 beams along the axes (0, +-90, 180 deg: 180 bins) end exactly on a cell edge (x or y = 0),
    # so each may fall either side in one map and the other: at most 2 cells apart each.
    assert len(pa ^ pb) <= 8, (len(pa), len(pb), len(pa ^ pb))


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
    # Only the obstacle and the inscribed radius block; the band out to the circumscribed radius costs
    # (CIRCUMSCRIBED..98: the planner checks the footprint's rectangle there, by heading).
    assert cost[40, 40] == LETHAL and (cost[(d > 0) & (d <= params.inscribed_m)] == INSCRIBED).all()
    ring = (d > params.inscribed_m) & (d <= params.circumscribed_m)
    assert ((cost[ring] >= CIRCUMSCRIBED) & (cost[ring] < INSCRIBED)).all()
    falling = (d > params.circumscribed_m) & (d <= params.inflation_m)
    assert ((cost[falling] >= 1) & (cost[falling] < CIRCUMSCRIBED)).all()
    order = np.argsort(d[falling])
    assert (np.diff(cost[falling][order].astype(int)) <= 0).all(), "the cost must fall with distance"
    order = np.argsort(d[ring])
    assert (np.diff(cost[ring][order].astype(int)) <= 0).all(), "... in the band too"
    assert (cost[(d > params.inflation_m) & (values == FREE)] == FREE).all()
    assert (cost[values == UNKNOWN] == UNKNOWN).all()
    assert (inflate(np.full((5, 5), UNKNOWN, np.int8), 0.05, params) == UNKNOWN).all()


@settings(max_examples=40, deadline=None)
@given(pose=poses, holes=st.sets(st.integers(0, BINS - 1), max_size=40))
def test_a_lone_beam_without_a_return_never_clears_through_a_wall(pose: Pose2D, holes: set[int]) -> None:
    """Bins a cloud left empty (+inf between two returns) clear only to their neighbours' walls; a run
    wider than GAP_ANGLE (with far returns round them) is an opening and clears to range_max."""
    beams = room_scan(pose)
    ranges = beams.ranges.copy()
    lone = {i for i in holes if (i - 1) % BINS not in holes and (i + 1) % BINS not in holes}
    ranges[sorted(lone)] = np.inf
    grid = OccupancyMap()
    grid.integrate(Beams(ranges, beams.angle_min, INC, beams.range_min, beams.range_max), pose)
    rows, cols = np.nonzero(grid.values() == FREE)
    cx = (cols + grid.offset[0] + 0.5) * grid.resolution
    cy = (rows + grid.offset[1] + 0.5) * grid.resolution
    tol = grid.resolution * math.sqrt(2) / 2  # the wall's own cells may be half free
    assert (np.abs(cx) < ROOM[0] + tol).all() and (np.abs(cy) < ROOM[1] + tol).all(), "free space past a wall"
    near = int(np.argmin(beams.ranges))  # an open door in the nearest wall (within no_return_m) ...
    opening = beams.ranges.copy()
    opening[np.arange(near - 1, near + OPEN) % BINS] = np.inf
    fresh = OccupancyMap()
    fresh.integrate(Beams(opening, beams.angle_min, INC, beams.range_min, beams.range_max), pose)
    rows, cols = np.nonzero(fresh.values() == FREE)
    cx = (cols + fresh.offset[0] + 0.5) * fresh.resolution
    cy = (rows + fresh.offset[1] + 0.5) * fresh.resolution
    assert ((np.abs(cx) > ROOM[0] + tol) | (np.abs(cy) > ROOM[1] + tol)).any(), "... clears past it"


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), band=st.integers(1, 40))
def test_the_costmap_in_bands_is_the_costmap_whole(seed: int, band: int) -> None:
    rng = np.random.default_rng(seed)
    values = rng.choice(np.array([UNKNOWN, FREE, LETHAL], np.int8), size=(60, 45), p=[0.3, 0.68, 0.02])
    params = CostmapParams.for_footprint(0.70, 0.31)
    assert np.array_equal(inflate(values, 0.05, params, band_rows=band), inflate(values, 0.05, params, band_rows=10**6))


def _free_past_walls(grid: OccupancyMap, room: tuple[float, float] = ROOM) -> int:
    rows, cols = np.nonzero(grid.values() == FREE)
    cx = (cols + grid.offset[0] + 0.5) * grid.resolution
    cy = (rows + grid.offset[1] + 0.5) * grid.resolution
    tol = grid.resolution * math.sqrt(2) / 2
    return int(((np.abs(cx) > room[0] + tol) | (np.abs(cy) > room[1] + tol)).sum())


@settings(max_examples=30, deadline=None)
@given(start=st.integers(0, BINS - 1), width=st.integers(OPEN, 120))
def test_a_ray_without_a_return_clears_what_it_passes_through(start: int, width: int) -> None:
    """A wall on the map, then an opening in the scan (beams without a return, wider than a gap in the
    sampling): the rays looked and saw nothing, so the wall they pass through has gone (a door opened).
    They clear it after a few scans, out to no_return_m and no farther; the walls off the opening stay."""
    room = (1.02, 0.98)  # near walls: the returns 2 degrees apart fall in neighbouring cells
    pose = Pose2D(0.0, 0.0, 0.0)
    beams = room_scan(pose, room=room)
    grid = OccupancyMap()
    grid.integrate(beams, pose)
    opening = beams.ranges.copy()
    idx = np.arange(start, start + width) % BINS
    opening[idx] = np.inf
    for _ in range(10):  # (max_logodds - free_logodds) / miss scans at most
        grid.integrate(Beams(opening, beams.angle_min, INC, beams.range_min, beams.range_max), pose)
    values = grid.values()
    angles = beams.angle_min + INC * idx[1:-1]  # the opening's inner beams (its edges share cells)
    for a in angles:
        r = min(room[0] / max(abs(math.cos(a)), 1e-9), room[1] / max(abs(math.sin(a)), 1e-9))
        x, y = r * math.cos(a), r * math.sin(a)
        assert values[grid.cell_of(x, y)] == FREE, f"the wall at {math.degrees(a):.0f} deg stayed"
    reach = GridParams().no_return_m + grid.resolution
    rows, cols = np.nonzero(values == FREE)
    xs, ys = (cols + grid.offset[0] + 0.5) * grid.resolution, (rows + grid.offset[1] + 0.5) * grid.resolution
    assert float(np.hypot(xs, ys).max()) <= reach
    inside = set(idx.tolist())
    kept = [k for k in range(BINS) if all((k + d) % BINS not in inside for d in range(-3, 4))]
    for k in kept:  # the walls off the opening (three beams clear of it) stay
        a = beams.angle_min + INC * k
        assert values[grid.cell_of(beams.ranges[k] * math.cos(a), beams.ranges[k] * math.sin(a))] == LETHAL, k


def test_an_obstacle_taken_away_is_cleared_by_rays_with_or_without_a_return() -> None:
    """A door leaf 1 m ahead, mapped; then it opens. Behind it a wall 3 m off clears it in a few scans;
    with nothing behind it (no return within range_max, over more than a gap in the sampling) it is
    cleared all the same."""
    pose = Pose2D(0.0, 0.0, 0.0)
    for behind in (3.0, math.inf):
        grid = OccupancyMap()
        box = room_scan(pose, room=(3.0, 3.0)).ranges.copy()
        ahead = np.abs(np.arange(BINS) - BINS // 2) <= OPEN // 2 + 1  # the beams round 0 rad (angle_min = -pi)
        box[ahead] = 1.0
        for _ in range(20):
            grid.integrate(Beams(box, -math.pi, INC, 0.05, 10.0), pose)
        assert grid.values()[grid.cell_of(1.0, 0.0)] == LETHAL
        gone = box.copy()
        gone[ahead] = behind
        for _ in range(15):
            grid.integrate(Beams(gone, -math.pi, INC, 0.05, 10.0), pose)
        assert grid.values()[grid.cell_of(1.0, 0.0)] == FREE, behind


def test_a_run_beside_a_near_object_is_the_lidars_shadow_not_an_opening() -> None:
    """The Go2's lidar sits 0.29 m ahead of the base: an object 0.2 m away hides a wide run of bins
    from it, bounded by far returns; the object two beams aside makes the run a gap."""
    pose = Pose2D(0.0, 0.0, 0.0)
    beams = room_scan(pose)
    ranges = beams.ranges.copy()
    run = np.arange(60, 60 + OPEN + 2)  # wider than GAP_ANGLE and than the far returns' parallax
    ranges[run] = np.inf
    ranges[57:59] = 0.2  # the near object, a beam before the run's bounding return
    grid = OccupancyMap()
    grid.integrate(Beams(ranges, beams.angle_min, INC, beams.range_min, beams.range_max, sensor=(0.29, 0.0)), pose)
    assert _free_past_walls(grid) == 0
    without = OccupancyMap()  # the same run with no near object beside it is an opening
    ranges[57:59] = beams.ranges[57:59]
    without.integrate(Beams(ranges, beams.angle_min, INC, beams.range_min, beams.range_max, sensor=(0.29, 0.0)), pose)
    assert _free_past_walls(without) > 0


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), h=st.integers(1, 40), w=st.integers(1, 40), frac=st.floats(0.0, 0.2),
       max_cells=st.integers(0, 20))  # fmt: skip
def test_the_bounded_distance_is_scipys_within_its_bound(
    seed: int, h: int, w: int, frac: float, max_cells: int
) -> None:
    from scipy import ndimage

    occ = np.random.default_rng(seed).random((h, w)) < frac
    got = bounded_distance(occ, max_cells)
    if not occ.any():
        assert np.isinf(got).all()
        return
    want = ndimage.distance_transform_edt(~occ)
    near = want <= max_cells
    assert np.allclose(got[near], want[near])
    assert np.isinf(got[~near]).all()


@settings(max_examples=40, deadline=None)
@given(pose=poses)
def test_one_scan_leaves_no_unseen_sliver_between_its_beams(pose: Pose2D) -> None:
    """The free space a scan shows is the wedge between neighbouring beams: 2 degrees apart, beams leave
    more than a cell between them from 1.4 m on, and an unseen sliver across a 0.75 m doorway seen from
    3.6 m cut it in two for the planner (houses 002). Every cell of the room off its walls is free."""
    grid = OccupancyMap()
    grid.integrate(room_scan(pose), pose)
    values = grid.values()
    rows, cols = np.indices(values.shape)
    cx = (cols + grid.offset[0] + 0.5) * grid.resolution
    cy = (rows + grid.offset[1] + 0.5) * grid.resolution
    inner = (np.abs(cx) < ROOM[0] - 0.25) & (np.abs(cy) < ROOM[1] - 0.25)
    assert inner.any() and (values[inner] == FREE).all(), int((values[inner] != FREE).sum())


def test_the_rays_between_beams_never_clear_what_the_map_holds() -> None:
    """A post one cell across, mapped from 1 m; then seen from 4 m where it lies between two beams (both
    pass beside it): the rays filled in between them clear the free wedge but not the post."""
    here = Pose2D(0.0, 0.025, 0.0)
    near = room_scan(here).ranges.copy()
    near[BINS // 2] = 1.0  # the beam at 0 rad meets the post's cell (1.0..1.05, 0..0.05)
    grid = OccupancyMap()
    for _ in range(20):
        grid.integrate(Beams(near, -math.pi, INC, 0.05, 10.0), here)
    post = grid.cell_of(1.025, 0.025)
    assert grid.values()[post] == LETHAL
    far = Pose2D(-3.0, 0.025, INC / 2)  # the post at bearing 0: half a beam from the nearest on either side
    for _ in range(15):
        grid.integrate(room_scan(far), far)
    assert grid.values()[post] == LETHAL
    assert grid.values()[grid.cell_of(0.0, 0.025)] == FREE  # the wedge before it is seen


def _seen(sensor: tuple[float, float], boxes: list[tuple[float, float, float, float]], n: int = 3600) -> np.ndarray:
    """The points a lidar at `sensor` sees of axis-aligned boxes (x0, y0, x1, y1): its rays' first hits."""
    a = np.arange(n) * 2 * math.pi / n
    dx, dy = np.cos(a), np.sin(a)
    best = np.full(n, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for x0, y0, x1, y1 in boxes:  # the slab test
            tx = np.sort(np.stack([(x0 - sensor[0]) / dx, (x1 - sensor[0]) / dx]), axis=0)
            ty = np.sort(np.stack([(y0 - sensor[1]) / dy, (y1 - sensor[1]) / dy]), axis=0)
            near, far = np.maximum(tx[0], ty[0]), np.minimum(tx[1], ty[1])
            best = np.where((near <= far) & (near > 0) & (near < best), near, best)
    ok = np.isfinite(best)
    return np.column_stack([sensor[0] + best[ok] * dx[ok], sensor[1] + best[ok] * dy[ok]])


def _binned(points: np.ndarray, pose: Pose2D) -> Beams:
    """World points seen by a sensor, binned as /scan is: by bearing from the base origin, at their range."""
    dx, dy = points[:, 0] - pose.x, points[:, 1] - pose.y
    bearing = (np.arctan2(dy, dx) - pose.yaw + math.pi) % (2 * math.pi) - math.pi
    rng = np.hypot(dx, dy)
    ranges = np.full(360, np.inf)
    k = np.floor((bearing + math.pi) / math.radians(1.0)).astype(int) % 360
    np.minimum.at(ranges, k, rng)
    return Beams(ranges, -math.pi + math.radians(0.5), math.radians(1.0), 0.05, 8.0, sensor=(0.29, 0.0))


def test_a_robot_in_a_doorway_does_not_wear_away_the_wall_beside_it() -> None:
    """A room 6 x 6 m cut in two along y = 0 by a wall 0.1 m thick with a 0.8 m door. The robot stands
    in the door facing north, its base behind the wall's plane and its lidar, 0.29 m ahead, past it:
    the lidar sees the wall's north face at a slant. Those returns prove free the segments from the
    lidar, north of the wall; beams drawn from the base ran through the wall and wore it away."""
    door = [(-3.0, -0.05, -0.4, 0.05), (0.4, -0.05, 3.0, 0.05)]
    boxes = [*door, (-3.1, -3.0, -3.0, 3.0), (3.0, -3.0, 3.1, 3.0), (-3.0, 3.0, 3.0, 3.1), (-3.0, -3.1, 3.0, -3.0)]
    before, in_door = Pose2D(0.0, -1.5, math.pi / 2), Pose2D(0.0, -0.15, math.pi / 2)
    first = _binned(_seen((0.0, -1.21), boxes), before)  # from the south, base and lidar alike
    scan = _binned(_seen((0.0, 0.14), boxes), in_door)
    lost = {}
    for sensor in ((0.29, 0.0), None):
        grid = OccupancyMap()
        for _ in range(5):
            grid.integrate(first, before)
        wall = [grid.cell_of(x, y) for x in np.arange(-2.5, -0.6, 0.05) for y in (-0.07, -0.03, 0.02)]
        was = {c for c in wall if grid.values()[c] == 100}
        for _ in range(10):
            grid.integrate(Beams(scan.ranges, scan.angle_min, scan.angle_increment, scan.range_min,
                                 scan.range_max, sensor=sensor), in_door)  # fmt: skip
        lost[sensor] = sum(grid.values()[c] != 100 for c in was) / len(was)
    assert lost[(0.29, 0.0)] == 0.0, lost
    assert lost[None] > 0.3, lost  # the base's beams: the wall worn away
