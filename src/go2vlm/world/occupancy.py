"""The occupancy map without any I/O: laser scans in, a log-odds grid in the odom frame out, and the
costmap a planner reads from it.

    grid = OccupancyMap(GridParams())
    result = grid.integrate(beams, pose)          # one scan at the pose of its stamp (world/poses.py)
    values = grid.values()                        # ROS OccupancyGrid cells: -1 unknown, 0 free, 100 occupied
    cost = inflate(values, grid.resolution, CostmapParams.for_footprint(0.70, 0.31))

Frame and cells
- Cells are squares of `resolution_m` on a fixed world lattice: the cell of world (x, y) is
  (floor(x / res), floor(y / res)) whatever the grid's extent, so growing the grid never moves a cell.
- Arrays are indexed [row, col] = [y, x]; `origin` is the world x, y of cell (0, 0)'s outer corner
  (its lowest x and y), as nav_msgs/MapMetaData.origin (yaw 0). Row-major, row 0 first: the ROS
  OccupancyGrid data order.

Rules
- A scan is placed at a pose (x, y, yaw in odom) with its beams starting at the scan frame's origin
  (`Beams.origin`, in the base frame: /scan is in base_link and its ranges are from the base origin).
  A return proves free the segment from the sensor that measured it (`Beams.sensor`: the Go2's lidar
  sits 0.29 m ahead of the base), not the beam from the origin: with the robot in a doorway, its base
  behind the wall's plane and its lidar past it, beams from the base to the wall's far face ran
  through the wall and wore it away beside the door. A beam without a return stays a ray from the
  origin: the scan's bins are the origin's bearings, and nothing was seen in that one.
- Each beam: a finite range in [range_min, range_max] is a hit: its end cell gains `hit` log-odds and
  the cells before it on the ray, up to a cell short of the end, lose `miss` (a range under
  range_min is a hit with no free ray: too close is not free). +inf, or a range beyond range_max,
  is no return (REP 117): the ray clears free space up to range_max, at most `no_return_m`, and
  marks nothing; but a run of them between two
  beams with returns that is no wider than GAP_ANGLE (60 degrees), or than 1.2 x atan(the parallax /
  the nearest return within NEAR_BEAMS of the run), is a gap in the sampling, not an opening (a /scan
  binned from a cloud leaves such holes: along walls, and wide ones beside a near object, as the
  Go2's lidar sits 0.29 m ahead of the base): it clears only up to the nearer of the two returns,
  less a cell, and never clears a cell the map holds occupied, nor any past it: a hole in the
  sampling cannot see through a wall seen before (a leak through it would read as a frontier
  outside). Every other ray clears what it passes through, a ray without a return too: it looked,
  and what the map held on it has moved (a door opened, an object taken away).
  NaN ranges are dropped and counted (`nan`); -inf and negative ranges too (`invalid`). A cell gains or loses once
  per scan, and a cell hit by this scan is not cleared by another of its rays grazing it. Log-odds
  are clamped to [min_logodds, max_logodds], so a moved object is cleared after a few scans.
- Rays are sampled every half cell (a vectorised walk; corner-clipped cells may be skipped).
- What a scan shows free is the wedge between each two neighbouring beams, out to the nearer of their
  free lengths: where the beams end more than SPREAD cells apart, rays filled in between them clear
  it, as weakly as a gap (nothing the map holds occupied, nor past it). Beams alone left unseen
  slivers between them from res / increment on (2.9 m at 5 cm and 1 degree), and one across a narrow
  doorway cut it in two for the planner.
- Grows with what it sees, `grow_margin_m` at a time, up to `max_size_m` a side; beyond that cap the
  part of a scan outside is dropped (`beyond_cap`, counted per beam), and a scan whose origin is
  outside is refused whole (ScanRefused("beyond_cap")). A bad scan geometry is refused whole
  (ScanRefused("bad_geometry")). Nothing is written until the whole scan has been checked: a refused
  scan leaves the grid as it was.
- `values()`: log-odds >= occupied_logodds -> 100, <= free_logodds -> 0, between (and never seen) -> -1.
- `inflate` (the costmap's cell codes, defined here once: UNKNOWN, FREE, CIRCUMSCRIBED, INSCRIBED,
  LETHAL): LETHAL (100) on an occupied cell; INSCRIBED (99) wherever the robot's centre puts its
  footprint within the creep's clearance (geometry/footprint.py `Clearance`) of one whatever its heading
  (the inscribed radius + padding: never entered); CIRCUMSCRIBED..98 (90..98) where it may, by heading
  (out to the circumscribed radius + padding: a cost, not a wall: the global planner checks the
  footprint's rectangle there at the heading the path gives it, so a doorway is crossed square-on);
  then a cost falling from 89 to 1 out to `inflation_m`; 0 free; -1 unknown, but within the inscribed
  radius of an obstacle (never entered). The cost bands are not inflated into the unknown, whose edge
  is the frontier.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from go2vlm.geometry.footprint import Clearance
from go2vlm.world.poses import Pose2D

__all__ = [
    "CIRCUMSCRIBED",
    "FREE",
    "INSCRIBED",
    "LETHAL",
    "UNKNOWN",
    "Beams",
    "CostmapParams",
    "GridParams",
    "Integrated",
    "OccupancyMap",
    "ScanRefused",
    "bounded_distance",
    "inflate",
]

# The costmap's cell codes (ROS OccupancyGrid values; `inflate`): unknown, free, the lowest code of the
# band where the footprint fits at some headings only, within the inscribed radius (never entered), an
# obstacle. Costs 1..CIRCUMSCRIBED-1 fall with the distance beyond the circumscribed radius.
UNKNOWN, FREE, CIRCUMSCRIBED, INSCRIBED, LETHAL = -1, 0, 90, 99, 100


@dataclass(frozen=True)
class GridParams:
    resolution_m: float = 0.05
    max_size_m: float = 60.0  # the cap, a side
    grow_margin_m: float = 2.0  # the grid grows this much past what a scan needs
    hit: float = 0.9  # log-odds a return adds to its cell
    miss: float = 0.4  # log-odds a ray through a cell takes
    min_logodds: float = -2.0
    max_logodds: float = 3.5
    no_return_m: float = 4.0  # a beam without a return clears free space this far at most
    occupied_logodds: float = 0.5  # /map: occupied at or above (one hit) ...
    free_logodds: float = -0.3  # ... free at or below (one ray through)

    def __post_init__(self) -> None:
        if not (0.005 <= self.resolution_m <= 1.0):
            raise ValueError(f"resolution_m must be in [0.005, 1.0], got {self.resolution_m}")
        if not (self.resolution_m * 8 <= self.max_size_m <= 1000.0):
            raise ValueError(f"max_size_m must be in [8 cells, 1000 m], got {self.max_size_m}")
        if not (self.hit > 0 and self.miss > 0 and self.min_logodds < self.free_logodds < 0):
            raise ValueError("need hit > 0, miss > 0 and min_logodds < free_logodds < 0")
        if not (0 < self.occupied_logodds <= self.hit <= self.max_logodds):
            raise ValueError("need 0 < occupied_logodds <= hit <= max_logodds: one return must mark a cell")
        if self.free_logodds < -self.miss:
            raise ValueError("need free_logodds >= -miss: one ray must clear a cell")

    @property
    def max_cells(self) -> int:
        return int(round(self.max_size_m / self.resolution_m))


@dataclass(frozen=True)
class Beams:
    """A planar scan in numbers (a sensor_msgs/LaserScan's fields): ranges from `origin` (the scan
    frame's origin in the base frame), beam i at angle_min + i * angle_increment."""

    ranges: np.ndarray
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    origin: tuple[float, float] = (0.0, 0.0)
    sensor: tuple[float, float] | None = None  # where the returns were measured from (base frame; None: origin)

    @property
    def parallax_m(self) -> float:
        """How far the sensor sits from `origin` (the scan was binned from there)."""
        sx, sy = self.sensor or self.origin
        return math.hypot(sx - self.origin[0], sy - self.origin[1])

    def returns(self) -> np.ndarray:
        """The returns (finite ranges within [0, range_max]) as (N, 2) points in the base frame."""
        r = np.asarray(self.ranges, dtype=np.float64).reshape(-1)
        with np.errstate(invalid="ignore"):
            hit = np.isfinite(r) & (r >= 0) & (r <= self.range_max)
        a = self.angle_min + self.angle_increment * np.nonzero(hit)[0]
        return np.column_stack([self.origin[0] + r[hit] * np.cos(a), self.origin[1] + r[hit] * np.sin(a)])


class ScanRefused(ValueError):
    """A scan the map took nothing from; `reason`: bad_geometry | beyond_cap."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


@dataclass(frozen=True)
class Integrated:
    """What one scan gave: beams with a return, beams without (free rays only), and those dropped."""

    hits: int
    no_return: int
    nan: int
    invalid: int
    beyond_cap: int
    grew: bool


class OccupancyMap:
    """A growing log-odds grid (see the module docstring)."""

    def __init__(self, params: GridParams | None = None) -> None:
        self.params = params or GridParams()
        self.logodds = np.zeros((0, 0), dtype=np.float32)
        self.offset = (0, 0)  # lattice index (ix, iy) of cell (0, 0)
        self.scans = 0

    # -- geometry --------------------------------------------------------------------------
    @property
    def resolution(self) -> float:
        return self.params.resolution_m

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) = (cells along y, cells along x)."""
        return self.logodds.shape

    @property
    def origin(self) -> tuple[float, float]:
        """World x, y of cell (0, 0)'s outer corner."""
        return self.offset[0] * self.resolution, self.offset[1] * self.resolution

    @property
    def empty(self) -> bool:
        return self.logodds.size == 0

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of world (x, y); may be outside the grid."""
        return (math.floor(y / self.resolution) - self.offset[1], math.floor(x / self.resolution) - self.offset[0])

    def center_of(self, row: int, col: int) -> tuple[float, float]:
        """World x, y of a cell's centre."""
        return (col + self.offset[0] + 0.5) * self.resolution, (row + self.offset[1] + 0.5) * self.resolution

    # -- integration ------------------------------------------------------------------------
    def integrate(self, beams: Beams, pose: Pose2D) -> Integrated:
        """One scan at `pose`; ScanRefused (and the grid unchanged) when nothing of it can be used."""
        p = self.params
        _check_geometry(beams)
        r = np.asarray(beams.ranges, dtype=np.float64).reshape(-1)
        nan = np.isnan(r)
        invalid = ~nan & ((r == -np.inf) | (r < 0))
        usable = ~nan & ~invalid
        hit = usable & np.isfinite(r) & (r <= beams.range_max)
        no_return = usable & ~hit
        angles = beams.angle_min + beams.angle_increment * np.arange(len(r))
        ox, oy = pose.to_world(*beams.origin)
        wa = angles + pose.yaw
        dx, dy = np.cos(wa), np.sin(wa)
        # Free rays: to the return (not for one under range_min), or to range_max without one; but a
        # lone beam without a return between two with one is a gap in the sampling (a scan binned
        # from a cloud leaves such holes in a wall), not a hole in the wall: it clears only as far as
        # the nearer of its neighbours' returns.
        clear = min(beams.range_max, p.no_return_m)
        # A return's own ray stops a cell short of it: the cell before the end may hold the same wall
        # (a ray meets a wall inside the cell it ends in, or the one before), and clearing it would
        # pit the wall with holes.
        res = self.resolution
        free_len = np.where(hit, np.where(r >= beams.range_min, np.maximum(r - res, 0.0), 0.0),
                            np.where(no_return, clear, 0.0))  # fmt: skip
        wraps = len(r) * beams.angle_increment > 2 * math.pi - 1.5 * beams.angle_increment
        gap, bound = _gaps(np.where(hit, r, np.inf), no_return, wraps, beams.angle_increment, beams.parallax_m)
        free_len[gap] = np.maximum(bound[gap] - res, 0.0)
        hx, hy = ox + r[hit] * dx[hit], oy + r[hit] * dy[hit]
        step = res / 2.0
        # A return's ray is the segment from the sensor that measured it.
        sx, sy = pose.to_world(*(beams.sensor or beams.origin))
        rox, roy = np.full(len(r), ox), np.full(len(r), oy)
        seg = np.nonzero(hit & (r >= beams.range_min))[0]
        rox[seg], roy[seg] = sx, sy
        vx, vy = ox + r[seg] * dx[seg] - sx, oy + r[seg] * dy[seg] - sy
        seg_len = np.maximum(np.hypot(vx, vy), 1e-9)
        ray_dx, ray_dy, ray_len = dx.copy(), dy.copy(), free_len.copy()
        ray_dx[seg], ray_dy[seg], ray_len[seg] = vx / seg_len, vy / seg_len, np.maximum(seg_len - res, 0.0)
        # The free space a scan shows is the wedge between two neighbouring beams, out to the nearer of
        # their free lengths, not the beams alone: beyond res / increment (2.9 m at 5 cm and 1 degree)
        # the beams are more than a cell apart and leave unseen slivers between them (one across a
        # 0.75 m doorway seen from 3.6 m cut it in two for the planner, houses 002). Rays in between,
        # as weak as a gap's: they clear nothing the map holds occupied, nor anything past it.
        apart = SPREAD * res
        ex_dx, ex_dy, ex_len = _between(wa, free_len, usable, beams.angle_increment, apart, wraps)
        dx, dy = np.concatenate((ray_dx, ex_dx)), np.concatenate((ray_dy, ex_dy))
        free_len = np.concatenate((ray_len, ex_len))
        rox, roy = np.concatenate((rox, np.full(len(ex_len), ox))), np.concatenate((roy, np.full(len(ex_len), oy)))
        weak_ray = np.concatenate((gap, np.ones(len(ex_len), dtype=bool)))
        # ... from where the beams are `apart` (nearer, the beams' own samples cover the wedge), in
        # longer steps than a beam's: their neighbours fill what one steps over.
        filled = np.arange(len(free_len)) >= len(r)
        start = np.where(filled, apart / abs(beams.angle_increment), 0.0)
        steps = np.where(filled, res * FILL_STEP, step)
        n = np.maximum(np.ceil((free_len - start) / steps), 0).astype(np.int64)
        total = int(n.sum())
        ray = np.repeat(np.arange(len(n)), n)
        t = start[ray] + (np.arange(total) - np.repeat(np.cumsum(n) - n, n)) * steps[ray]
        fx, fy = rox[ray] + t * dx[ray], roy[ray] + t * dy[ray]
        # Lattice indices of everything this scan touches, then the window it may write.
        o_ix, o_iy = math.floor(ox / res), math.floor(oy / res)
        h_ix, h_iy = np.floor(hx / res).astype(np.int64), np.floor(hy / res).astype(np.int64)
        f_ix, f_iy = np.floor(fx / res).astype(np.int64), np.floor(fy / res).astype(np.int64)
        xs = [o_ix, *(a.min() for a in (h_ix, f_ix) if a.size), *(a.max() for a in (h_ix, f_ix) if a.size)]
        ys = [o_iy, *(a.min() for a in (h_iy, f_iy) if a.size), *(a.max() for a in (h_iy, f_iy) if a.size)]
        x_lo, x_hi = self._window(0, o_ix, int(min(xs)), int(max(xs)))
        y_lo, y_hi = self._window(1, o_iy, int(min(ys)), int(max(ys)))
        if not (x_lo <= o_ix <= x_hi and y_lo <= o_iy <= y_hi):
            raise ScanRefused("beyond_cap", f"the scan's origin ({ox:.2f}, {oy:.2f}) m is outside the "
                              f"{p.max_size_m:g} m map the grid may hold")  # fmt: skip
        h_in = (h_ix >= x_lo) & (h_ix <= x_hi) & (h_iy >= y_lo) & (h_iy <= y_hi)
        f_in = (f_ix >= x_lo) & (f_ix <= x_hi) & (f_iy >= y_lo) & (f_iy <= y_hi)
        beyond = np.zeros(len(r), dtype=bool)
        beyond[np.nonzero(hit)[0][~h_in]] = True
        out = ray[~f_in]
        beyond[out[out < len(r)]] = True  # counted per beam: the rays in between are none
        # Checked: now write (grow, then free rays, then hits over them).
        grew = self._grow(x_lo, x_hi, y_lo, y_hi)
        ix0, iy0 = self.offset
        flat_w = self.logodds.shape[1]
        lo = self.logodds.reshape(-1)
        h_flat = (h_iy[h_in] - iy0) * flat_w + (h_ix[h_in] - ix0)
        f_ix, f_iy = f_ix[f_in] - ix0, f_iy[f_in] - iy0  # grid indices from here on
        f_flat = f_iy * flat_w + f_ix
        before = lo[h_flat]
        # A gap in the sampling (not a measurement: a hole a binned cloud leaves) stops at the first
        # cell that is, or touches, one the map holds occupied: it may not clear what has been seen (a
        # wall behind a shadow stays a wall), nor slip between two wall cells that meet at a corner. A
        # ray that returned nothing did look: what the map held on it has gone, and it clears it.
        f_ray = ray[f_in]
        w = np.nonzero(weak_ray[f_ray])[0]  # weak samples: each ray's in a row, in order
        if len(w):
            gy, gx = f_iy[w], f_ix[w]
            y0, x0 = max(int(gy.min()) - 1, 0), max(int(gx.min()) - 1, 0)
            held = self.logodds[y0 : int(gy.max()) + 2, x0 : int(gx.max()) + 2] >= p.occupied_logodds
            touch = held.copy()  # an occupied cell or one of its 8 neighbours, over the window touched
            touch[1:] |= held[:-1]
            touch[:-1] |= held[1:]
            touch[:, 1:] |= touch[:, :-1].copy()
            touch[:, :-1] |= touch[:, 1:].copy()
            occ = touch[gy - y0, gx - x0]
            if occ.any():
                wr = f_ray[w]
                begins = np.r_[True, wr[1:] != wr[:-1]]  # where each weak ray begins
                first = np.flatnonzero(begins)
                csum = np.cumsum(occ)
                group = np.cumsum(begins) - 1
                before_ray = (csum[first] - occ[first])[group]
                keep = np.ones(len(f_flat), dtype=bool)
                keep[w[csum - before_ray > 0]] = False  # from its first such cell on
                f_flat = f_flat[keep]
        lo[f_flat] = np.maximum(lo[f_flat] - p.miss, p.min_logodds)
        lo[h_flat] = np.minimum(before + p.hit, p.max_logodds)
        self.scans += 1
        return Integrated(int(hit.sum()), int(no_return.sum()), int(nan.sum()), int(invalid.sum()),
                          int(beyond.sum()), grew)  # fmt: skip

    def _window(self, axis: int, origin: int, need_lo: int, need_hi: int) -> tuple[int, int]:
        """The lattice range [lo, hi] along `axis` the grid will span: the current one grown over
        what a scan needs (plus a margin), at most max_cells, never dropping a mapped cell."""
        cap = self.params.max_cells
        margin = int(round(self.params.grow_margin_m / self.resolution))
        if self.empty:
            lo, hi = need_lo - margin, need_hi + margin
            if hi - lo + 1 <= cap:
                return lo, hi
            lo = max(need_lo, origin - cap // 2)
            return lo, lo + cap - 1
        size = self.logodds.shape[1 - axis]
        cur_lo = self.offset[axis]
        cur_hi = cur_lo + size - 1
        if need_lo >= cur_lo and need_hi <= cur_hi:
            return cur_lo, cur_hi
        lo, hi = min(cur_lo, need_lo - margin), max(cur_hi, need_hi + margin)
        if hi - lo + 1 <= cap:
            return lo, hi
        lo, hi = min(cur_lo, need_lo), max(cur_hi, need_hi)
        if hi - lo + 1 <= cap:  # fits without the margin: take what is left of the cap
            spare = cap - (hi - lo + 1)
            return (lo - spare, hi) if need_lo < cur_lo else (lo, hi + spare)
        if need_hi > cur_hi and origin >= cur_lo:
            return cur_lo, cur_lo + cap - 1
        return cur_hi - cap + 1, cur_hi

    def _grow(self, x_lo: int, x_hi: int, y_lo: int, y_hi: int) -> bool:
        rows, cols = y_hi - y_lo + 1, x_hi - x_lo + 1
        if not self.empty and (x_lo, y_lo) == self.offset and (rows, cols) == self.shape:
            return False
        new = np.zeros((rows, cols), dtype=np.float32)
        if not self.empty:
            r0, c0 = self.offset[1] - y_lo, self.offset[0] - x_lo
            h, w = self.shape
            new[r0 : r0 + h, c0 : c0 + w] = self.logodds
        self.logodds, self.offset = new, (x_lo, y_lo)
        return True

    # -- reading ----------------------------------------------------------------------------
    def values(self) -> np.ndarray:
        """The grid as ROS OccupancyGrid cells (int8, [rows = y, cols = x]): -1, 0 or 100."""
        p = self.params
        out = np.full(self.shape, UNKNOWN, dtype=np.int8)
        out[self.logodds <= p.free_logodds] = FREE
        out[self.logodds >= p.occupied_logodds] = LETHAL
        return out

    def occupied_points(self) -> np.ndarray:
        """World x, y of every occupied cell's centre, (N, 2)."""
        rows, cols = np.nonzero(self.logodds >= self.params.occupied_logodds)
        res = self.resolution
        return np.column_stack([(cols + self.offset[0] + 0.5) * res, (rows + self.offset[1] + 0.5) * res])

    def counts(self) -> dict[str, int]:
        v = self.values()
        return {"occupied": int((v == LETHAL).sum()), "free": int((v == FREE).sum()),
                "unknown": int((v == UNKNOWN).sum())}  # fmt: skip


# A run of beams without a return between two with one, no wider than this, is a gap in the binned
# cloud (its shadows), not an opening: a house has walls within range_max all round, so a true
# opening with nothing behind it is rare indoors, while shadows of near furniture are common.
GAP_ANGLE = math.radians(60.0)


NEAR_BEAMS = 5  # how far beside a run its shadow's caster is looked for
FILL_STEP = 0.7  # cells between the samples of a ray filled in (the beams: half a cell; 0.8 left cells)
SPREAD = 0.7  # rays filled in between beams end at most this many cells apart (1.0 left slivers)


def _gaps(
    r_hit: np.ndarray, no_return: np.ndarray, wraps: bool, increment: float, parallax_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Beams without a return that are gaps in the sampling, not openings (see `OccupancyMap.integrate`),
    and for each the nearer of the two returns round its run."""
    n = len(r_hit)
    gap, bound = np.zeros(n, dtype=bool), np.full(n, np.inf)
    hits = np.nonzero(np.isfinite(r_hit))[0]
    if len(hits) < 2 or not no_return.any():
        return gap, bound
    # Each run lies between two consecutive returns (round the turn when the scan wraps).
    a, b = hits[:-1], hits[1:]
    if wraps:
        a, b = np.append(a, hits[-1]), np.append(b, hits[0] + n)
    length = b - a - 1
    # ... and so is one no wider than what a sensor parallax_m off the scan's origin leaves beside a
    # return at that range (a lidar ahead of the base casts its rays round a near object's edge): the
    # nearest return within a few beams of either end, since the object that casts the shadow is
    # often a beam or two beside the far returns that bound it.
    near = np.full(len(a), np.inf)
    for k in range(NEAR_BEAMS):
        near = np.minimum(near, np.minimum(r_hit[(a - k) % n], r_hit[(b + k) % n]))
    widest = np.maximum(GAP_ANGLE / increment, 1.2 * np.arctan2(parallax_m, near) / increment + 1)
    short = (length >= 1) & (length <= widest)
    for lo, hi in zip(a[short], b[short], strict=True):
        idx = np.arange(lo + 1, hi) % n
        idx = idx[no_return[idx]]
        gap[idx] = True
        bound[idx] = min(r_hit[lo % n], r_hit[hi % n])
    return gap, bound


def _between(
    angles: np.ndarray, free_len: np.ndarray, usable: np.ndarray, increment: float, step: float, wraps: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays between each two neighbouring usable beams, no further apart than `step` where they end,
    each as long as the shorter of the two: their directions (x, y) and lengths."""
    n = len(free_len)
    i = np.arange(n if wraps else n - 1)
    j = (i + 1) % n
    both = usable[i] & usable[j]
    i, j = i[both], j[both]
    reach = np.minimum(free_len[i], free_len[j])
    k = np.maximum(np.ceil(reach * abs(increment) / step).astype(np.int64) - 1, 0)  # rays in between
    pair = np.repeat(np.arange(len(i)), k)
    m = np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k) + 1
    a = angles[i][pair] + increment * m / (k[pair] + 1)
    return np.cos(a), np.sin(a), reach[pair]


def _check_geometry(b: Beams) -> None:
    geo = (b.angle_min, b.angle_increment, b.range_min, b.range_max, *b.origin)
    n = int(np.size(b.ranges))
    if not all(math.isfinite(v) for v in geo) or b.angle_increment <= 0 or not 0 <= b.range_min < b.range_max:
        raise ScanRefused("bad_geometry", f"angle_min, angle_increment, range_min, range_max = {geo[:4]}")
    if n == 0:
        raise ScanRefused("bad_geometry", "the scan has no beams")
    if n * b.angle_increment > 2 * math.pi + 1e-3:
        raise ScanRefused("bad_geometry", f"{n} beams x {b.angle_increment:g} rad is more than a turn")
    if b.range_max > 100.0:
        raise ScanRefused("bad_geometry", f"range_max {b.range_max:g} m: a planar lidar of a house reaches 100 m")


@dataclass(frozen=True)
class CostmapParams:
    """Radii of the robot's footprint about its centre (m): the costmap's bands."""

    inscribed_m: float
    circumscribed_m: float
    inflation_m: float

    def __post_init__(self) -> None:
        if not (0 < self.inscribed_m <= self.circumscribed_m <= self.inflation_m <= 5.0):
            raise ValueError("need 0 < inscribed_m <= circumscribed_m <= inflation_m <= 5 m")

    @staticmethod
    def for_footprint(
        length: float, width: float, padding_m: float = Clearance().creep_m, inflation_m: float = 0.8
    ) -> CostmapParams:
        """A rectangle's inscribed and circumscribed circles, both `padding_m` wider (the clearance
        kept at a creep)."""
        inscribed = min(length, width) / 2 + padding_m
        circumscribed = math.hypot(length / 2, width / 2) + padding_m
        return CostmapParams(inscribed, circumscribed, max(inflation_m, circumscribed))


def bounded_distance(occupied: np.ndarray, max_cells: int) -> np.ndarray:
    """Euclidean distance (in cells) from each cell to the nearest True cell of `occupied`, exact up
    to `max_cells` and +inf beyond. Separable, in numpy: the squared distance along each column
    within `max_cells`, then the nearest of the columns within `max_cells` either side (about
    scipy's time). Written here, not taken from scipy.ndimage, whose import (with scipy.special)
    was 29 MB of the map node's memory."""
    occ = np.asarray(occupied, dtype=bool)
    h, w = occ.shape
    cap = np.float32((max_cells + 1) ** 2)
    g2 = np.where(occ, np.float32(0.0), cap).astype(np.float32)
    for k in range(1, min(max_cells, h - 1) + 1):
        kk = np.float32(k * k)
        np.minimum(g2[k:], np.where(occ[:-k], kk, cap), out=g2[k:])
        np.minimum(g2[:-k], np.where(occ[k:], kk, cap), out=g2[:-k])
    best = g2.copy()
    for k in range(1, min(max_cells, w - 1) + 1):
        kk = np.float32(k * k)
        np.minimum(best[:, k:], g2[:, :-k] + kk, out=best[:, k:])
        np.minimum(best[:, :-k], g2[:, k:] + kk, out=best[:, :-k])
    d = np.sqrt(best).astype(np.float64)
    d[d > max_cells] = np.inf
    return d


def inflate(values: np.ndarray, resolution: float, params: CostmapParams, band_rows: int = 256) -> np.ndarray:
    """The costmap of an OccupancyGrid's cells (see the module docstring), int8, same shape. Computed
    in bands of rows (each with the inflation radius of rows round it), so that a map at the cap
    needs a band's distance transform at a time, not the whole grid's."""
    occupied = values == LETHAL
    cost = np.where(values == UNKNOWN, UNKNOWN, FREE).astype(np.int8)
    reach = int(math.ceil(params.inflation_m / resolution)) + 1
    span = max(params.inflation_m - params.circumscribed_m, 1e-9)
    ring = max(params.circumscribed_m - params.inscribed_m, 1e-9)
    top = INSCRIBED - CIRCUMSCRIBED - 1  # the band's codes above CIRCUMSCRIBED
    rows = values.shape[0]
    for r0 in range(0, rows, band_rows):
        lo, hi = max(0, r0 - reach), min(rows, r0 + band_rows + reach)
        occ = occupied[lo:hi]
        if not occ.any():
            continue
        d = bounded_distance(occ, reach)[r0 - lo : r0 - lo + band_rows]  # in cells
        near = np.nonzero(d <= params.inflation_m / resolution)
        dn = d[near] * resolution
        out = CIRCUMSCRIBED - 2
        falling = np.minimum(1 + np.floor(out * np.clip((params.inflation_m - dn) / span, 0.0, 1.0)), out + 1)
        within = CIRCUMSCRIBED + np.floor(top * np.clip((params.circumscribed_m - dn) / ring, 0.0, 1.0))
        band = np.where(dn <= params.inscribed_m, INSCRIBED, np.where(dn <= params.circumscribed_m, within, falling))
        band[dn == 0] = LETHAL
        # Unknown cells stay unknown but within the inscribed radius (Nav2's inflate_unknown: false):
        # a band inflated into the unknown round every wall would read as known space, and its edge as a
        # frontier all round the house.
        keep = (values[r0 + near[0], near[1]] != UNKNOWN) | (band >= INSCRIBED)
        cost[r0 + near[0][keep], near[1][keep]] = band[keep].astype(np.int8)
    return cost
