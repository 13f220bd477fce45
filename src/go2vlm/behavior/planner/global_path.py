"""The global planner: the shortest safe path on the map's inflated costmap, as waypoints. Pure (no
DDS); the commander hands the next waypoint to its approach and its local planner, and the safety
gate and its collision guard keep the last word.

The costmap is a ROS-convention grid (nav_msgs/OccupancyGrid's data, the codes of world/occupancy.py):
int8, rows = y, cols = x; -1 unknown, 0 free, 1..98 the inflation's cost gradient (90..98, from
CIRCUMSCRIBED: the footprint fits at some headings only), >= `lethal` (99, the footprint's inscribed
radius, and 100, an obstacle) never entered. `origin` is the world (x, y) of cell (0, 0)'s corner.

The footprint, by heading: where the path crosses the band between the inscribed and the
circumscribed radius (a doorway, a gap between furniture), the robot's rectangle, with the clearance
kept at a creep (geometry/footprint.py `Clearance`), is checked at the heading the path gives it there
(the robot walks along its path) against the obstacle cells. A path whose rectangle would touch has
the cells where it does closed and is searched again (at most `footprint_replans` times): what is left
is the way the footprint fits, which through a doorway is square-on. Waypoints keep the check: a
shortcut through the band is taken only where the rectangle fits along it.

Search: scikit-image's `graph.MCP_Geometric` (Dijkstra, 8-connected, each step costing its length
times the mean of the two cells' costs: geometric, so a diagonal costs sqrt(2)). Chosen by
measurement (benchmarks/bench_planner.py, docs/navigation.md): on a 1200 x 1200 house (60 x 60 m
at 5 cm, the map's cap) corner to corner it takes 0.54 s of CPU, pyastar2d's A* 0.14 s and scipy's
csgraph 1.2 s with its graph build. MCP wins on what the planner is for: one search settles the
costs to *every* goal cell, so the nearest of many frontiers (by path cost), or the nearest free
cell round an object, comes from one search that stops at the first goal reached; A* needs one
search per goal. And its costs are Euclidean (pyastar2d's diagonal costs as much as a straight
step: its paths measure ~9 % longer). A full replan across the largest world (the apartment,
303 x 223 cells) takes 15 ms. A grid of more than `max_cells` cells is first planned coarse, by the
smallest whole factor that fits, each coarse cell as cheap as its cheapest fine cell (a coarse cell
is passable when any of its fine cells is, so a doorway narrower than a coarse cell is never closed
by it), then again at full resolution within a corridor of coarse cells round that path (and on the
whole grid when the corridor holds no way): the plan is always the fine grid's.

Unknown space (`unknown_cost`): the cost per cell of crossing an unknown cell; `math.inf` never
crosses one. Exploration crosses unknown at a small cost (a frontier's goal is at the edge of the
known); a go to a remembered object prefers known free space (a high cost: unknown only where no
known way exists).

Start and goal: a start on a lethal cell (the robot inside the inflation, by a wall) plans from the
nearest passable cell within `escape_m`; any passable cell within `goal_tolerance_m` of the goal is
the goal (an object is itself an obstacle on the map: the path ends beside it). A refusal says why:
outside the map, boxed in, the goal inside an obstacle, or cut off.

Waypoints: the dense cell path pruned by line of sight: from each waypoint the next is the farthest
path cell reachable in a straight line that crosses no cell costlier than the stretch of path it
replaces (a shortcut never goes nearer an obstacle than the path did).

Replanning: `Route` (planner/route.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from go2vlm.geometry.footprint import Clearance, rect_distance
from go2vlm.robot_profile.go2 import FOOTPRINT_LENGTH, FOOTPRINT_WIDTH
from go2vlm.world.occupancy import CIRCUMSCRIBED, INSCRIBED, LETHAL, UNKNOWN

__all__ = [
    "Costmap",
    "GlobalParams",
    "Plan",
    "cell_costs",
    "chain_cost",
    "footprint_fits",
    "line_cells",
    "passable",
    "plan_path",
]


@dataclass(frozen=True)
class Costmap:
    """An inflated costmap: `data` int8 (rows = y, cols = x), `resolution` m per cell, `origin` the
    world (x, y) of cell (0, 0)'s corner, `stamp` when it was made (s, the bus clock)."""

    data: np.ndarray
    resolution: float
    origin: tuple[float, float]
    stamp: float = 0.0

    def __post_init__(self) -> None:
        if self.data.ndim != 2 or self.data.size == 0:
            raise ValueError(f"a costmap is a non-empty 2-D grid, got shape {self.data.shape}")
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"costmap resolution must be a positive number, got {self.resolution}")

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.data.shape[0]), int(self.data.shape[1])

    def cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the world point (x, y) (may lie outside the grid)."""
        return int(math.floor((y - self.origin[1]) / self.resolution)), int(
            math.floor((x - self.origin[0]) / self.resolution)
        )

    def inside(self, rc: tuple[int, int]) -> bool:
        return 0 <= rc[0] < self.shape[0] and 0 <= rc[1] < self.shape[1]

    def world(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """(N, 2) world (x, y) of cell centres."""
        r = self.resolution
        return np.column_stack(
            (self.origin[0] + (np.asarray(cols) + 0.5) * r, self.origin[1] + (np.asarray(rows) + 0.5) * r)
        )


@dataclass(frozen=True)
class GlobalParams:
    lethal: int = INSCRIBED  # a cell this costly or more is never entered (99 inscribed, 100 an obstacle)
    cost_scale: float = 10.0  # a cell of cost v (0..98) costs 1 + cost_scale * v / 100 per cell crossed
    unknown_cost: float = math.inf  # per unknown cell crossed; inf: never
    max_cells: int = 160_000  # larger grids are planned coarse first, then at full resolution round that path
    goal_tolerance_m: float = 0.6  # any passable cell this near the goal is the goal
    escape_m: float = 0.6  # a start on a lethal cell plans from the nearest passable cell this near
    off_path_m: float = 0.8  # the robot this far from the route: replan
    replan_period_s: float = 2.0  # a new costmap replans at most this often (a blocked route at once)
    half_length: float = FOOTPRINT_LENGTH / 2  # the footprint checked in the band (m)
    half_width: float = FOOTPRINT_WIDTH / 2
    clearance_m: float = Clearance().creep  # kept round it there: the clearance at a creep
    footprint_replans: int = 8  # searches again with the cells where the footprint touched closed

    def __post_init__(self) -> None:
        if not 1 <= self.lethal <= 100:
            raise ValueError(f"lethal must be within 1..100, got {self.lethal}")
        for name in ("cost_scale", "goal_tolerance_m", "escape_m", "off_path_m", "replan_period_s", "half_length",
                     "half_width", "clearance_m"):  # fmt: skip
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v}")
        if not (self.unknown_cost >= 1.0):  # also refuses NaN
            raise ValueError(f"unknown_cost must be >= 1 (or inf: never cross), got {self.unknown_cost}")
        if self.max_cells < 100:
            raise ValueError(f"max_cells must be at least 100, got {self.max_cells}")
        if not 0 <= self.footprint_replans <= 100:
            raise ValueError(f"footprint_replans must be within 0..100, got {self.footprint_replans}")


@dataclass(frozen=True)
class Plan:
    ok: bool
    reason: str  # why not (a refusal), or what was planned
    waypoints: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (M, 2) world x, y; [0] the start
    cost: float = math.inf  # the search's cost (m, weighted)
    length: float = math.inf  # m along the waypoints
    goal: tuple[float, float] | None = None  # the goal cell reached (world x, y)
    goal_index: int = -1  # plan_path's goals: which one was reached
    stride: int = 1  # the coarsening factor it was planned at
    cells: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=int))  # dense (row, col) path, fine grid


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
    unknown = d == UNKNOWN
    v = d.astype(np.int16)
    c = 1.0 + p.cost_scale * np.clip(v, 0, 100) / 100.0
    c[unknown] = p.unknown_cost
    c[v >= p.lethal] = np.inf
    c[v < UNKNOWN] = np.inf  # not a ROS occupancy value: never entered
    return c


def footprint_fits(cm: Costmap, cells: np.ndarray, headings: np.ndarray, p: GlobalParams) -> np.ndarray:
    """bool per (row, col) of `cells`: does the footprint's rectangle centred on the cell, at the
    heading (rad, world), keep `clearance_m` from every obstacle cell (LETHAL, by its centre)?"""
    cells = np.asarray(cells, dtype=int).reshape(-1, 2)
    if len(cells) == 0:
        return np.zeros(0, bool)
    res = cm.resolution
    reach = int(math.ceil((math.hypot(p.half_length, p.half_width) + p.clearance_m) / res))
    dr, dc = np.mgrid[-reach : reach + 1, -reach : reach + 1]
    dr, dc = dr.reshape(-1), dc.reshape(-1)
    rows, cols = cells[:, :1] + dr[None], cells[:, 1:] + dc[None]
    h, w = cm.shape
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    obstacle = np.zeros(rows.shape, bool)
    obstacle[inside] = cm.data[rows[inside], cols[inside]] == LETHAL
    th = np.asarray(headings, dtype=float).reshape(-1, 1)
    cs, sn = np.cos(th), np.sin(th)
    x, y = dc[None] * res, dr[None] * res
    d = rect_distance(cs * x + sn * y, -sn * x + cs * y, p.half_length, p.half_width)
    return np.asarray(~(obstacle & (d < p.clearance_m)).any(axis=1))


def _path_headings(cells: np.ndarray, span: int = 2) -> np.ndarray:
    """The heading (rad, world) of a dense cell path at each of its cells: along the path, over
    `span` cells either side (a single 8-connected step is 45 degrees coarse)."""
    n = len(cells)
    i = np.arange(n)
    a, b = cells[np.maximum(i - span, 0)], cells[np.minimum(i + span, n - 1)]
    return np.arctan2(b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]).astype(float)


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
    False)."""
    goal_list = list(goals)
    if not goal_list:
        return Plan(False, "no goal to plan to")
    if not all(math.isfinite(v) for v in start) or not all(math.isfinite(v) for g in goal_list for v in g):
        return Plan(False, "start or goal is not a finite point")
    k = stride_for(cm.shape, p.max_cells)
    c = cell_costs(cm, p)
    if k > 1:  # a coarse guide first, then the fine grid round it
        guide = _search(cm, cell_costs(cm, p, k), k, start, goal_list, p)
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


