"""The global planner's footprint check and its search by heading (behavior/planner/global_path.py's
module docstring): where a path's footprint touches in the band out to the circumscribed radius, the
rectangle is checked at its heading, and the search is run again over (cell, line) states so that a
doorway is crossed square-on. In the band the robot turns in place from one line to the next (45
degrees) where its rectangle sweeps clear (`turn_free`), as a Go2 does: the circumscribed disc is the
sweep of a whole turn, and among furniture a path that may turn only where that fits found none.
Pure (no DDS)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from go2vlm.behavior.planner.grid import Costmap, Found, GlobalParams
from go2vlm.geometry.footprint import rect_distance
from go2vlm.world.occupancy import CIRCUMSCRIBED, LETHAL

__all__ = ["LINES", "by_heading", "footprint_fits", "footprint_free", "path_headings", "turn_free", "turn_reach"]


def turn_reach(p: GlobalParams, res: float) -> int:
    """Cells round the start, and before the goal, where neither search checks the rectangle: the
    footprint's circumscribed radius and its clearance. The robot stands at the start at whatever
    heading it has (in a doorway too, off its middle) and stops short of the goal to turn and look;
    the controller and the guard move it there."""
    return int(math.ceil((math.hypot(p.half_length, p.half_width) + p.clearance_m) / res))


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


def path_headings(cells: np.ndarray, span: int = 2) -> np.ndarray:
    """The heading (rad, world) of a dense cell path at each of its cells: along the path, over
    `span` cells either side (a single 8-connected step is 45 degrees coarse)."""
    n = len(cells)
    i = np.arange(n)
    a, b = cells[np.maximum(i - span, 0)], cells[np.minimum(i + span, n - 1)]
    return np.arctan2(b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]).astype(float)


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


def turn_free(cm: Costmap, p: GlobalParams, steps: int = 6) -> np.ndarray:
    """bool (4, rows, cols): does the footprint's rectangle (plus `clearance_m`, as `footprint_fits`),
    turning in place on the cell from LINES[k] to LINES[k + 1] (45 degrees; the last to the first,
    the rectangle being the same turned half round), keep clear of every obstacle cell throughout?
    The sweep is the rectangles at `steps` + 1 headings across the turn (a cell of error at the
    corners' radius from 6 on); an obstacle within it, found by one FFT convolution a turn."""
    from scipy.signal import fftconvolve

    res = cm.resolution
    obstacle = (cm.data == LETHAL).astype(np.float32)
    reach = int(math.ceil((math.hypot(p.half_length, p.half_width) + p.clearance_m) / res))
    dr, dc = np.mgrid[-reach : reach + 1, -reach : reach + 1]
    x, y = dc * res, dr * res
    out = np.zeros((4, *cm.shape), bool)
    for k in range(4):
        swept = np.zeros(x.shape, bool)
        for th in k * math.pi / 4 + np.linspace(0.0, math.pi / 4, steps + 1):
            cs, sn = math.cos(th), math.sin(th)
            swept |= rect_distance(cs * x + sn * y, -sn * x + cs * y, p.half_length, p.half_width) < p.clearance_m
        hits = fftconvolve(obstacle, swept[::-1, ::-1].astype(np.float32), mode="same")
        out[k] = hits < 0.5
    return out


def _box_count(img: np.ndarray, r: np.ndarray, q: np.ndarray, hr: int, hq: int) -> np.ndarray:
    """How many True cells of `img` lie within +-hr rows and +-hq cols of each (r, q)."""
    s = np.zeros((img.shape[0] + 1, img.shape[1] + 1), np.int32)
    s[1:, 1:] = img.astype(np.int32).cumsum(0).cumsum(1)
    r0, r1 = np.clip(r - hr, 0, img.shape[0]), np.clip(r + hr + 1, 0, img.shape[0])
    q0, q1 = np.clip(q - hq, 0, img.shape[1]), np.clip(q + hq + 1, 0, img.shape[1])
    return np.asarray(s[r1, q1] - s[r0, q1] - s[r1, q0] + s[r0, q0])


def by_heading(cm: Costmap, c: np.ndarray, found: Found, p: GlobalParams) -> Found | None:
    """The cheapest path from the search's start to its goal cells over (cell, line) states: a cell
    where the footprint's disc fits is one state (it may turn there); a cell of the band is one state
    for each line along which the rectangle fits there, entered and left along that line only (a
    doorway is crossed square-on). Dijkstra (scipy's csgraph) on that graph, over the box of the
    cells that may be entered (a corridor round a coarse guide); None: no way. A step between a band
    cell and a cell where the disc fits may go any of the 8 ways (the rectangle fits at both, at the
    band cell's line: a cell's sidestep at the band's edge). A band cell's state
    on one line turns to the next line's where the rectangle sweeps clear between them (`turn_free`),
    at the cost of walking `turn_cost_m` there."""
    rows, cols = np.nonzero(np.isfinite(c))
    reach = turn_reach(p, cm.resolution)
    pad = reach + 1
    r0, c0 = max(0, int(rows.min()) - pad), max(0, int(cols.min()) - pad)
    r1, c1 = min(c.shape[0], int(rows.max()) + pad + 1), min(c.shape[1], int(cols.max()) + pad + 1)
    if (r0, c0, r1, c1) != (0, 0, *c.shape):
        sub = Costmap(cm.data[r0:r1, c0:c1], cm.resolution, cm.origin)
        off = np.array([r0, c0])
        moved = Found(found.dense - off, (found.start[0] - r0, found.start[1] - c0), found.escaped,
                       (found.goal[0] - r0, found.goal[1] - c0), found.cost, found.goal_index, found.ends - off,
                       found.owners)  # fmt: skip
        inner = (moved.ends[:, 0] >= 0) & (moved.ends[:, 0] < r1 - r0) & (moved.ends[:, 1] >= 0)
        inner &= moved.ends[:, 1] < c1 - c0
        moved = replace(moved, ends=moved.ends[inner], owners=moved.owners[inner])
        got = by_heading(sub, c[r0:r1, c0:c1], moved, p)
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
    # goal, and turns where it stands); round the robot's own cell, as the path's own check (turn_reach)
    first = found.dense[1] if found.escaped else found.dense[0]
    fit[:, found.ends[:, 0], found.ends[:, 1]] = True
    rr, cc = np.ogrid[:h, :w]
    fit[:, (rr - int(first[0])) ** 2 + (cc - int(first[1])) ** 2 <= reach**2] = True
    fit &= band[None]
    flat = np.arange(n).reshape(h, w)
    src: list[np.ndarray] = []
    dst: list[np.ndarray] = []
    wgt: list[np.ndarray] = []

    def edge(ia: np.ndarray, ib: np.ndarray, m: np.ndarray, cost: np.ndarray) -> None:
        src.append(ia[m])
        dst.append(ib[m])
        wgt.append(cost[m])

    for k, (dr, dc) in enumerate(LINES):
        for sr, sc in ((dr, dc), (-dr, -dc)):
            ra, rb = slice(max(0, -sr), h - max(0, sr)), slice(max(0, sr), h + min(0, sr) or None)
            ca, cb = slice(max(0, -sc), w - max(0, sc)), slice(max(0, sc), w + min(0, sc) or None)
            fa, fb, ia, ib = free[ra, ca], free[rb, cb], flat[ra, ca], flat[rb, cb]
            cost = math.hypot(sr, sc) * 0.5 * (c[ra, ca] + c[rb, cb])
            edge(ia, ib, fa & fb, cost)
            for j in range(4):  # a band cell's state on line j: along j to the next; on or off the band, any way
                ja, jb = fit[j][ra, ca], fit[j][rb, cb]
                if j == k:
                    edge(n * (1 + j) + ia, n * (1 + j) + ib, ja & jb, cost)
                edge(ia, n * (1 + j) + ib, fa & jb, cost)
                edge(n * (1 + j) + ia, ib, ja & fb, cost)
    sweep = turn_free(cm, p)  # fit is the band's already
    turn = p.turn_cost_m / cm.resolution
    for k in range(4):
        k2 = (k + 1) % 4
        m = sweep[k] & fit[k] & fit[k2]
        i = flat[m]
        src += [n * (1 + k) + i, n * (1 + k2) + i]
        dst += [n * (1 + k2) + i, n * (1 + k) + i]
        wgt += [turn * c[m], turn * c[m]]
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
    return Found(cells, found.start, found.escaped, goal, cost, int(found.owners[which]), found.ends, found.owners)
