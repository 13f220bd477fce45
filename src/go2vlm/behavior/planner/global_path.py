"""The global planner: the shortest safe path on the map's inflated costmap, as waypoints. Pure (no
DDS); the navigator (behavior/navigate/) follows it, and the safety gate's guard keeps the last word.

The costmap is a ROS-convention grid (nav_msgs/OccupancyGrid's data, the codes of world/occupancy.py):
int8, rows = y, cols = x; -1 unknown, 0 free, 1..98 the inflation's cost gradient (90..98, from
CIRCUMSCRIBED: the footprint fits at some headings only), >= `lethal` (99, the footprint's inscribed
radius, and 100, an obstacle) never entered. `origin` is the world (x, y) of cell (0, 0)'s corner.

The footprint, by heading: where the path crosses the band between the inscribed and the
circumscribed radius (a doorway, a gap between furniture), the robot's rectangle, with the clearance
kept at a creep (geometry/footprint.py `Clearance`), is checked at the heading the path gives it there
(the robot walks along its path) against the obstacle cells. A path whose rectangle would touch is
searched again by heading (planner/by_heading.py: over (cell, line) states, a band cell entered and
left along a line the rectangle fits, turning to the next line where the rectangle sweeps clear),
which through a doorway is square-on. Waypoints keep the
check: a shortcut through the band is taken only where the rectangle fits along it.

Search: scikit-image's `graph.MCP_Geometric` (Dijkstra, 8-connected, each step costing its length
times the mean of the two cells' costs: geometric, so a diagonal costs sqrt(2)), chosen by
measurement against pyastar2d's A* and scipy's csgraph (benchmarks/bench_planner.py, the figures in
docs/navigation.md): one search settles the costs to *every* goal cell (the nearest of many
frontiers, the nearest free cell round an object), and its costs are Euclidean. A grid of more
than `max_cells` cells is first planned coarse, by the smallest whole factor that fits, each coarse
cell as cheap as its cheapest fine cell (so a doorway narrower than a coarse cell is never closed by
it), then again at full resolution within a corridor of coarse cells round that path (and on the
whole grid when the corridor holds no way): the plan is always the fine grid's.

Unknown space (`unknown_cost`): the cost per cell of crossing an unknown cell; `math.inf` never
crosses one (exploring crosses it cheaply; a go to a remembered object only where no known way exists).

Start and goal: a start on a lethal cell (the robot inside the inflation, by a wall) plans from the
nearest passable cell within `escape_m`; any passable cell within `goal_tolerance_m` of the goal is
the goal (an object is itself an obstacle on the map: the path ends beside it); with `goal_turnable`
(a stand to look round from) only those where the footprint turns in place, where there are any.
With `goal_in_sight` (a place to look at: an object) only those in sight of it: the straight line to
the goal crosses no obstacle cell farther than `goal_body_m` from it, or that belongs to a piece of
obstacle lying wholly within `goal_body_m + goal_own_m` of it (the object's own cells hide nothing,
where a remembered place is off by up to `goal_own_m`; a wall running past is no such piece); a cell
near the goal but behind a wall from it is not there (a duck seen through a doorway from beside its jamb
is within a metre of the jamb's far side). A frontier is not asked: its goal often lies in a gap of
a wall the map is still drawing, and which side sees it changes with each scan. A refusal says why:
outside the map, boxed in, the goal inside an obstacle, or cut off.

Waypoints: the dense cell path pruned by line of sight: from each waypoint the next is the farthest
path cell reachable in a straight line that crosses no cell costlier than the stretch of path it
replaces (a shortcut never goes nearer an obstacle than the path did).

Replanning: `Route` (planner/route.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from go2vlm.behavior.planner.by_heading import by_heading, footprint_fits, path_headings, turn_reach
from go2vlm.behavior.planner.grid import Costmap, Found, GlobalParams, Plan
from go2vlm.behavior.planner.sight import in_sight
from go2vlm.world.occupancy import CIRCUMSCRIBED, UNKNOWN

__all__ = [
    "Costmap",
    "GlobalParams",
    "Plan",
    "cell_costs",
    "chain_cost",
    "costs_of",
    "footprint_fits",
    "goal_costs",
    "in_sight",
    "line_cells",
    "passable",
    "plan_path",
]

NO_FIT = "unreachable: no way the footprint fits through (every way crosses a gap too narrow)"


def cell_costs(cm: Costmap, p: GlobalParams, k: int = 1) -> np.ndarray:
    """float64 cost of entering each cell (inf: never), on the grid coarsened by `k`: each k x k
    block as cheap as its cheapest known cell (unknown where all are; the edge padded unknown). A
    coarse plan is a guide, not a path: it never closes a gap a fine cell leaves open."""
    d = cm.data
    if k > 1:
        h, w = d.shape
        hh, ww = -(-h // k) * k, -(-w // k) * k
        pad = np.full((hh, ww), UNKNOWN, np.int8)
        pad[:h, :w] = d
        known = np.where(pad == UNKNOWN, np.int8(127), pad)
        d = known.reshape(hh // k, k, ww // k, k).min(axis=3).min(axis=1)
        d[d == 127] = UNKNOWN
    return costs_of(d, p)


def costs_of(d: np.ndarray, p: GlobalParams) -> np.ndarray:
    """The cost of entering cells of costmap values `d` (inf: never): `cell_costs` cell by cell."""
    unknown = d == UNKNOWN
    v = d.astype(np.int16)
    c = 1.0 + p.cost_scale * np.clip(v, 0, 100) / 100.0
    c[unknown] = p.unknown_cost
    c[v >= p.lethal] = np.inf
    c[v < UNKNOWN] = np.inf  # not a ROS occupancy value: never entered
    return c


def passable(cm: Costmap, cells: np.ndarray, p: GlobalParams) -> np.ndarray:
    """bool per (row, col) of `cells`: may it be entered (inside the grid, below lethal, and known
    unless unknown may be crossed)? Only those cells are read (a check along a line, not the grid)."""
    cells = np.asarray(cells, dtype=int).reshape(-1, 2)
    h, w = cm.shape
    inside = (cells[:, 0] >= 0) & (cells[:, 0] < h) & (cells[:, 1] >= 0) & (cells[:, 1] < w)
    v = np.full(len(cells), 100, np.int16)
    v[inside] = cm.data[cells[inside, 0], cells[inside, 1]]
    ok = (v >= 0) & (v < p.lethal)
    if math.isfinite(p.unknown_cost):
        ok |= v == UNKNOWN
    return ok & inside


def stride_for(shape: tuple[int, int], max_cells: int) -> int:
    return max(1, math.ceil(math.sqrt(shape[0] * shape[1] / max_cells)))


def line_cells(a: tuple[int, int], b: tuple[int, int]) -> np.ndarray:
    """(N, 2) cells a straight line from cell a to cell b passes through (8-connected, a and b included)."""
    n = max(abs(b[0] - a[0]), abs(b[1] - a[1]))
    if n == 0:
        return np.array([a], dtype=int)
    # One cell per step along the longer axis (Bresenham's 8-connected line, as the path itself moves):
    # half steps would put a diagonal step's midpoint, a cell corner, into one of the two cells beside
    # the step, and a diagonal step past an obstacle's corner would read as crossing it.
    t = np.linspace(0.0, 1.0, n + 1)
    rows = np.floor(a[0] + t * (b[0] - a[0]) + 0.5).astype(int)
    cols = np.floor(a[1] + t * (b[1] - a[1]) + 0.5).astype(int)
    cells = np.column_stack((rows, cols))
    keep = np.ones(len(cells), bool)
    keep[1:] = np.any(np.diff(cells, axis=0) != 0, axis=1)
    return cells[keep]


def chain_cost(c: np.ndarray, cells: np.ndarray) -> float:
    """MCP_Geometric's cost of walking `cells` (adjacent, 8-connected) on cost grid `c`."""
    cells = np.asarray(cells, dtype=int)
    if len(cells) < 2:
        return 0.0
    v = c[cells[:, 0], cells[:, 1]]
    step = np.hypot(*np.diff(cells, axis=0).T)
    return float(np.sum(step * 0.5 * (v[1:] + v[:-1])))