@dataclass
class _Found:
    dense: np.ndarray  # (N, 2) cells from the start cell to the goal cell
    start: tuple[int, int]  # the robot's cell
    escaped: bool  # the search began at a passable cell near it
    goal: tuple[int, int]
    cost: float
    goal_index: int
    ends: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=int))  # every goal cell (row, col)
    owners: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # ... and its goal's index


def _search(
    cm: Costmap,
    c: np.ndarray,
    k: int,
    start: tuple[float, float],
    goal_list: list[tuple[float, float]],
    p: GlobalParams,
) -> _Found | Plan:
    """One search on cost grid `c` (the costmap coarsened by `k`): the cell path, or a refusal."""
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
        ends += [(int(a), int(b)) for a, b in cells]
        owner += [gi] * len(cells)
    if not ends:
        if outside == len(goal_list):
            return Plan(False, "the goal is outside the map")
        return Plan(False, f"the goal is inside an obstacle: no passable cell within {p.goal_tolerance_m:g} m of it")
    from skimage.graph import MCP_Geometric  # the nav extra; imported here so a commander without a map needs none

    mcp = MCP_Geometric(c, fully_connected=True)
    costs, _ = mcp.find_costs([s_from], ends, find_all_ends=False)
    end_arr = np.array(ends)
    end_costs = costs[end_arr[:, 0], end_arr[:, 1]]
    best = int(np.argmin(end_costs))
    if not np.isfinite(end_costs[best]):
        how = "obstacles and unknown space" if math.isinf(p.unknown_cost) else "obstacles"
        return Plan(False, f"unreachable: {how} cut the goal off from the robot")
    e = (int(end_arr[best, 0]), int(end_arr[best, 1]))
    dense = np.array(mcp.traceback(e), dtype=int).reshape(-1, 2)
    if s_from != s:
        dense = np.vstack((np.array([s]), dense))
    return _Found(dense, s, s_from != s, e, float(end_costs[best]) * res, owner[best], end_arr, np.array(owner))


