"""Camera helpers: pinhole intrinsics and Gazebo -> MuJoCo orientation."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CameraIntrinsics:
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def k(self) -> list[float]:
        """Row-major 3x3 K as in sensor_msgs/CameraInfo."""
        return [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0]


def intrinsics(width: int, height: int, fovy_deg: float) -> CameraIntrinsics:
    """MuJoCo's fovy is vertical; pixels are square, principal point at the centre."""
    fy = 0.5 * height / math.tan(math.radians(fovy_deg) / 2)
    return CameraIntrinsics(width, height, fy, fy, width / 2.0, height / 2.0)


def hfov_to_fovy_deg(hfov_rad: float, width: int, height: int) -> float:
    return math.degrees(2 * math.atan(math.tan(hfov_rad / 2) * height / width))


def fovy_to_hfov(fovy_deg: float, width: int, height: int) -> float:
    """Horizontal field of view (radians) of a square-pixel camera with this vertical one (degrees)."""
    return 2.0 * math.atan(math.tan(math.radians(fovy_deg) / 2.0) * width / height)


def gazebo_rpy_to_xyaxes(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """MuJoCo camera ``xyaxes`` for a Gazebo camera pose with this rpy.

    Gazebo (R = Rz(yaw) Ry(pitch) Rx(roll)) cameras look along +x with +z up;
    MuJoCo cameras look along -z with +y up, so x_mj = -y_gz and y_mj = z_gz.
    """
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    r = rz @ ry @ rx
    return np.concatenate([-r[:, 1], r[:, 2]])
