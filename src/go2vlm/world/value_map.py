"""VLFM's value map: the model's scores of the views it was shown, placed in the world. Pure.

A scored view is where the robot stood and which way it faced when the frame was taken, the
camera's field of view, and a score in [0, 1] (behavior/view_scores.py: likely 1, maybe 0.5,
unlikely 0). It is spread over the cells the camera could have seen: inside the view's cone, out
to `range_m`, and along each ray only up to the first obstacle on the costmap (a score says nothing
of what lies behind a wall). Unknown cells are passed through: a frontier lies where the known
ends.

Each cell's confidence in a view falls off from the optical axis, cos^2(theta / (hfov / 2) x pi / 2)
(VLFM: what an image is about is in its middle). A cell seen again blends the two by confidence:
value = (c v + c' s) / (c + c'), confidence = (c^2 + c'^2) / (c + c'), so a view straight at a cell
outweighs a glance at its edge, and a newer view never simply erases an older one.

`at(x, y)` is the confidence-weighted value within `radius_m` of a place (a frontier's centroid);
`unscored` where no view covered it. The cells live in their own sparse grid of `resolution` in
the odometry frame, so the map round them may grow or shift without moving a score.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from go2vlm.world.occupancy import LETHAL

__all__ = ["Grid", "ValueMap"]


class Grid(Protocol):
    """What the value map needs of a costmap: its cells and where they lie."""

    @property
    def data(self) -> np.ndarray: ...
    @property
    def resolution(self) -> float: ...
    @property
    def origin(self) -> tuple[float, float]: ...


@dataclass
class ValueMap:
    resolution: float = 0.2  # m: the value map's own cells
    range_m: float = 8.0  # a view's score reaches this far along each ray, at most
    radius_m: float = 0.6  # a place's value: the cells within this of it
    unscored: float = 0.5  # a place no view covered counts as maybe
    cells: dict[tuple[int, int], tuple[float, float]] = field(default_factory=dict)  # -> (value, confidence)
    views: int = 0  # views placed

    def clear(self) -> None:
        self.cells.clear()
        self.views = 0

    def observe(self, x: float, y: float, yaw: float, hfov: float, score: float, grid: Grid | None) -> int:
        """Place one scored view taken at (x, y) facing `yaw` with a camera `hfov` wide (rad); the rays
        stop at `grid`'s obstacles (None: no map, the whole cone). Returns the cells it touched."""
        if not all(math.isfinite(v) for v in (x, y, yaw, hfov, score)) or not (0.0 <= score <= 1.0) or hfov <= 0:
            return 0
        half = min(hfov, math.pi) / 2
        coarse = self.resolution / 2  # the value map's samples along a ray
        fine = coarse if grid is None else min(coarse, grid.resolution / 2)  # the walls' (none slips through)
        k = max(1, int(round(coarse / fine)))
        n_rays = max(3, int(math.ceil(2 * half * self.range_m / coarse)) + 1)
        offs = np.linspace(-half, half, n_rays)
        conf = np.cos(offs / half * math.pi / 2) ** 2  # per ray
        a = (yaw + offs)[:, None]
        dists = np.arange(1, int(self.range_m / fine) + 1) * fine
        run = _free_run(x + dists[None, :] * np.cos(a), y + dists[None, :] * np.sin(a), grid)  # fine samples
        d = dists[k - 1 :: k]  # the coarse samples, each the last of its k fine ones
        keep = (np.arange(len(d))[None, :] * k + k <= run[:, None]) & (conf[:, None] > 1e-6)
        px, py = x + d[None, :] * np.cos(a), y + d[None, :] * np.sin(a)
        ci = np.floor(px[keep] / self.resolution).astype(np.int64)
        cj = np.floor(py[keep] / self.resolution).astype(np.int64)
        c = np.broadcast_to(conf[:, None], keep.shape)[keep]
        order = np.argsort(-c, kind="stable")  # each cell's confidence: the ray nearest the axis
        ci, cj, c = ci[order], cj[order], c[order]
        _, first = np.unique((ci << 32) + (cj & 0xFFFFFFFF), return_index=True)
        best = {(int(ci[i]), int(cj[i])): float(c[i]) for i in first}
        for cell, cn in best.items():
            old = self.cells.get(cell)
            if old is None:
                self.cells[cell] = (score, cn)
            else:
                v0, c0 = old
                self.cells[cell] = ((c0 * v0 + cn * score) / (c0 + cn), (c0 * c0 + cn * cn) / (c0 + cn))
        self.views += 1
        return len(best)

    def at(self, x: float, y: float) -> float:
        """The value round (x, y): confidence-weighted over the cells within `radius_m`; `unscored`
        where no view covered any of them."""
        r = int(math.ceil(self.radius_m / self.resolution))
        ci, cj = int(math.floor(x / self.resolution)), int(math.floor(y / self.resolution))
        num = den = 0.0
        for i in range(ci - r, ci + r + 1):
            for j in range(cj - r, cj + r + 1):
                hit = self.cells.get((i, j))
                if hit is None:
                    continue
                if math.hypot((i + 0.5) * self.resolution - x, (j + 0.5) * self.resolution - y) > self.radius_m:
                    continue
                num += hit[0] * hit[1]
                den += hit[1]
        return num / den if den > 0 else self.unscored


def _free_run(px: np.ndarray, py: np.ndarray, grid: Grid | None) -> np.ndarray:
    """For each ray (a row of points), how many of its points come before its first obstacle cell on
    `grid` (all of them without a grid; off the grid counts as unknown: passed through)."""
    n = px.shape[1]
    if grid is None:
        return np.full(px.shape[0], n)
    h, w = grid.data.shape
    c = np.floor((px - grid.origin[0]) / grid.resolution).astype(np.int64)
    r = np.floor((py - grid.origin[1]) / grid.resolution).astype(np.int64)
    inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
    blocked = np.zeros(px.shape, bool)
    blocked[inside] = grid.data[r[inside], c[inside]] >= LETHAL
    return np.where(blocked.any(axis=1), blocked.argmax(axis=1), n)
