"""Frontiers: where the known free space of the map meets the unknown, the places worth walking to
when what is looked for is nowhere in the known part of the house. Pure (numpy + scipy.ndimage).

The grid is a ROS-convention costmap (nav_msgs/OccupancyGrid data: int8, rows = y, cols = x; -1
unknown, 0..`lethal`-1 free at some cost, >= `lethal` not to be entered). A frontier cell is a known
cell that is no obstacle (value 0..99: the inflation's cells count, so a doorway's frontier is as
wide as the door less the obstacle's own cells, not less the whole footprint) with an unknown cell
among its 8 neighbours. Frontier cells are
clustered by 8-connectivity (scipy.ndimage.label); a cluster shorter than `min_size_m` (its cell
count times the resolution: the length of its edge) is dropped, as are the speckles a sparse scan
leaves between its rays. Each frontier has its centroid, its size, and a goal: the cell of the
cluster nearest the centroid whose cost is below `lethal` (so the robot can stand there; a frontier
without one is dropped), among
`reachable` cells when the caller gives that mask (the global planner's costs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from go2vlm.world.occupancy import INSCRIBED

__all__ = ["Frontier", "FrontierParams", "clusters", "find_frontiers", "frontier_cells", "gains"]

_EIGHT = np.ones((3, 3), bool)


@dataclass(frozen=True)
class FrontierParams:
    lethal: int = INSCRIBED  # as the global planner's: a cell this costly is no place to stand
    min_size_m: float = 0.5  # a frontier with a shorter edge is dropped

    def __post_init__(self) -> None:
        if not 1 <= self.lethal <= 100:
            raise ValueError(f"lethal must be within 1..100, got {self.lethal}")
        if not (math.isfinite(self.min_size_m) and self.min_size_m >= 0):
            raise ValueError(f"min_size_m must be a finite number >= 0, got {self.min_size_m}")


@dataclass(frozen=True)
class Frontier:
    id: int  # 1.. in this map's clustering (not stable across maps)
    centroid: tuple[float, float]  # world x, y (m)
    goal: tuple[float, float]  # world x, y of the cell to walk to
    goal_cell: tuple[int, int]  # its (row, col)
    size: int  # cells
    size_m: float  # the edge's length (cells x resolution)
    kind: str = "map"  # map: the map's edge with the unknown; view: free space the camera has not looked at

    def to_dict(self) -> dict[str, object]:
        return {
            "id": self.id,
            "kind": self.kind,
            "centroid": [round(self.centroid[0], 2), round(self.centroid[1], 2)],
            "goal": [round(self.goal[0], 2), round(self.goal[1], 2)],
            "size_m": round(self.size_m, 2),
        }


OBSTACLE = 100  # the costmap's value on an obstacle (and within the footprint's inscribed radius of one)


def frontier_cells(grid: np.ndarray) -> np.ndarray:
    """bool mask: known cells that are no obstacle (0..99) with an unknown (-1) 8-neighbour."""
    from scipy import ndimage  # the nav extra; here, so the commander starts as fast without a map

    g = np.asarray(grid)
    unknown = g == -1
    free = (g >= 0) & (g < OBSTACLE)
    near_unknown = ndimage.binary_dilation(unknown, structure=_EIGHT)
    return free & near_unknown


def find_frontiers(
    grid: np.ndarray,
    resolution: float,
    origin: tuple[float, float],
    p: FrontierParams,
    reachable: np.ndarray | None = None,
) -> list[Frontier]:
    """The frontiers of `grid`, largest first. `reachable` (bool, the grid's shape): cells the robot
    can get to; a frontier with no reachable cell is dropped."""
    g = np.asarray(grid)
    if g.ndim != 2:
        raise ValueError(f"a frontier grid is 2-D, got shape {g.shape}")
    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution must be a positive number, got {resolution}")
    if reachable is not None and reachable.shape != g.shape:
        raise ValueError(f"reachable mask {reachable.shape} is not the grid's shape {g.shape}")
    return clusters(frontier_cells(g), g, resolution, origin, p.lethal, p.min_size_m / resolution, reachable)


def clusters(
    mask: np.ndarray,
    grid: np.ndarray,
    resolution: float,
    origin: tuple[float, float],
    lethal: int,
    min_cells: float,
    reachable: np.ndarray | None = None,
    kind: str = "map",
) -> list[Frontier]:
    """The 8-connected clusters of `mask` with at least `min_cells` cells, each with its centroid and
    a goal to stand on (the cluster's cell nearest its centroid whose cost on `grid` is below
    `lethal`, among `reachable`), largest first; a cluster with no such cell is dropped."""
    from scipy import ndimage  # the nav extra; here, so the commander starts as fast without a map

    labels, n = ndimage.label(mask, structure=_EIGHT)
    if n == 0:
        return []
    out: list[Frontier] = []
    counts = np.bincount(labels.ravel(), minlength=n + 1)
    standable = (grid >= 0) & (grid < lethal)
    if reachable is not None:
        standable &= reachable
    for lab, box in enumerate(ndimage.find_objects(labels), start=1):
        if box is None or counts[lab] < max(1.0, min_cells):
            continue
        cells = np.argwhere(labels[box] == lab) + (box[0].start, box[1].start)
        ok = cells[standable[cells[:, 0], cells[:, 1]]]
        if len(ok) == 0:
            continue
        cr, cc = cells.mean(axis=0)
        i = int(np.argmin(np.hypot(ok[:, 0] - cr, ok[:, 1] - cc)))
        gr, gc = int(ok[i, 0]), int(ok[i, 1])

        def world(r: float, c: float) -> tuple[float, float]:
            return origin[0] + (c + 0.5) * resolution, origin[1] + (r + 0.5) * resolution

        out.append(
            Frontier(
                id=len(out) + 1,
                centroid=world(cr, cc),
                goal=world(gr, gc),
                goal_cell=(gr, gc),
                size=int(counts[lab]),
                size_m=float(counts[lab] * resolution),
                kind=kind,
            )
        )
    out.sort(key=lambda f: -f.size)
    return [replace(f, id=i + 1) for i, f in enumerate(out)]


def gains(mask: np.ndarray, resolution: float, cells: np.ndarray, radius_m: float) -> np.ndarray:
    """m^2 of `mask` cells (unknown, or free space the camera has not looked at) within `radius_m` of
    each (row, col) of `cells`, over a square window (an integral image: O(cells) for any number of
    them): at most what walking there and looking round would reveal, its information gain."""
    cells = np.asarray(cells, dtype=int).reshape(-1, 2)
    if len(cells) == 0:
        return np.zeros(0)
    h, w = mask.shape
    r = max(0, int(round(radius_m / resolution)))
    s = np.zeros((h + 1, w + 1), np.int64)
    s[1:, 1:] = np.asarray(mask, bool).astype(np.int64).cumsum(0).cumsum(1)
    r0, r1 = np.clip(cells[:, 0] - r, 0, h), np.clip(cells[:, 0] + r + 1, 0, h)
    c0, c1 = np.clip(cells[:, 1] - r, 0, w), np.clip(cells[:, 1] + r + 1, 0, w)
    return (s[r1, c1] - s[r0, c1] - s[r1, c0] + s[r0, c0]) * resolution**2
