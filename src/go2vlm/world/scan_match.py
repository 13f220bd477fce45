"""Scan matching against the occupancy map: where the robot is, given where odometry says it is and
what the lidar sees. Pure numpy, no I/O.

    field = LikelihoodField.around(grid, guess.x, guess.y, half_size_m=6.0, sigma_m=0.1)
    m = match(field, points, guess, MatchParams())     # points: the scan's returns in the base frame
    if m.ok: pose = m.pose                             # else keep the odometry's guess (m.reason says why)

How
- The field: each cell of a window of the map about the guess holds exp(-d^2 / 2 sigma^2), d the
  distance from its centre to the nearest occupied cell (a distance transform); cells the map has
  never seen are marked unknown.
- A coarse correlative search first: every yaw within +-search_yaw_rad (yaw_step_rad apart) and every
  whole-cell shift within +-search_xy_m, scored by the mean field under the scan's returns (the
  Corrector skips it while its matches hold: odometry is then off by millimetres a scan). Then
  Gauss-Newton on the bilinear field (as Hector SLAM does on its map) refines the best one below a
  cell, with a weak pull back to the guess (prior_weight) so that a corridor, which fixes only the
  sideways position, does not slide the pose along itself. The step is held within the search window.
- Accepted (ok) only when at least min_points returns fall on mapped cells near a wall (field > 0.5)
  and their mean field is at least min_score: a scan of a place the map does not know, or one that
  fits nowhere, keeps the guess (reason few_points or weak).

Why our own and not a library (measured, docs/benchmarks.md, `bench_map.py --sections icp`): on a
100 m walk with a Go2's drift small_gicp's ICP is as accurate and nearly twice as fast (0.8 ms a
scan against 1.4 ms), but it follows whatever correspondences it finds as far as they lead and says
nothing of whether a match holds; this matcher stays within its window, refuses a weak match (`fit`,
which the map node's odometry-jump check uses too), needs no compiled dependency, and fits the
5 ms budget. `Corrector.locate` is the one place to swap it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from go2vlm.world.occupancy import OccupancyMap, bounded_distance
from go2vlm.world.poses import IDENTITY, Pose2D, wrap_angle

__all__ = ["Corrector", "LikelihoodField", "Match", "MatchParams", "fit", "match"]

FIELD_SIGMAS = 5.0  # the likelihood field is exact this many sigmas out, 0 beyond (exp(-12.5) < 4e-6)


@dataclass(frozen=True)
class MatchParams:
    sigma_m: float = 0.1  # the field's width round an occupied cell
    search_xy_m: float = 0.1  # the coarse search: shifts within +- this ...
    search_yaw_rad: float = 0.05  # ... and turns within +- this (about 3 degrees) ...
    yaw_step_rad: float = 0.0125  # ... this far apart
    iterations: int = 6  # Gauss-Newton steps after it
    prior_weight: float = 2.0  # the pull back to the guess, in returns' worth (per m and per rad)
    min_points: int = 40  # returns on mapped walls for a match to count ...
    min_score: float = 0.45  # ... and their mean field at least this
    max_points: int = 240  # at most this many returns are used (evenly thinned)

    def __post_init__(self) -> None:
        if not (self.sigma_m > 0 and self.search_xy_m >= 0 and self.search_yaw_rad >= 0 and self.yaw_step_rad > 0):
            raise ValueError("need sigma_m > 0, search_xy_m >= 0, search_yaw_rad >= 0, yaw_step_rad > 0")
        if not (self.min_points >= 3 and 0 < self.min_score < 1 and self.max_points >= self.min_points):
            raise ValueError("need min_points >= 3, 0 < min_score < 1 and max_points >= min_points")


@dataclass(frozen=True)
class Match:
    """The matched pose (the guess when not ok), the mean field of the returns used, how many returns
    sat on mapped walls, and why it was not taken ('' when ok)."""

    pose: Pose2D
    score: float
    support: int
    reason: str

    @property
    def ok(self) -> bool:
        return not self.reason


class LikelihoodField:
    """How well a world point fits the map's walls (1 on one, falling with distance), on a window."""

    def __init__(self, field: np.ndarray, known: np.ndarray, origin: tuple[float, float], resolution: float) -> None:
        self.field = field  # [rows = y, cols = x], float32
        self.known = known  # cells the map has seen
        self.origin = origin  # world x, y of cell (0, 0)'s outer corner
        self.resolution = resolution
        # A zero border two cells wide round it: a lookup outside the window clips onto the border and
        # reads 0, also for the second cell of a bilinear one.
        self._padded = np.pad(field, 2).reshape(-1)
        self._width = field.shape[1] + 4 if field.size else 0

    @staticmethod
    def around(grid: OccupancyMap, x: float, y: float, half_size_m: float, sigma_m: float) -> LikelihoodField:
        """The field on the part of `grid` within half_size_m of (x, y)."""
        res = grid.resolution
        rows, cols = grid.shape
        r0, c0 = grid.cell_of(x - half_size_m, y - half_size_m)
        r1, c1 = grid.cell_of(x + half_size_m, y + half_size_m)
        r0, c0, r1, c1 = max(r0, 0), max(c0, 0), min(r1 + 1, rows), min(c1 + 1, cols)
        if r1 <= r0 or c1 <= c0:
            empty = np.zeros((0, 0), dtype=np.float32)
            return LikelihoodField(empty, empty.astype(bool), grid.origin, res)
        lo = grid.logodds[r0:r1, c0:c1]
        occupied = lo >= grid.params.occupied_logodds
        if occupied.any():
            d = bounded_distance(occupied, int(math.ceil(FIELD_SIGMAS * sigma_m / res))) * res  # beyond: 0
            field = np.exp(-0.5 * (d / sigma_m) ** 2).astype(np.float32)
        else:
            field = np.zeros(lo.shape, dtype=np.float32)
        ox, oy = grid.origin
        return LikelihoodField(field, lo != 0, (ox + c0 * res, oy + r0 * res), res)

    @property
    def empty(self) -> bool:
        return self.field.size == 0

    def contains(self, x: float, y: float, margin_m: float) -> bool:
        """(x, y) lies at least margin_m inside the window."""
        rows, cols = self.field.shape
        fx, fy = (x - self.origin[0]) / self.resolution, (y - self.origin[1]) / self.resolution
        m = margin_m / self.resolution
        return m <= fx <= cols - m and m <= fy <= rows - m

    def cells(self, wx: np.ndarray, wy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (
            np.floor((wy - self.origin[1]) / self.resolution).astype(np.int64),
            np.floor((wx - self.origin[0]) / self.resolution).astype(np.int64),
        )

    def lookup(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """The field at cells (0 outside the window)."""
        h, w = self.field.shape
        r = np.minimum(np.maximum(rows + 2, 0), h + 3)
        c = np.minimum(np.maximum(cols + 2, 0), w + 3)
        return self._padded[r * self._width + c]

    def bilinear(self, wx: np.ndarray, wy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The field at world points, interpolated between cell centres, and its x and y gradients."""
        h, w = self.field.shape
        fx = (wx - self.origin[0]) / self.resolution - 0.5
        fy = (wy - self.origin[1]) / self.resolution - 0.5
        c0, r0 = np.floor(fx), np.floor(fy)
        ax, ay = fx - c0, fy - r0
        base = (np.minimum(np.maximum(r0.astype(np.int64) + 2, 0), h + 2) * self._width
                + np.minimum(np.maximum(c0.astype(np.int64) + 2, 0), w + 2))  # fmt: skip
        f = self._padded
        v00, v01 = f[base], f[base + 1]
        v10, v11 = f[base + self._width], f[base + self._width + 1]
        value = (1 - ay) * ((1 - ax) * v00 + ax * v01) + ay * ((1 - ax) * v10 + ax * v11)
        gx = ((1 - ay) * (v01 - v00) + ay * (v11 - v10)) / self.resolution
        gy = ((1 - ax) * (v10 - v00) + ax * (v11 - v01)) / self.resolution
        return value, gx, gy


def _to_world(points: np.ndarray, x: float, y: float, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    c, s = math.cos(yaw), math.sin(yaw)
    return x + c * points[:, 0] - s * points[:, 1], y + s * points[:, 0] + c * points[:, 1]


def match(field: LikelihoodField, points: np.ndarray, guess: Pose2D, params: MatchParams) -> Match:
    """The pose that best lays `points` (the scan's returns, (N, 2) in the base frame) on the map's
    walls, near `guess` (module docstring)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) > params.max_points:
        pts = pts[np.linspace(0, len(pts) - 1, params.max_points).astype(np.int64)]
    if field.empty or len(pts) < params.min_points:
        return Match(guess, 0.0, 0, "few_points")
    # Coarse: whole-cell shifts x a few turns.
    k = int(params.search_xy_m / field.resolution)
    shifts = np.arange(-k, k + 1)
    dr, dc = (a.reshape(-1, 1) for a in np.meshgrid(shifts, shifts, indexing="ij"))
    n_yaw = int(params.search_yaw_rad / params.yaw_step_rad)
    best = (-1.0, 0.0, 0.0, 0.0)
    for dyaw in params.yaw_step_rad * np.arange(-n_yaw, n_yaw + 1):
        wx, wy = _to_world(pts, guess.x, guess.y, guess.yaw + dyaw)
        rows, cols = field.cells(wx, wy)
        scores = field.lookup(rows[None, :] + dr, cols[None, :] + dc).mean(axis=1)
        i = int(np.argmax(scores))
        if scores[i] > best[0]:
            best = (float(scores[i]), float(dc[i, 0]) * field.resolution, float(dr[i, 0]) * field.resolution, dyaw)
    _, x, y, yaw = best
    x, y, yaw = guess.x + x, guess.y + y, guess.yaw + yaw
    # Fine: Gauss-Newton on 1 - field, with a weak prior at the guess; a step that does not lower the
    # cost is halved (the bilinear field is only piecewise smooth).
    w = params.prior_weight

    def cost(x: float, y: float, yaw: float) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        wx, wy = _to_world(pts, x, y, yaw)
        value, gx, gy = field.bilinear(wx, wy)
        off = np.array([x - guess.x, y - guess.y, wrap_angle(yaw - guess.yaw)])
        resid = 1.0 - value
        jac = np.column_stack([gx, gy, gx * -(wy - y) + gy * (wx - x)])  # d(field)/d(x, y, yaw)
        return float(resid @ resid + w * off @ off), resid, jac, off, value

    c0, resid, jac, off, _ = cost(x, y, yaw)
    for _ in range(params.iterations):
        try:
            step = np.linalg.solve(jac.T @ jac + w * np.eye(3), jac.T @ resid - w * off)
        except np.linalg.LinAlgError:
            break
        for _ in range(4):
            c1, r1, j1, o1, _ = cost(x + step[0], y + step[1], yaw + step[2])
            if c1 < c0:
                break
            step = step / 2
        else:
            break
        x, y, yaw = x + step[0], y + step[1], yaw + step[2]
        c0, resid, jac, off = c1, r1, j1, o1
        if abs(step[0]) + abs(step[1]) < 1e-4 and abs(step[2]) < 1e-4:
            break
    # Held within the search window (plus a cell): never a leap to another wall.
    lim = params.search_xy_m + field.resolution
    x = guess.x + float(np.clip(x - guess.x, -lim, lim))
    y = guess.y + float(np.clip(y - guess.y, -lim, lim))
    lim_yaw = params.search_yaw_rad + params.yaw_step_rad
    yaw = guess.yaw + float(np.clip(wrap_angle(yaw - guess.yaw), -lim_yaw, lim_yaw))
    pose = Pose2D(x, y, wrap_angle(yaw))
    score, support, _ = fit(field, pts, pose)
    if support < params.min_points:
        return Match(guess, score, support, "few_points")
    if score < params.min_score:
        return Match(guess, score, support, "weak")
    return Match(pose, score, support, "")


def fit(field: LikelihoodField, points: np.ndarray, pose: Pose2D) -> tuple[float, int, int]:
    """How well `points` (base frame) at `pose` lie on the map: the mean field of those on cells the
    map has seen, how many of those sit on a wall (field > 0.5), and how many fell on seen cells."""
    wx, wy = _to_world(np.asarray(points, dtype=np.float64).reshape(-1, 2), pose.x, pose.y, pose.yaw)
    value, _, _ = field.bilinear(wx, wy)
    rows, cols = field.cells(wx, wy)
    h, w = field.known.shape
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    known = np.zeros(len(wx), dtype=bool)
    known[inside] = field.known[rows[inside], cols[inside]]
    score = float(value[known].mean()) if known.any() else 0.0
    return score, int((known & (value > 0.5)).sum()), int(known.sum())


class Corrector:
    """Odometry corrected against a growing map: the correction (map <- odom) from the newest match
    that held, and the field it matches on, rebuilt every `field_every` integrated scans or when the
    robot nears its edge. `locate` is what the map node does with each scan before integrating it."""

    def __init__(self, params: MatchParams | None = None, window_m: float = 6.0, field_every: int = 5) -> None:
        self.params = params or MatchParams()
        # While matches hold, odometry is off by millimetres a scan: Gauss-Newton alone (its window a
        # cell and a yaw step), the coarse search only after a match that did not hold.
        self.tracking_params = replace(self.params, search_xy_m=0.0, search_yaw_rad=0.0)
        self.window_m = window_m
        self.field_every = field_every
        self.correction = IDENTITY
        self.tracking = False
        self._field: LikelihoodField | None = None
        self._age = 0

    def field(self, grid: OccupancyMap, pose: Pose2D) -> LikelihoodField:
        f = self._field
        if f is None or self._age >= self.field_every or not f.contains(pose.x, pose.y, self.window_m / 2):
            f = self._field = LikelihoodField.around(grid, pose.x, pose.y, self.window_m, self.params.sigma_m)
            self._age = 0
        return f

    def locate(
        self, grid: OccupancyMap, points: np.ndarray, odom: Pose2D, matching: bool
    ) -> tuple[Pose2D, Match | None]:
        """The scan's pose: odometry corrected, then (matching, on a map with something in it) matched;
        a match that holds becomes the correction."""
        guess = self.correction.compose(odom)
        if not matching or grid.empty:
            return guess, None
        m = match(self.field(grid, guess), points, guess, self.tracking_params if self.tracking else self.params)
        if m.ok:
            self.correction = m.pose.compose(odom.inverse())  # map <- odom
        self.tracking = m.ok
        return m.pose, m

    def integrated(self) -> None:
        """A scan went into the map: the field ages."""
        self._age += 1

    def reset(self) -> None:
        self.correction = IDENTITY
        self.tracking = False
        self._field, self._age = None, 0
