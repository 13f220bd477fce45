"""Constant-speed closed paths for the moving ball (arc-length parametrised)."""

from __future__ import annotations

from typing import Any

import numpy as np


class BallPath:
    """Ellipse or figure-eight in the ground plane, travelled at ``speed`` m/s.

    ``params`` = (cx, cy, rx, ry, start_angle).  The figure-eight is a
    lemniscate of Gerono: (cx + rx sin t, cy + ry sin t cos t).
    """

    def __init__(self, kind: str, params: tuple[float, ...], speed: float, z: float) -> None:
        if kind not in ("ellipse", "figure8"):
            raise ValueError(f"unknown ball path {kind!r}")
        cx, cy, rx, ry, t0 = params
        self.speed, self.z = speed, z
        t = t0 + np.linspace(0.0, 2 * np.pi, 4001)
        if kind == "ellipse":
            xy = np.stack([cx + rx * np.cos(t), cy + ry * np.sin(t)], axis=1)
        else:
            xy = np.stack([cx + rx * np.sin(t), cy + ry * np.sin(t) * np.cos(t)], axis=1)
        seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
        self._s = np.concatenate([[0.0], np.cumsum(seg)])
        self._xy = xy
        self.length = float(self._s[-1])

    def at(self, s: float) -> np.ndarray:
        """Point at arc length ``s`` (metres, wraps around)."""
        s = s % self.length
        x = np.interp(s, self._s, self._xy[:, 0])
        y = np.interp(s, self._s, self._xy[:, 1])
        return np.array([x, y, self.z])

    def position(self, t: float) -> np.ndarray:
        """Point reached after ``t`` seconds at the constant ``speed``."""
        return self.at(self.speed * t)


def follow_command(sim: Any, body: str = "red_ball") -> tuple[tuple[float, float, float], float]:
    """A crude ground-truth follower: the (vx, vy, vyaw) command that steers a `Go2Sim` towards
    `body` and holds it about 1 m away, and the body's current distance from the base."""
    s = sim.state()
    rel = sim.object_poses()[body].position[:2] - s.position[:2]
    yaw = s.imu_rpy[2]
    bx = np.cos(yaw) * rel[0] + np.sin(yaw) * rel[1]
    by = -np.sin(yaw) * rel[0] + np.cos(yaw) * rel[1]
    dist = float(np.hypot(bx, by))
    return (np.clip(1.2 * (dist - 1.0), -0.5, 1.0), 0.0, np.clip(2.0 * np.arctan2(by, bx), -1.5, 1.5)), dist