def _fitting(
    cm: Costmap, c: np.ndarray, start: tuple[float, float], goal_list: list[tuple[float, float]], p: GlobalParams
) -> Plan:
    """The search at full resolution; where its path's footprint touches in the band, the search by
    heading instead (module docstring); and the path's waypoints."""
    found = _search(cm, c, 1, start, goal_list, p)
    if isinstance(found, Plan):
        return found
    skip = int(math.ceil((math.hypot(p.half_length, p.half_width) + p.clearance_m) / cm.resolution))
    dense = found.dense
    v = cm.data[dense[:, 0], dense[:, 1]]
    check = (v >= CIRCUMSCRIBED) & (v < p.lethal)
    # round the start the robot turns where it stands (the local planner's part), and round the goal it
    # stops short and turns to look (the approach's)
    check[:skip] = check[-skip:] = False
    idx = np.nonzero(check)[0]
    if not footprint_fits(cm, dense[idx], _path_headings(dense)[idx], p).all():
        by_heading = _by_heading(cm, c, found, p)
        if by_heading is None:
            return Plan(False, "unreachable: no way the footprint fits through (every way crosses a gap too narrow)")
        found = by_heading
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


# The search by heading's moves: one step along each of four lines (0, 45, 90, 135 degrees, rows = y);
# in the band a cell is entered and left along one line (the robot walks along its path and turns only
# where the footprint's circumscribed disc fits).
LINES = ((0, 1), (1, 1), (1, 0), (1, -1))