def _nearest_passable(c: np.ndarray, rc: tuple[int, int], radius: int) -> tuple[int, int] | None:
    r0, c0 = max(0, rc[0] - radius), max(0, rc[1] - radius)
    win = c[r0 : rc[0] + radius + 1, c0 : rc[1] + radius + 1]
    ok = np.argwhere(np.isfinite(win))
    if len(ok) == 0:
        return None
    d = np.hypot(ok[:, 0] + r0 - rc[0], ok[:, 1] + c0 - rc[1])
    i = int(np.argmin(d))
    if d[i] > radius:
        return None
    return int(ok[i, 0] + r0), int(ok[i, 1] + c0)


def _goal_cells(c: np.ndarray, rc: tuple[int, int], radius: int) -> np.ndarray:
    """Passable cells within `radius` cells of `rc` ((N, 2) row, col)."""
    r0, c0 = max(0, rc[0] - radius), max(0, rc[1] - radius)
    win = c[r0 : rc[0] + radius + 1, c0 : rc[1] + radius + 1]
    ok = np.argwhere(np.isfinite(win)) + (r0, c0)
    return ok[np.hypot(ok[:, 0] - rc[0], ok[:, 1] - rc[1]) <= radius + 1e-9]


def prune(c: np.ndarray, cells: np.ndarray, fits: Callable[[np.ndarray, float], bool] | None = None) -> list[int]:
    """Indices into `cells` (a dense path on cost grid `c`) kept as waypoints: line-of-sight pruning
    that never crosses a cell costlier than the stretch it replaces, and (`fits`) only where the
    footprint fits along the line at its heading. From each waypoint the next is
    found by galloping then bisecting over the path (each candidate line checked): O(log n) checks
    a leg, not one a cell; a leg may stop short of the farthest visible cell, never go past a
    blocked one."""
    n = len(cells)
    if n <= 2:
        return list(range(n))
    v = c[cells[:, 0], cells[:, 1]]

    def clear(i: int, j: int) -> bool:
        line = line_cells(tuple(cells[i]), tuple(cells[j]))
        if not (c[line[:, 0], line[:, 1]] <= v[i : j + 1].max()).all():
            return False
        heading = math.atan2(cells[j][0] - cells[i][0], cells[j][1] - cells[i][1])
        return fits is None or fits(line, heading)

    keep = [0]
    i = 0
    while i < n - 1:
        good, step = i + 1, 1  # i + 1 is the path's own next cell: always clear
        while good + step < n and clear(i, good + step):
            good += step
            step *= 2
        bad = min(good + step, n)  # the first candidate found blocked (or past the end)
        while bad - good > 1:
            mid = (good + bad) // 2
            if clear(i, mid):
                good = mid
            else:
                bad = mid
        keep.append(good)
        i = good
    return keep


