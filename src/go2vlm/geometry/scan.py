"""Point cloud -> planar range scan, and scan -> points: the one conversion behind /scan.

Pure numpy. The sim (its ray-cast L1 cloud) and the go2 driver (the robot's rt/utlidar/cloud) both
turn their cloud into the /scan they publish with `cloud_to_ranges`; the safety gate and the
commander read /scan back into obstacle points with `scan_points`.

The scan is in the base frame (x forward, y left), 360 degrees from -pi, one bin per
`angle_increment`. A bin holds the horizontal distance to the nearest point in the obstacle band:
between `z_min` and `z_max` in the base frame of the robot standing level (above what the legs step
over, below what the body passes under), outside the robot's own footprint (its legs in the cloud),
within [range_min, range_max]. A bin without such a point is +inf (REP 117: nothing within range_max).

With the robot's `Stance` (its attitude and the base's height above the floor) the band is measured
from the floor, as pointcloud_to_laserscan does in a gravity-aligned frame: the cloud is levelled and
raised or lowered to where a level robot at `stand_height` would see it. Without it, in the base
frame: a Go2 lying damped sees the floor 0.1 m below its base, inside the band, and the near rows that
keep a low object in the scan would fill it with floor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from go2vlm.declare import param

__all__ = [
    "ScanSpec",
    "Stance",
    "cloud_to_ranges",
    "frame_scan_points",
    "mount_transform",
    "nearest_return",
    "scan_points",
    "to_base",
]


@dataclass(frozen=True)
class ScanSpec:
    bins: int = 180  # 2 degrees: the sim lidar's azimuth step
    range_min: float = 0.05  # m
    range_max: float = 10.0  # m
    # The obstacle band. Its top is above the robot's own height (a standing Go2 is 0.40 m tall): the
    # episodes count a collision where the footprints meet in the plane, so a table top the robot could
    # walk under is kept an obstacle (docs/navigation.md, "Known limits").
    z_min: float = param(
        -0.28, help="scan: points at least this high in the base frame are obstacles (m; -0.28: 4 cm off the "
        "floor for a standing Go2, below the lowest thing a home leaves on the floor, a 7 cm tray)", min=-1.0,
        max=1.0,
    )  # fmt: skip
    z_max: float = param(
        0.45, help="scan: ... and at most this high (m in the base frame; 0.45: 0.77 m off the floor)", min=-1.0,
        max=2.0,
    )  # fmt: skip
    self_hx: float = 0.0  # half length and width of the robot's own box, left out (0 = keep all)
    self_hy: float = 0.0
    stand_height: float = 0.0  # the base above the floor, standing (m): where a `Stance` puts the band

    @property
    def angle_min(self) -> float:
        return -math.pi

    @property
    def angle_increment(self) -> float:
        return 2.0 * math.pi / self.bins

    @property
    def angle_max(self) -> float:
        return self.angle_min + (self.bins - 1) * self.angle_increment


@dataclass(frozen=True)
class Stance:
    """The robot's attitude and height: `level` rotates base-frame vectors into the frame of the same
    heading with z up (roll and pitch undone), and `height` is the base's height above the floor (m)."""

    level: np.ndarray
    height: float

    @staticmethod
    def of(rotation: np.ndarray, height: float) -> Stance:
        """From the base's rotation in any frame with z up (a world frame, an IMU's): its yaw is dropped."""
        r = np.asarray(rotation, dtype=float).reshape(3, 3)
        yaw = math.atan2(r[1, 0], r[0, 0])
        c, s = math.cos(yaw), math.sin(yaw)
        return Stance(np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ r, float(height))