def footprint_free(cm: Costmap, p: GlobalParams) -> np.ndarray:
    """bool (4, rows, cols): does the footprint's rectangle (its half sizes plus `clearance_m`, corners
    square), centred on the cell and along LINES[k], keep clear of every obstacle cell? Box sums over
    an integral image, the diagonal lines on the grid turned 45 degrees: O(cells) for each line."""
    obstacle = cm.data == LETHAL
    h, w = obstacle.shape
    a = (p.half_length + p.clearance_m) / cm.resolution  # along the heading, in cells
    b = (p.half_width + p.clearance_m) / cm.resolution
    out = np.zeros((4, h, w), bool)
    rows, cols = np.indices((h, w))
    for k, (dr, dc) in enumerate(LINES):
        if dr == 0 or dc == 0:  # along cols (k 0) or rows (k 2)
            img, r, q = obstacle, rows, cols
            ha, hb = (b, a) if dr == 0 else (a, b)  # half extents along rows, along cols
        else:  # u = row + col, v = row - col: a diagonal line is one of their axes
            img = np.zeros((h + w - 1, h + w - 1), bool)
            img[rows + cols, rows - cols + w - 1] = obstacle
            r, q = rows + cols, rows - cols + w - 1
            along, across = a * math.sqrt(2.0), b * math.sqrt(2.0)  # one step of u or v is res / sqrt 2
            ha, hb = (along, across) if dc > 0 else (across, along)
        out[k] = _box_count(img, r, q, int(math.floor(ha)), int(math.floor(hb))) == 0
    return out


def _box_count(img: np.ndarray, r: np.ndarray, q: np.ndarray, hr: int, hq: int) -> np.ndarray:
    """How many True cells of `img` lie within +-hr rows and +-hq cols of each (r, q)."""
    s = np.zeros((img.shape[0] + 1, img.shape[1] + 1), np.int32)
    s[1:, 1:] = img.astype(np.int32).cumsum(0).cumsum(1)
    r0, r1 = np.clip(r - hr, 0, img.shape[0]), np.clip(r + hr + 1, 0, img.shape[0])
    q0, q1 = np.clip(q - hq, 0, img.shape[1]), np.clip(q + hq + 1, 0, img.shape[1])
    return np.asarray(s[r1, q1] - s[r0, q1] - s[r1, q0] + s[r0, q0])


