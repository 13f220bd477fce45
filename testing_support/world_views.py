"""What a level pinhole camera on the Go2 sees of an upright cylinder, and what a planar lidar at its
base returns from it: synthetic views for the world stage's tests and benchmarks (world/)."""

from __future__ import annotations

import math

import numpy as np

from go2vlm.geometry.camera import PinholeCamera
from go2vlm.world.placement import CameraMount
from go2vlm.world.poses import Pose2D

__all__ = ["CAM", "MOUNT", "cylinder_box", "cylinder_scan"]

CAM = PinholeCamera.from_hfov(640, 480, math.radians(73.0))
MOUNT = CameraMount()


def cylinder_box(
    pose: Pose2D,
    obj: tuple[float, float],
    r: float,
    height: float,
    cam: PinholeCamera = CAM,
    mount: CameraMount = MOUNT,
) -> tuple[float, float, float, float] | None:
    """The pixel box of an upright cylinder (centre `obj`, radius r) seen from the robot at `pose`,
    or None when it is not wholly in the picture."""
    cx, cy = pose.to_world(mount.forward_m, mount.left_m)
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    dx, dy = obj[0] - cx, obj[1] - cy
    f, left = c * dx + s * dy, -s * dx + c * dy
    d = math.hypot(f, left)
    if f - r < 0.3 or d <= r:
        return None
    b, a = math.atan2(left, f), math.asin(r / d)
    if abs(b) + a >= math.pi / 2 - 0.05:
        return None
    x1, x2 = cam.cx - cam.fx * math.tan(b + a), cam.cx - cam.fx * math.tan(b - a)
    h = mount.height_m
    y2 = cam.cy + cam.fy * h / (f - r)
    y1 = min(cam.cy + cam.fy * (h - height) / (f - r), cam.cy + cam.fy * (h - height) / (f + r))
    if x1 < 5 or x2 > cam.width - 5 or y1 < 5 or y2 > cam.height - 5:
        return None
    return x1, y1, x2, y2


def cylinder_scan(pose: Pose2D, obj: tuple[float, float], r: float, n: int = 180) -> np.ndarray:
    """Scan returns (base frame at `pose`) on the near side of a cylinder, as an n-beam lidar at the
    base centre sees it."""
    pts = []
    lx, ly = pose.to_local(*obj)
    for k in range(n):
        a = -math.pi + 2 * math.pi * k / n
        ux, uy = math.cos(a), math.sin(a)
        t = lx * ux + ly * uy
        disc = t * t - (lx * lx + ly * ly - r * r)
        if disc >= 0 and t - math.sqrt(disc) > 0:
            dist = t - math.sqrt(disc)
            pts.append((dist * ux, dist * uy))
    return np.array(pts).reshape(-1, 2)
