"""The robot's map in an episode's outputs: the newest /map the recorder kept, the frontiers of the
newest /map/costmap (world/frontiers.py, as the explorer finds them), the frontiers the explorer
walked to (its /commander/status) and the routes on /plan. Pure apart from `write_map_files`.

    nav = nav_series(rec)               # {} without a map; else map (OccupancyGridDict), frontiers, ...
    write_map_files(rec.grid, out)      # out/map.npz (the whole grid) and out/map.png (one pixel a cell)

The plot's grid is at most `MAX_PLOT_CELLS` a side: a bigger map is cropped to its known cells and
coarsened by blocks, each block the most telling of its cells (occupied over free over unknown).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from go2vlm.apps.episodes.outputs import atomic
from go2vlm.apps.episodes.plot import OccupancyGridDict
from go2vlm.world.frontiers import FrontierParams, find_frontiers
from go2vlm.world.map_msg import Grid

if TYPE_CHECKING:
    from go2vlm.apps.episodes.recorder import Recording

__all__ = ["MAX_PLOT_CELLS", "coarse_grid", "map_image", "map_summary", "nav_series", "write_map_files"]

MAX_PLOT_CELLS = 400  # cells a side of the map in series.json and the plot
MARGIN_CELLS = 4  # kept round the known cells when the map is cropped


def coarse_grid(g: Grid, max_cells: int = MAX_PLOT_CELLS) -> OccupancyGridDict | None:
    """`g` cropped to its known cells and coarsened to at most `max_cells` a side, in
    nav_msgs/OccupancyGrid's layout (plot.OccupancyGridDict); None when nothing is known."""
    cells = np.asarray(g.cells)
    known = np.argwhere(cells >= 0)
    if not len(known):
        return None
    r0, c0 = np.maximum(known.min(axis=0) - MARGIN_CELLS, 0)
    r1, c1 = np.minimum(known.max(axis=0) + MARGIN_CELLS + 1, cells.shape)
    crop = cells[r0:r1, c0:c1]
    k = max(1, math.ceil(max(crop.shape) / max_cells))
    if k > 1:  # a block is occupied if any of its cells is, else free if any is, else unknown
        rows, cols = -(-crop.shape[0] // k) * k, -(-crop.shape[1] // k) * k
        padded = np.full((rows, cols), -1, dtype=np.int16)
        padded[: crop.shape[0], : crop.shape[1]] = crop
        crop = padded.reshape(rows // k, k, cols // k, k).max(axis=(1, 3))
    res = g.resolution * k
    return {
        "origin": [round(float(g.origin[0] + c0 * g.resolution), 4), round(float(g.origin[1] + r0 * g.resolution), 4)],
        "resolution": round(res, 6),
        "width": int(crop.shape[1]),
        "height": int(crop.shape[0]),
        "data": crop.astype(int).reshape(-1).tolist(),
    }


def _explored(rec: Recording) -> list[list[float]]:
    """The goals of the frontiers the explorer chose, in the order it chose them."""
    out: list[list[float]] = []
    for _, st in rec.commander:
        ex = st.get("explore")
        f = ex.get("frontier") if isinstance(ex, dict) else None
        goal = f.get("goal") if isinstance(f, dict) else None
        if isinstance(goal, list) and len(goal) == 2 and goal not in out:
            out.append([float(goal[0]), float(goal[1])])
    return out


def nav_series(rec: Recording) -> dict[str, object]:
    """The plot's share of the map: map (coarse, see `coarse_grid`), frontiers (of the newest
    costmap, else map: [x, y, edge m] each), explored (the frontier goals walked to), plans ([sim t,
    [[x, y], ...]] each). {} when the episode heard neither a map nor a plan."""
    if rec.grid is None and rec.costmap is None and not rec.plans:
        return {}
    base = rec.costmap if rec.costmap is not None else rec.grid
    frontiers: list[list[float]] = []
    if base is not None:
        fp = FrontierParams()
        cells = np.asarray(base.cells)
        found = find_frontiers(cells, base.resolution, base.origin, fp, reachable=(cells >= 0) & (cells < fp.lethal))
        frontiers = [[round(f.centroid[0], 2), round(f.centroid[1], 2), round(f.size_m, 2)] for f in found]
    shown = rec.grid if rec.grid is not None else rec.costmap
    return {
        "map": coarse_grid(shown) if shown is not None else None,
        "frontiers": frontiers,
        "explored": _explored(rec),
        "plans": [[round(t, 2), [[round(x, 3), round(y, 3)] for x, y in pts]] for t, pts in rec.plans],
    }


def map_summary(rec: Recording, nav: dict[str, object]) -> dict[str, float | int | str] | None:
    """metrics["map"]: the newest map's size and cells, the frontiers left, the routes heard."""
    g = rec.grid
    if g is None and not nav:
        return None
    frontiers, explored = nav.get("frontiers"), nav.get("explored")
    out: dict[str, float | int | str] = {
        "plans": len(rec.plans),
        "frontiers_left": len(frontiers) if isinstance(frontiers, list) else 0,
        "explored_frontiers": len(explored) if isinstance(explored, list) else 0,
    }
    if g is not None:
        c = np.asarray(g.cells)
        area = g.resolution**2
        out.update({"resolution_m": g.resolution, "width": int(c.shape[1]), "height": int(c.shape[0]),
                    "free_m2": round(float((c == 0).sum()) * area, 2),
                    "occupied_m2": round(float((c > 0).sum()) * area, 2),
                    "frame_id": g.frame_id})  # fmt: skip
    return out


def map_image(cells: np.ndarray) -> np.ndarray:
    """RGB, one pixel a cell, north (higher y) up: unknown grey, free white, occupied black."""
    c = np.asarray(cells)
    img = np.full((*c.shape, 3), 160, dtype=np.uint8)
    img[(c >= 0) & (c < 50)] = 255
    img[c >= 50] = 0
    return img[::-1]


def write_map_files(g: Grid, out: Path) -> dict[str, str]:
    """out/map.npz (cells int8 [rows = y, cols = x] as on /map, origin, resolution, frame_id, stamp)
    and out/map.png (`map_image`); {name: path} of what was written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files: dict[str, str] = {}
    with atomic(out / "map.npz") as tmp:
        np.savez_compressed(tmp, cells=np.asarray(g.cells, dtype=np.int8), origin=np.array(g.origin, dtype=float),
                            resolution=np.array(g.resolution), frame_id=np.array(g.frame_id),
                            stamp=np.array(g.stamp))  # fmt: skip
    files["map_npz"] = str(out / "map.npz")
    with atomic(out / "map.png") as tmp:
        plt.imsave(tmp, map_image(g.cells))
    files["map_png"] = str(out / "map.png")
    return files
