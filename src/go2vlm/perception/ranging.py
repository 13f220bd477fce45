"""Monocular ranging: how far is the object in a box, from one pinhole camera and no depth sensor.

Distance = camera -> the object's near surface:

1. Bottom edge (size-free): objects stand on the floor, the camera is `camera_height` above it and
   looks level (plus `camera_pitch`, + = down, and the body's pitch at the frame: a Go2 stands 0.8
   degrees nose down, which read an object 5 m away 1.2 m farther). The image row v of the object's lowest visible point
   is a ray `beta = atan((v - cy) / fy) + pitch` below the horizon, meeting the floor at
   `h / tan(beta)`. For a box or a cylinder that point is the near edge of its footprint; for a
   ball the silhouette bottom and its angular radius give the centre distance in closed form
   (D = h / (sin a - sin(a - beta))). Usable while the bottom is in the picture.
2. Apparent size: box width W = d * (tan a2 - tan a1) (its left/right edge rays a1, a2); cylinder and
   ball radius r from the half-angle a: d_centre = r / sin a. Each bottom-edge reading *calibrates*
   the object's size (median of the readings), so when the robot is so close that the bottom leaves
   the picture (the Go2 head camera sits 0.36 m up: floor visible from ~0.65 m ahead at 58 deg fovy),
   the size carries the estimate. Before any calibration the configured `default_sizes` are used.
3. An object cut by both the left and right image borders cannot be measured: if it fills most of
   the width it is reported as at distance 0 ("fills the view") -- stopping early is the safe side.

The target_tracker ranges every tracked box with one `RangeEstimator` per query; behaviours add the
camera's offset from the robot's base (behavior/control.py turns the distance into motion).
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field
from typing import Any

from go2vlm.geometry.camera import PinholeCamera
from go2vlm.robot_profile.go2 import HEAD_CAMERA_HEIGHT

__all__ = ["DEFAULT_SIZES", "RangeEstimator", "RangeReading", "check_object_sizes"]

# Sizes of the objects in vision_test (the VLM article's Gazebo world): ball radius, box face
# width, cylinder radius.
DEFAULT_SIZES = {"ball": 0.5, "box": 1.0, "cylinder": 0.3}


def check_object_sizes(sizes: dict[str, Any]) -> None:
    """ValueError unless `sizes` maps known shapes to sizes in 0.01..20 m (an `object_sizes` parameter)."""
    for key, value in sizes.items():
        if key not in DEFAULT_SIZES:
            raise ValueError(f"object_sizes: unknown shape {key!r}; use {sorted(DEFAULT_SIZES)}")
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not 0.01 <= float(value) <= 20:
            raise ValueError(f"object_sizes[{key!r}] = {value!r} must be a number in 0.01..20 m")


@dataclass(frozen=True)
class RangeReading:
    distance: float | None  # camera -> near surface (m); None: cannot tell
    method: str  # bottom | size | default_size | fills_view | none


@dataclass
class RangeEstimator:
    """Per-target distance estimate with online size calibration (reset it for a new target)."""

    shape: str | None  # ball | box | cylinder | None (treated as a box: a flat face)
    camera_height: float = HEAD_CAMERA_HEIGHT
    camera_pitch: float = 0.0  # rad, + = looking down
    default_sizes: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_SIZES))
    border_px: int = 3
    _sizes: list[float] = field(default_factory=list)

    @property
    def size(self) -> float:
        """The calibrated size (median of bottom-edge readings), else the default for the shape."""
        if self._sizes:
            return statistics.median(self._sizes[-15:])
        return float(self.default_sizes.get(self.shape or "box", DEFAULT_SIZES["box"]))

    @property
    def calibrated(self) -> bool:
        return bool(self._sizes)

    def estimate(self, xyxy: tuple[float, float, float, float], cam: PinholeCamera, pitch: float = 0.0) -> RangeReading:
        """The box's range; `pitch`: the body's at the frame (rad, + nose down), added to the camera's."""
        x1, y1, x2, y2 = xyxy
        b = self.border_px
        clip_l, clip_r = x1 <= b, x2 >= cam.width - 1 - b
        bottom_visible = y2 < cam.height - 1 - b
        a1 = math.atan((x1 - cam.cx) / cam.fx)
        a2 = math.atan((x2 - cam.cx) / cam.fx)
        half = max(1e-4, (a2 - a1) / 2.0)
        width_ok = not (clip_l or clip_r)
        shape = self.shape or "box"
        beta = math.atan((y2 - cam.cy) / cam.fy) + self.camera_pitch + pitch if bottom_visible else 0.0
        if bottom_visible and beta > 0.02:
            h = self.camera_height
            if shape == "ball" and width_ok:
                d_centre3 = h / max(1e-6, math.sin(half) - math.sin(half - beta))
                r = d_centre3 * math.sin(half)
                elev = half - beta
                dist = d_centre3 * math.cos(elev) - r
                self._calibrate(r)
                return RangeReading(max(0.0, dist), "bottom")
            if shape == "ball":  # cut at the sides: the bottom tangent ray plus the known radius
                dist = _ball_from_bottom(beta, self.size, h)
                return RangeReading(dist, "size" if self.calibrated else "default_size")
            dist = h / math.tan(beta)
            if width_ok and shape == "cylinder":
                # r = D sin(half), with D = (dist + r) / cos(bearing) the centre along its ray
                s, cb = math.sin(half), math.cos((a1 + a2) / 2.0)
                self._calibrate(dist * s / max(1e-6, cb - s))
            elif width_ok and shape == "box":
                self._calibrate(dist * (math.tan(a2) - math.tan(a1)))
            return RangeReading(dist, "bottom")
        if width_ok:
            method = "size" if self.calibrated else "default_size"
            size = self.size
            if shape == "box":
                return RangeReading(size / max(1e-6, math.tan(a2) - math.tan(a1)), method)
            d_centre = size / math.sin(half)
            if shape == "ball":
                dz = size - self.camera_height
                d_centre = math.sqrt(max(0.0, d_centre * d_centre - dz * dz))
            return RangeReading(max(0.0, d_centre - size), method)
        if (x2 - x1) >= 0.8 * cam.width:
            return RangeReading(0.0, "fills_view")
        return RangeReading(None, "none")

    def _calibrate(self, size: float) -> None:
        if math.isfinite(size) and size > 0.01:
            self._sizes.append(size)
            del self._sizes[:-31]


def _ball_from_bottom(beta: float, r: float, h: float) -> float:
    """Camera -> surface of a ball of radius r whose silhouette bottom is `beta` below the horizon
    (bisection on the centre distance D: the tangent ray's elevation asin(r/D) - beta must point at
    the centre's height r - h)."""
    lo, hi = r * 1.0001, 100.0

    def f(d: float) -> float:
        return d * math.sin(math.asin(min(1.0, r / d)) - beta) - (r - h)

    if f(lo) * f(hi) > 0:
        return max(0.0, h / math.tan(beta))
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if f(lo) * f(mid) <= 0:
            hi = mid
        else:
            lo = mid
    d = 0.5 * (lo + hi)
    elev = math.asin(min(1.0, r / d)) - beta
    return max(0.0, d * math.cos(elev) - r)
