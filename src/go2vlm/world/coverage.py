"""Where the camera has looked during a goal: the part of the house the search has seen, as against
the part the lidar has mapped. Pure (numpy), timestamp-free: the caller says when a frame counts.

    cov = Coverage(CoverageParams())
    cov.observe(costmap, resolution, origin, x, y, yaw, view)   # a frame at this pose
    looked = cov.looked_on(costmap.shape, resolution, origin)    # bool, the costmap's cells
    unlooked = cov.unlooked(costmap, resolution, origin, lethal) # standable cells the camera has not seen

Why: the lidar reaches 10 m and through every doorway, the camera's answers find an object a few
metres away. A search that walks only to where the *map* ends leaves rooms the lidar mapped through a
doorway unseen by the camera; one that turns all round at every place looks again at what it has
seen. VLFM explores on the camera's own map for that reason.

Rules
- A fixed world lattice of `cell_m` cells, `size_m` a side round the odom origin (the map's cap);
  cells outside are never looked at.
- A frame looks along `rays` rays spread over the camera's horizontal view (`view`, rad, centred on
  the heading `yaw`), from `near_m` (where the frame's lower edge meets the floor) out to `range_m`,
  each stopping at the first costmap cell of `blocked` or more (an obstacle, within the footprint's
  inscribed radius of one): the camera does not see through walls. Unknown cells do not stop it
  (the camera sees what the lidar did not map); cells off the map neither.
- `unlooked`: costmap cells a robot may stand on (0 <= cost < lethal) that no frame has looked at.
- `unseen_visible`: of those, the ones in the line of sight of a place (rays all round, as a
  frame's), and which way to turn to see them soonest: a look there ends when they are seen, and a
  look at a place whose unseen space lies behind a wall does not turn all round for nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from go2vlm.robot_profile.go2 import HEAD_CAMERA_FOVY_DEG
from go2vlm.world.placement import CameraMount

__all__ = ["AROUND_RAYS", "Coverage", "CoverageParams"]

AROUND_RAYS = 180  # rays all round, for what a look from a place could still see (2 degrees apart)


@dataclass(frozen=True)
class CoverageParams:
    range_m: float = 4.0  # how far a frame's answers find an object (the oracle's boxes, a VLM's)
    # ... and from how near: the floor nearer than where the frame's lower edge meets it is not in the
    # picture (0.98 m from a Go2's base centre): a small thing on the floor beside the robot is not
    # seen, and the cells round it must not count as looked at.
    near_m: float = CameraMount().floor_seen_from(math.radians(HEAD_CAMERA_FOVY_DEG))
    cell_m: float = 0.1  # the lattice
    size_m: float = 60.0  # the lattice's side, round the odom origin (the map's cap)
    rays: int = 33  # rays across the view
    blocked: int = 100  # a costmap value the view stops at (an obstacle and its inscribed band)

    def __post_init__(self) -> None:
        for name in ("range_m", "cell_m", "size_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"coverage {name} must be a positive number, got {v}")
        if self.rays < 2 or self.size_m / self.cell_m > 4000:
            raise ValueError("coverage needs at least 2 rays and at most 4000 cells a side")


class Coverage:
    def __init__(self, params: CoverageParams | None = None) -> None:
        self.base = self.params = p = params or CoverageParams()
        self.half = int(round(p.size_m / p.cell_m / 2))
        self.looked = np.zeros((2 * self.half, 2 * self.half), dtype=bool)  # [row = y, col = x]
        self.frames = 0

    def reset(self) -> None:
        """A new goal: nothing looked at, at the range it began with."""
        self.looked[:] = False
        self.frames = 0
        self.params = self.base

    def closer(self, range_m: float) -> None:
        """Look again at everything, counting a frame only out to `range_m` (a second pass)."""
        self.looked[:] = False
        self.frames = 0
        self.params = replace(self.params, range_m=range_m)

    def _lattice(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Lattice (row, col) of world points, and which are on the lattice."""
        c = np.floor(x / self.params.cell_m).astype(np.int64) + self.half
        r = np.floor(y / self.params.cell_m).astype(np.int64) + self.half
        n = 2 * self.half
        return r, c, (r >= 0) & (r < n) & (c >= 0) & (c < n)

    def _cast(
        self, costmap: np.ndarray, resolution: float, origin: tuple[float, float], x: float, y: float, a: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Rays from (x, y) at world angles `a` out to range_m, sampled finer than a cell: their
        points (x, y), the costmap value under each (-1 off the map), and which lie before the ray's
        first `blocked` cell (the camera does not see through walls)."""
        p = self.params
        step = min(resolution, p.cell_m) / 2.0
        t = np.arange(1, int(p.range_m / step) + 1) * step
        px = x + np.cos(a)[:, None] * t[None, :]
        py = y + np.sin(a)[:, None] * t[None, :]
        g = np.asarray(costmap)
        col = np.floor((px - origin[0]) / resolution).astype(np.int64)
        row = np.floor((py - origin[1]) / resolution).astype(np.int64)
        on = (row >= 0) & (row < g.shape[0]) & (col >= 0) & (col < g.shape[1])
        value = np.full(px.shape, -1, dtype=np.int16)
        value[on] = g[row[on], col[on]]
        stop = value >= p.blocked
        first = np.where(stop.any(axis=1), stop.argmax(axis=1), len(t))
        return px, py, value, (np.arange(len(t))[None, :] < first[:, None]) & (t >= p.near_m)[None, :]

    def observe(
        self,
        costmap: np.ndarray,
        resolution: float,
        origin: tuple[float, float],
        x: float,
        y: float,
        yaw: float,
        view: float,
    ) -> int:
        """A frame taken at (x, y, yaw) with a horizontal view of `view` rad; the cells it newly looked at."""
        p = self.params
        if not all(math.isfinite(v) for v in (x, y, yaw, view)) or view <= 0 or resolution <= 0:
            return 0
        px, py, _, seen = self._cast(costmap, resolution, origin, x, y, yaw + np.linspace(-view / 2, view / 2, p.rays))
        r, c, ok = self._lattice(px[seen], py[seen])
        r, c = r[ok], c[ok]
        new = int((~self.looked[r, c]).sum())
        self.looked[r, c] = True
        self.frames += 1
        return new

    def looked_on(self, shape: tuple[int, int], resolution: float, origin: tuple[float, float]) -> np.ndarray:
        """bool, `shape`: the cells of a grid (resolution, origin as a costmap's) whose centre was looked at."""
        rows, cols = np.indices(shape)
        r, c, ok = self._lattice(origin[0] + (cols + 0.5) * resolution, origin[1] + (rows + 0.5) * resolution)
        out = np.zeros(shape, dtype=bool)
        out[ok] = self.looked[r[ok], c[ok]]
        return out

    def unlooked(self, costmap: np.ndarray, resolution: float, origin: tuple[float, float], lethal: int) -> np.ndarray:
        """bool: the costmap's cells a robot may stand on that no frame has looked at."""
        g = np.asarray(costmap)
        return (g >= 0) & (g < lethal) & ~self.looked_on(g.shape, resolution, origin)

    def looked_at(self, x: float, y: float) -> bool:
        """Has a frame looked at the world point (x, y)?"""
        r, c, ok = self._lattice(np.array([x]), np.array([y]))
        return bool(ok[0] and self.looked[r[0], c[0]])

    def unseen_visible(
        self,
        costmap: np.ndarray,
        resolution: float,
        origin: tuple[float, float],
        lethal: int,
        x: float,
        y: float,
        yaw: float,
        view: float,
    ) -> tuple[float, float, float]:
        """What a look from (x, y) could still see: m^2 of standable, unlooked cells in its line of
        sight all round (rays as a frame's, `AROUND_RAYS` of them over 360 degrees), and the turn left
        and the turn right (rad, >= 0) that would bring all of them into a `view` rad wide view from
        the heading `yaw`. Cells behind a wall do not count: no turn here would see them."""
        p = self.params
        if not all(math.isfinite(v) for v in (x, y, yaw, view)) or resolution <= 0:
            return 0.0, 0.0, 0.0
        a = np.linspace(-math.pi, math.pi, AROUND_RAYS, endpoint=False)
        px, py, value, seen = self._cast(costmap, resolution, origin, x, y, yaw + a)
        r, c, ok = self._lattice(px, py)
        want = seen & ok & (value >= 0) & (value < lethal)
        want[want] = ~self.looked[r[want], c[want]]
        if not want.any():
            return 0.0, 0.0, 0.0
        cells = np.unique(r[want] * (2 * self.half) + c[want])
        b = np.broadcast_to(a[:, None], want.shape)[want]  # bearings off the heading, [-pi, pi)
        half = view / 2.0
        out = np.abs(b) > half  # those in the view now need no turn
        left = float(np.where(out, np.where(b >= 0, b, b + 2 * math.pi) - half, 0.0).max())
        right = float(np.where(out, np.where(b <= 0, -b, 2 * math.pi - b) - half, 0.0).max())
        return len(cells) * p.cell_m**2, left, right