def mount_transform(pos: tuple[float, float, float], pitch: float) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of a sensor mounted at `pos` pitched by `pitch` about y: p_base = R @ p_sensor + t."""
    c, s = math.cos(pitch), math.sin(pitch)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]), np.asarray(pos, dtype=float)


def to_base(points: np.ndarray, transform: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    r, t = transform
    return np.asarray(points, dtype=float).reshape(-1, 3) @ r.T + t


def cloud_to_ranges(points_base: np.ndarray, spec: ScanSpec, stance: Stance | None = None) -> np.ndarray:
    """(N, 3) points in the base frame -> `spec.bins` ranges (float32, +inf where nothing); with
    `stance`, the band measured from the floor (module docstring)."""
    p = np.asarray(points_base, dtype=float).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    if stance is not None:
        p = p @ stance.level.T + (0.0, 0.0, stance.height - spec.stand_height)
    p = p[(p[:, 2] >= spec.z_min) & (p[:, 2] <= spec.z_max)]
    if spec.self_hx > 0 and spec.self_hy > 0:
        p = p[(np.abs(p[:, 0]) > spec.self_hx) | (np.abs(p[:, 1]) > spec.self_hy)]
    r = np.hypot(p[:, 0], p[:, 1])
    keep = (r >= spec.range_min) & (r <= spec.range_max)
    p, r = p[keep], r[keep]
    out = np.full(spec.bins, np.inf, dtype=np.float32)
    if len(r):
        idx = np.floor((np.arctan2(p[:, 1], p[:, 0]) - spec.angle_min) / spec.angle_increment + 0.5).astype(int)
        np.minimum.at(out, idx % spec.bins, r.astype(np.float32))
    return out


def scan_points(
    ranges: np.ndarray | list[float], angle_min: float, angle_increment: float, range_min: float, range_max: float
) -> np.ndarray:
    """A scan's returns as (N, 2) points in the scan frame. +inf (and beyond range_max) is free space;
    anything else that is not a finite in-range distance (NaN, -inf, negative, a bad geometry) is
    garbage and raises ValueError: a consumer must not read a broken scan as free space."""
    geo = (angle_min, angle_increment, range_min, range_max)
    if not all(math.isfinite(v) for v in geo) or angle_increment <= 0 or not 0 <= range_min < range_max:
        raise ValueError(f"scan geometry is not usable: angle_min, angle_increment, range_min, range_max = {geo}")
    r = np.asarray(ranges, dtype=float).reshape(-1)
    if len(r) == 0:
        raise ValueError("scan has no beams")
    if len(r) * angle_increment > 2 * math.pi + 1e-3:
        raise ValueError(f"scan of {len(r)} beams x {angle_increment:g} rad is more than a turn")
    bad = np.isnan(r) | (r == -np.inf) | (r < 0)
    if bad.any():
        raise ValueError(f"scan has {int(bad.sum())} invalid range(s) (NaN, -inf or negative)")
    hit = np.isfinite(r) & (r <= range_max)  # a return under range_min is kept: too close is not free
    a = angle_min + angle_increment * np.nonzero(hit)[0]
    return np.column_stack([r[hit] * np.cos(a), r[hit] * np.sin(a)])


def frame_scan_points(
    frame: str,
    frame_id: str,
    ranges: np.ndarray | list[float],
    angle_min: float,
    angle_increment: float,
    range_min: float,
    range_max: float,
) -> np.ndarray:
    """`scan_points` of a scan that must be in `frame` (a scan in another frame raises ValueError too):
    what the safety gate's guard and the commander's planner both take from /scan."""
    if frame_id != frame:
        raise ValueError(f"scan in frame {frame_id!r}, not {frame!r}")
    return scan_points(ranges, angle_min, angle_increment, range_min, range_max)


def nearest_return(points: np.ndarray | None, origin: tuple[float, float], lo: float, hi: float) -> float | None:
    """The nearest scan point (base frame, (N, 2)) seen from `origin` (a sensor's x, y in the base
    frame, facing +x) between the bearings lo..hi (rad, + left), as a horizontal distance from
    `origin`; None when there is none. The object memory places a box with it, the commander ranges
    a near target with it."""
    if points is None or len(points) == 0:
        return None
    rel = np.asarray(points, dtype=float).reshape(-1, 2) - origin
    ang = np.arctan2(rel[:, 1], rel[:, 0])
    hit = (ang >= lo) & (ang <= hi) & (rel[:, 0] > 0.0)
    return float(np.hypot(rel[hit, 0], rel[hit, 1]).min()) if hit.any() else None