def _by_heading(cm: Costmap, c: np.ndarray, found: _Found, p: GlobalParams) -> _Found | None:
    """The cheapest path from the search's start to its goal cells over (cell, line) states: a cell
    where the footprint's disc fits is one state (it may turn there); a cell of the band is one state
    for each line along which the rectangle fits there, entered and left along that line only (a
    doorway is crossed square-on). Dijkstra (scipy's csgraph) on that graph, over the box of the
    cells that may be entered (a corridor round a coarse guide); None: no way."""
    rows, cols = np.nonzero(np.isfinite(c))
    pad = int(math.ceil((math.hypot(p.half_length, p.half_width) + p.clearance_m) / cm.resolution)) + 1
    r0, c0 = max(0, int(rows.min()) - pad), max(0, int(cols.min()) - pad)
    r1, c1 = min(c.shape[0], int(rows.max()) + pad + 1), min(c.shape[1], int(cols.max()) + pad + 1)
    if (r0, c0, r1, c1) != (0, 0, *c.shape):
        sub = Costmap(cm.data[r0:r1, c0:c1], cm.resolution, cm.origin)
        off = np.array([r0, c0])
        moved = _Found(found.dense - off, (found.start[0] - r0, found.start[1] - c0), found.escaped,
                       (found.goal[0] - r0, found.goal[1] - c0), found.cost, found.goal_index, found.ends - off,
                       found.owners)  # fmt: skip
        inner = (moved.ends[:, 0] >= 0) & (moved.ends[:, 0] < r1 - r0) & (moved.ends[:, 1] >= 0)
        inner &= moved.ends[:, 1] < c1 - c0
        moved = replace(moved, ends=moved.ends[inner], owners=moved.owners[inner])
        got = _by_heading(sub, c[r0:r1, c0:c1], moved, p)
        if got is None:
            return None
        return replace(got, dense=got.dense + off, start=found.start, goal=(got.goal[0] + r0, got.goal[1] + c0),
                       ends=found.ends, owners=found.owners)  # fmt: skip
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra

    h, w = c.shape
    n = h * w
    ok = np.isfinite(c)
    band = ok & (cm.data >= CIRCUMSCRIBED) & (cm.data < p.lethal)
    free = ok & ~band
    fit = footprint_free(cm, p)
    # a goal cell is where the path ends, at whatever line it arrives (the approach stops short of the
    # goal, and turns where it stands); the robot's own cell too (it turns out of it first)
    first = found.dense[1] if found.escaped else found.dense[0]
    fit[:, found.ends[:, 0], found.ends[:, 1]] = True
    fit[:, int(first[0]), int(first[1])] = True
    fit &= band[None]
    flat = np.arange(n).reshape(h, w)
    src: list[np.ndarray] = []
    dst: list[np.ndarray] = []
    wgt: list[np.ndarray] = []
    for k, (dr, dc) in enumerate(LINES):
        for sr, sc in ((dr, dc), (-dr, -dc)):
            ra, rb = slice(max(0, -sr), h - max(0, sr)), slice(max(0, sr), h + min(0, sr) or None)
            ca, cb = slice(max(0, -sc), w - max(0, sc)), slice(max(0, sc), w + min(0, sc) or None)
            fa, fb = free[ra, ca], free[rb, cb]
            va, vb = fa | fit[k][ra, ca], fb | fit[k][rb, cb]
            m = va & vb
            ia = np.where(fa, flat[ra, ca], n * (1 + k) + flat[ra, ca])[m]
            ib = np.where(fb, flat[rb, cb], n * (1 + k) + flat[rb, cb])[m]
            src.append(ia)
            dst.append(ib)
            wgt.append(math.hypot(sr, sc) * 0.5 * (c[ra, ca][m] + c[rb, cb][m]))
    graph = csr_matrix((np.concatenate(wgt), (np.concatenate(src), np.concatenate(dst))), shape=(5 * n, 5 * n))

    def states(rc: tuple[int, int]) -> list[int]:
        i = int(flat[rc])
        if free[rc]:
            return [i]
        return [n * (1 + k) + i for k in range(4) if fit[k][rc]]

    starts = states((int(first[0]), int(first[1])))
    dist, pred, _ = dijkstra(graph, indices=starts, min_only=True, return_predecessors=True)
    ends = [(s, i) for i, e in enumerate(found.ends) for s in states((int(e[0]), int(e[1])))]
    if not ends or not np.isfinite(min(dist[s] for s, _ in ends)):
        return None
    node, which = min(ends, key=lambda e: dist[e[0]])
    goal = (int(found.ends[which, 0]), int(found.ends[which, 1]))
    cost = float(dist[node]) * cm.resolution
    chain = [node]
    while pred[chain[-1]] >= 0:
        chain.append(int(pred[chain[-1]]))
    cells = np.array([divmod(i % n, w) for i in reversed(chain)], dtype=int)
    if found.escaped:
        cells = np.vstack((np.array([found.start]), cells))
    return _Found(cells, found.start, found.escaped, goal, cost, int(found.owners[which]), found.ends, found.owners)


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
    c2[s] = np.nanmax(np.where(np.isfinite(c), c, np.nan))
    return c2
