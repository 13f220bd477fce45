"""The global planner's library choice, measured: a full plan corner to corner on a 60 x 60 m house
at 5 cm (1200 x 1200 cells), the largest map the occupancy grid allows.

    .venv/bin/python benchmarks/bench_planner.py --repeats 5

The house: a 6 x 6 grid of 10 m rooms, walls 10 cm thick with a 1 m doorway in each, a few boxes
in every room; the walls are inflated by the footprint's half width, with a cost gradient beyond
(as the map's costmap is). Candidates, each on the same cost array (free 1, the gradient 1..50,
lethal impassable), 8-connected:

- scikit-image `graph.MCP_Geometric` (Dijkstra from the start until the goal is settled), then
  its traceback;
- scikit-image `graph.route_through_array` (the same, wrapped);
- `pyastar2d.astar_path` (A*, C++, Euclidean heuristic);
- scipy `sparse.csgraph.dijkstra` (the graph built from the array, then one source).

Candidates whose package is not installed are reported as such. Prints one row per candidate:
median and best wall time, median CPU time, the path's cost. Then, with `--world NAME` (repeatable;
default household), the planner itself (`plan_path`, the whole call) on the world's own costmap: its
bodies' footprints rasterised at 5 cm and inflated as the map node inflates (world/occupancy.py),
planned between the two free cells farthest apart (a full replan across the house). No target is
asserted here: docs/navigation.md keeps the figures.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

RES = 0.05
SIZE = 1200


def house(seed: int = 0) -> np.ndarray:
    """int8 ROS-convention occupancy (rows = y): 0 free, 100 a wall or a box."""
    rng = np.random.default_rng(seed)
    g = np.zeros((SIZE, SIZE), np.int8)
    room = int(10.0 / RES)
    for k in range(0, SIZE + 1, room):
        k = min(k, SIZE - 2)
        g[k : k + 2, :] = 100
        g[:, k : k + 2] = 100
    for i in range(6):
        for j in range(6):
            y0, x0 = i * room, j * room
            dx = x0 + int(rng.integers(40, room - 60))
            dy = y0 + int(rng.integers(40, room - 60))
            if j < 5:
                g[dy : dy + 20, x0 + room - 1 : x0 + room + 3] = 0  # a door in the east wall
            if i < 5:
                g[y0 + room - 1 : y0 + room + 3, dx : dx + 20] = 0  # and in the north wall
            for _ in range(3):
                by, bx = y0 + int(rng.integers(20, room - 30)), x0 + int(rng.integers(20, room - 30))
                g[by : by + 10, bx : bx + 10] = 100
    return g


def costs(occ: np.ndarray) -> np.ndarray:
    """float64 cost per cell: lethal within the inflation radius, a gradient to 1 beyond it."""
    from scipy import ndimage

    d = ndimage.distance_transform_edt(occ < 50) * RES
    c = 1.0 + 49.0 * np.clip((0.6 - d) / 0.4, 0.0, 1.0)
    c[d <= 0.2] = np.inf
    return c


def bench(fn: Callable[[], float], repeats: int) -> tuple[float, float, float, float]:
    """(median wall ms, best wall ms, median CPU ms, the path's cost): CPU time is the steadier figure
    on a shared machine (every candidate runs on one thread)."""
    walls, cpus, cost = [], [], 0.0
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        cost = fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return statistics.median(walls) * 1e3, min(walls) * 1e3, statistics.median(cpus) * 1e3, cost


def row(med: float, best: float, cpu: float, cost: float) -> str:
    return f"median {med:7.1f} ms  best {best:7.1f} ms  CPU {cpu:7.1f} ms  cost {cost:8.1f}"


def path_cost(c: np.ndarray, path: np.ndarray) -> float:
    p = np.asarray(path)
    steps = np.hypot(*np.diff(p, axis=0).T)
    return float(np.sum(steps * 0.5 * (c[p[1:, 0], p[1:, 1]] + c[p[:-1, 0], p[:-1, 1]])))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--world", action="append", help="also plan across this world (default: household)")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures here")
    args = ap.parse_args()
    occ = house()
    c = costs(occ)
    free = np.argwhere(np.isfinite(c))
    start = tuple(int(v) for v in free[np.argmin(np.hypot(*(free - 30).T))])
    goal = tuple(int(v) for v in free[np.argmin(np.hypot(*(free - (SIZE - 30)).T))])
    rows: list[tuple[str, str]] = []

    try:
        from skimage import graph as skg

        def mcp() -> float:
            m = skg.MCP_Geometric(c, fully_connected=True)
            m.find_costs([start], [goal], find_all_ends=True)
            return path_cost(c, np.array(m.traceback(goal)))

        def route() -> float:
            p, _ = skg.route_through_array(c, start, goal, fully_connected=True, geometric=True)
            return path_cost(c, np.array(p))

        for name, fn in (("skimage MCP_Geometric", mcp), ("skimage route_through_array", route)):
            med, best, cpu, cost = bench(fn, args.repeats)
            rows.append((name, row(med, best, cpu, cost)))
    except ImportError:
        rows.append(("skimage", "not installed"))

    try:
        import pyastar2d

        w = np.where(np.isfinite(c), c, np.inf).astype(np.float32)

        def astar() -> float:
            p = pyastar2d.astar_path(w, start, goal, allow_diagonal=True)
            return path_cost(c, p)

        med, best, cpu, cost = bench(astar, args.repeats)
        rows.append(("pyastar2d astar_path", row(med, best, cpu, cost)))
    except ImportError:
        rows.append(("pyastar2d", "not installed"))

    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    def csgraph() -> float:
        ok = np.isfinite(c)
        idx = np.arange(c.size).reshape(c.shape)
        src, dst, wt = [], [], []
        for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
            a = idx[max(0, -dy) : SIZE - max(0, dy), max(0, -dx) : SIZE - max(0, dx)]
            b = idx[max(0, dy) : SIZE - max(0, -dy) + 0, max(0, dx) : SIZE - max(0, -dx)]
            a, b = a.ravel(), b.ravel()
            keep = ok.ravel()[a] & ok.ravel()[b]
            a, b = a[keep], b[keep]
            d = np.hypot(dy, dx) * 0.5 * (c.ravel()[a] + c.ravel()[b])
            src += [a, b]
            dst += [b, a]
            wt += [d, d]
        gr = coo_matrix(
            (np.concatenate(wt), (np.concatenate(src), np.concatenate(dst))), shape=(c.size, c.size)
        ).tocsr()
        s, t = idx[start], idx[goal]
        _, pred, _ = dijkstra(gr, indices=s, return_predecessors=True, min_only=True)
        path = [t]
        while path[-1] != s:
            path.append(pred[path[-1]])
        p = np.column_stack(np.unravel_index(np.array(path[::-1]), c.shape))
        return path_cost(c, p)

    med, best, cpu, cost = bench(csgraph, max(1, args.repeats // 2))
    rows.append(("scipy csgraph dijkstra", row(med, best, cpu, cost)))
    from go2vlm.behavior.planner.global_path import Costmap, GlobalParams, plan_path

    cm = Costmap(np.where(np.isfinite(c), np.clip((c - 1.0) / 49.0 * 98, 0, 98), 100).astype(np.int8), RES, (0.0, 0.0))
    sxy = (float((start[1] + 0.5) * RES), float((start[0] + 0.5) * RES))
    gxy = (float((goal[1] + 0.5) * RES), float((goal[0] + 0.5) * RES))
    for name, gp in (
        ("go2vlm plan_path (coarsened)", GlobalParams()),
        ("go2vlm plan_path (full res)", GlobalParams(max_cells=SIZE * SIZE)),
    ):

        def ours(gp: GlobalParams = gp) -> float:
            plan = plan_path(cm, sxy, [gxy], gp)
            assert plan.ok, plan.reason
            return plan.cost / RES

        med, best, cpu, cost = bench(ours, args.repeats)
        rows.append((name, row(med, best, cpu, cost) + " (int8 costs, waypoints included)"))
    print(f"{SIZE} x {SIZE} cells at {RES} m, corner to corner, {args.repeats} repeats")
    for name, text in rows:
        print(f"{name:30s} {text}")
    worlds = {world: bench_world(world, args.repeats) for world in args.world or ["household"]}
    if args.json is not None:
        out = {"grid": {"cells": SIZE, "resolution_m": RES, "repeats": args.repeats}, "candidates": dict(rows)}
        args.json.write_text(json.dumps({**out, "worlds": worlds}, indent=1) + "\n")


def world_costmap(name: str) -> tuple[np.ndarray, tuple[float, float]]:
    """The world's bodies (their floor footprints) rasterised at RES and inflated as the map node does."""
    from go2vlm.robot_profile.go2 import FOOTPRINT_LENGTH, FOOTPRINT_WIDTH
    from go2vlm.sim.worlds import world_footprints, world_model
    from go2vlm.world.occupancy import LETHAL, CostmapParams, inflate

    model, _ = world_model(name)
    named = world_footprints(model)
    feet = list(named.values())
    walls = [f for k, f in named.items() if k.startswith("wall")] or feet  # the house's extent: its walls
    hx = max(abs(f.x) + (f.r or f.hx) for f in walls) + 0.5  # the walls are axis-aligned
    hy = max(abs(f.y) + (f.r or f.hy) for f in walls) + 0.5
    xs, ys = np.meshgrid(
        -hx + (np.arange(int(2 * hx / RES)) + 0.5) * RES, -hy + (np.arange(int(2 * hy / RES)) + 0.5) * RES
    )
    occ = np.zeros(xs.shape, np.int8)
    for f in feet:
        dx, dy = xs - f.x, ys - f.y
        if f.kind == "circle":
            occ[np.hypot(dx, dy) <= f.r] = LETHAL
        else:
            c, sn = np.cos(f.yaw), np.sin(f.yaw)
            u, w = c * dx + sn * dy, -sn * dx + c * dy
            occ[(np.abs(u) <= f.hx) & (np.abs(w) <= f.hy)] = LETHAL
    return inflate(occ, RES, CostmapParams.for_footprint(FOOTPRINT_LENGTH, FOOTPRINT_WIDTH)), (-hx, -hy)


def bench_world(name: str, repeats: int) -> dict[str, float]:
    from go2vlm.behavior.planner.global_path import Costmap, GlobalParams, plan_path

    cost, origin = world_costmap(name)
    cm = Costmap(cost, RES, origin)
    from scipy import ndimage

    from go2vlm.world.occupancy import CIRCUMSCRIBED

    # the ends where the robot may stand turned any way (its disc fits), in the house's free space, not a
    # pocket behind a counter
    labels, _ = ndimage.label((cost >= 0) & (cost < CIRCUMSCRIBED))
    big = np.bincount(labels.ravel())[1:].argmax() + 1
    free = np.argwhere(labels == big)
    a = free[np.argmin(free[:, 1] - 0.3 * free[:, 0])]  # far west (and north)
    b = free[np.argmax(free[:, 1] + 0.3 * free[:, 0])]  # far east
    sxy, gxy = tuple(cm.world(a[:1], a[1:])[0]), tuple(cm.world(b[:1], b[1:])[0])
    plan = plan_path(cm, sxy, [gxy], GlobalParams())
    assert plan.ok, plan.reason

    def one() -> float:
        return plan_path(cm, sxy, [gxy], GlobalParams()).cost

    med, best, cpu, _ = bench(one, repeats)
    print(
        f"{name}: {cost.shape[1]} x {cost.shape[0]} cells, ({sxy[0]:.1f}, {sxy[1]:.1f}) -> ({gxy[0]:.1f}, "
        f"{gxy[1]:.1f}), {plan.length:.1f} m in {len(plan.waypoints) - 1} legs: plan_path median {med:.1f} ms, "
        f"best {best:.1f} ms, CPU {cpu:.1f} ms"
    )
    return {"median_ms": med, "best_ms": best, "cpu_ms": cpu, "length_m": plan.length}


if __name__ == "__main__":
    main()
