"""The one pinhole camera model: intrinsics from a field of view or from CameraInfo.K.

Two pixel conventions meet here, and each constructor says which it uses:
- ROS (`sensor_msgs/CameraInfo`): integer pixel centres, so an ideal camera's principal point is
  ((w - 1) / 2, (h - 1) / 2). `from_hfov` and `from_k` use it.
- MuJoCo's renderer: continuous coordinates with pixel edges at integers, principal point (w/2, h/2).
  `from_fovy` uses it (MuJoCo cameras are specified by their vertical field of view).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["PinholeCamera", "focal_length", "fovy_to_hfov", "hfov_to_fovy_deg"]


def focal_length(size_px: float, fov_rad: float) -> float:
    """Focal length in pixels of an image `size_px` wide (or high) that spans `fov_rad`."""
    return (size_px / 2.0) / math.tan(fov_rad / 2.0)


def fovy_to_hfov(fovy_deg: float, width: int, height: int) -> float:
    """Horizontal field of view (radians) of a square-pixel camera with this vertical one (degrees)."""
    return 2.0 * math.atan(math.tan(math.radians(fovy_deg) / 2.0) * width / height)


def hfov_to_fovy_deg(hfov_rad: float, width: int, height: int) -> float:
    return math.degrees(2 * math.atan(math.tan(hfov_rad / 2) * height / width))


@dataclass(frozen=True)
class PinholeCamera:
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @classmethod
    def from_hfov(cls, width: int, height: int, hfov_rad: float) -> PinholeCamera:
        """Square pixels, no distortion, principal point at the centre (ROS convention)."""
        f = focal_length(width, hfov_rad)
        return cls(width, height, f, f, (width - 1) / 2.0, (height - 1) / 2.0)

    @classmethod
    def from_fovy(cls, width: int, height: int, fovy_deg: float) -> PinholeCamera:
        """A MuJoCo camera: vertical field of view, square pixels, principal point (w/2, h/2)."""
        f = focal_length(height, math.radians(fovy_deg))
        return cls(width, height, f, f, width / 2.0, height / 2.0)

    @classmethod
    def from_k(cls, width: int, height: int, k: Sequence[float]) -> PinholeCamera:
        """From CameraInfo.k (row-major 3x3). Raises ValueError for an unusable K."""
        if width <= 0 or height <= 0:
            raise ValueError(f"camera size {width}x{height} is not positive")
        fx, fy, cx, cy = float(k[0]), float(k[4]), float(k[2]), float(k[5])
        if not all(math.isfinite(v) for v in (fx, fy, cx, cy)) or fx <= 0 or fy <= 0:
            raise ValueError(f"camera K has fx={fx}, fy={fy}, cx={cx}, cy={cy}; fx and fy must be positive")
        return cls(width, height, fx, fy, cx, cy)

    @property
    def k(self) -> list[float]:
        """Row-major 3x3 K as in sensor_msgs/CameraInfo."""
        return [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0]

    def bearing(self, u: float) -> float:
        """The horizontal bearing (rad, + left) of image column `u` from the optical axis."""
        return math.atan2(self.cx - u, self.fx)

    @property
    def hfov(self) -> float:
        """Horizontal field of view, radians."""
        return 2.0 * math.atan(self.width / (2.0 * self.fx))

    def scaled_to(self, width: int, height: int) -> PinholeCamera:
        """The same camera at another image size (CameraInfo and images may disagree)."""
        if (width, height) == (self.width, self.height):
            return self
        sx, sy = width / self.width, height / self.height
        return PinholeCamera(width, height, self.fx * sx, self.fy * sy, self.cx * sx, self.cy * sy)