def plan_path(
    cm: Costmap,
    start: tuple[float, float],
    goals: Sequence[tuple[float, float]],
    p: GlobalParams,
) -> Plan:
    """The cheapest path from world point `start` to the nearest (by path cost) of `goals` (one
    point, or several: frontiers) along which the footprint fits, or a refusal with its reason (`ok`
    False). Where no way keeps `clearance_m`, one that keeps `tight_clearance_m` ("tight": walked at
    the speed its gaps allow; docs/navigation.md "Tight, at a crawl")."""
    plan = _plan_path(cm, start, goals, p)
    if not plan.ok and plan.reason == NO_FIT and p.tight_clearance_m < p.clearance_m:
        tight = _plan_path(cm, start, goals, replace(p, clearance_m=p.tight_clearance_m))
        if tight.ok:
            why = f"{tight.reason}, tight ({p.tight_clearance_m:g} m clear: a crawl)"
            return replace(tight, reason=why, tight=True)
    return plan


def _plan_path(cm: Costmap, start: tuple[float, float], goals: Sequence[tuple[float, float]], p: GlobalParams) -> Plan:
    goal_list = list(goals)
    if not goal_list:
        return Plan(False, "no goal to plan to")
    if not all(math.isfinite(v) for v in start) or not all(math.isfinite(v) for g in goal_list for v in g):
        return Plan(False, "start or goal is not a finite point")
    k = stride_for(cm.shape, p.max_cells)
    c = cell_costs(cm, p)
    if k > 1:  # a coarse guide first, then the fine grid round it
        guide = _search(cm, cell_costs(cm, p, k), k, start, goal_list, p)
        assert not isinstance(guide, np.ndarray)
        if isinstance(guide, Plan):
            return replace(guide, stride=k)
        near = np.zeros((-(-cm.shape[0] // k), -(-cm.shape[1] // k)), bool)
        near[guide.dense[:, 0], guide.dense[:, 1]] = True
        near = _dilate(near)
        corridor = np.repeat(np.repeat(near, k, axis=0), k, axis=1)[: cm.shape[0], : cm.shape[1]]
        plan = _fitting(cm, np.where(corridor, c, np.inf), start, goal_list, p)
        if plan.ok:
            return replace(plan, stride=k)
    return _fitting(cm, c, start, goal_list, p)


def goal_costs(
    cm: Costmap, start: tuple[float, float], goals: Sequence[tuple[float, float]], p: GlobalParams
) -> np.ndarray:
    """The path cost (m, weighted as a plan's) from world point `start` to each of `goals` (inf: no
    way, or no passable cell near it): one search to them all, on the grid coarsened as plan_path's
    guide is when it is large (a cost to choose by, not a path)."""
    goal_list = list(goals)
    if not goal_list:
        return np.zeros(0)
    k = stride_for(cm.shape, p.max_cells)
    got = _search(cm, cell_costs(cm, p, k), k, start, goal_list, p, every=True)
    return got if isinstance(got, np.ndarray) else np.full(len(goal_list), np.inf)


def _search(
    cm: Costmap,
    c: np.ndarray,
    k: int,
    start: tuple[float, float],
    goal_list: list[tuple[float, float]],
    p: GlobalParams,
    every: bool = False,
) -> Found | Plan | np.ndarray:
    """One search on cost grid `c` (the costmap coarsened by `k`): the cell path, or a refusal; with
    `every`, the cost (m, weighted) to each goal instead (inf: no way)."""
    res = cm.resolution * k
    cm_k = Costmap(np.zeros((1, 1), np.int8), res, cm.origin)
    s = cm_k.cell(*start)
    if not (0 <= s[0] < c.shape[0] and 0 <= s[1] < c.shape[1]):
        return Plan(False, f"the robot at ({start[0]:.2f}, {start[1]:.2f}) is outside the map")
    s_from = s
    if not np.isfinite(c[s]):
        radius = int(round(p.escape_m / res))
        esc = _nearest_passable(c, s, radius) if radius > 0 else None
        if esc is None:
            return Plan(False, f"boxed in: no passable cell within {p.escape_m:g} m of the robot")
        s_from = esc
    radius = max(0, int(round(p.goal_tolerance_m / res)))
    ends: list[tuple[int, int]] = []
    owner: list[int] = []
    outside = 0
    for gi, g in enumerate(goal_list):
        gc = cm_k.cell(*g)
        if not (-radius <= gc[0] < c.shape[0] + radius and -radius <= gc[1] < c.shape[1] + radius):
            outside += 1
            continue
        cells = _goal_cells(c, gc, radius)
        # a coarse guide's goal cells are a guide's: the fine search keeps those in sight
        if k == 1 and p.goal_in_sight:
            cells = cells[in_sight(cm.data, cells, gc, p.goal_body_m / res, p.goal_own_m / res)]
        if k == 1 and p.goal_turnable and len(cells):
            v = cm.data[cells[:, 0], cells[:, 1]]
            turnable = (v >= 0) & (v < CIRCUMSCRIBED)
            cells = cells[turnable] if turnable.any() else cells
        ends += [(int(a), int(b)) for a, b in cells]
        owner += [gi] * len(cells)
    if not ends:
        if outside == len(goal_list):
            return Plan(False, "the goal is outside the map")
        seen = " and in sight of it" if p.goal_in_sight else ""
        return Plan(
            False, f"the goal is inside an obstacle: no passable cell within {p.goal_tolerance_m:g} m of it{seen}"
        )
    from skimage.graph import MCP_Geometric  # the nav extra; imported here so a commander without a map needs none

    mcp = MCP_Geometric(c, fully_connected=True)
    costs, _ = mcp.find_costs([s_from], ends, find_all_ends=every)
    end_arr = np.array(ends)
    end_costs = costs[end_arr[:, 0], end_arr[:, 1]]
    if every:
        per_goal = np.full(len(goal_list), np.inf)
        np.minimum.at(per_goal, np.array(owner), np.where(np.isfinite(end_costs), end_costs, np.inf) * res)
        return per_goal
    best = int(np.argmin(end_costs))
    if not np.isfinite(end_costs[best]):
        how = "obstacles and unknown space" if math.isinf(p.unknown_cost) else "obstacles"
        return Plan(False, f"unreachable: {how} cut the goal off from the robot")
    e = (int(end_arr[best, 0]), int(end_arr[best, 1]))
    dense = np.array(mcp.traceback(e), dtype=int).reshape(-1, 2)
    if s_from != s:
        dense = np.vstack((np.array([s]), dense))
    return Found(dense, s, s_from != s, e, float(end_costs[best]) * res, owner[best], end_arr, np.array(owner))


def _fitting(
    cm: Costmap, c: np.ndarray, start: tuple[float, float], goal_list: list[tuple[float, float]], p: GlobalParams
) -> Plan:
    """The search at full resolution; where its path's footprint touches in the band, the search by
    heading instead (module docstring); and the path's waypoints."""
    found = _search(cm, c, 1, start, goal_list, p)
    assert not isinstance(found, np.ndarray)
    if isinstance(found, Plan):
        return found
    skip = turn_reach(p, cm.resolution)
    dense = found.dense
    v = cm.data[dense[:, 0], dense[:, 1]]
    check = (v >= CIRCUMSCRIBED) & (v < p.lethal)
    check[:skip] = check[-skip:] = False  # round the start it turns where it stands; round the goal, to look
    idx = np.nonzero(check)[0]
    if not footprint_fits(cm, dense[idx], path_headings(dense)[idx], p).all():
        squared = by_heading(cm, c, found, p)
        if squared is None:
            return Plan(False, NO_FIT)
        found = squared
        dense = found.dense

    def fits(line: np.ndarray, heading: float) -> bool:
        lv = cm.data[line[:, 0], line[:, 1]]
        band = (lv >= CIRCUMSCRIBED) & (lv < p.lethal)
        band[: min(skip, len(band))] &= found.start != (int(line[0, 0]), int(line[0, 1]))
        return bool(footprint_fits(cm, line[band], np.full(int(band.sum()), heading), p).all())

    keep = prune(_with_start(c, found.start) if found.escaped else c, dense, fits)
    pts = cm.world(dense[keep, 0], dense[keep, 1])
    pts[0] = start
    length = float(np.sum(np.hypot(*np.diff(pts, axis=0).T))) if len(pts) > 1 else 0.0
    gxy = cm.world(np.array([found.goal[0]]), np.array([found.goal[1]]))[0]
    return Plan(
        True,
        f"{length:.1f} m in {len(pts) - 1} legs",
        waypoints=pts,
        cost=found.cost,
        length=length,
        goal=(float(gxy[0]), float(gxy[1])),
        goal_index=found.goal_index,
        stride=1,
        cells=dense,
    )


def _dilate(m: np.ndarray) -> np.ndarray:
    """`m` grown by one cell (8-connected)."""
    out = m.copy()
    out[1:] |= m[:-1]
    out[:-1] |= m[1:]
    grown = out.copy()
    grown[:, 1:] |= out[:, :-1]
    grown[:, :-1] |= out[:, 1:]
    return grown


def _with_start(c: np.ndarray, s: tuple[int, int]) -> np.ndarray:
    """The cost grid with the (lethal) start cell passable, for pruning a path that escapes from it."""
    c2 = c.copy()
    c2[s] = np.nanmax(np.where(np.isfinite(c), c, np.nan))  # the dearest passable cell's cost
    return c2
