"""Tiny rotation helpers (quaternions are w, x, y, z)."""

from __future__ import annotations

import numpy as np


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def mat_to_rpy(r: np.ndarray) -> np.ndarray:
    """ZYX Euler angles (roll, pitch, yaw) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = np.arcsin(np.clip(-r[2, 0], -1.0, 1.0))
    return np.array([np.arctan2(r[2, 1], r[2, 2]), pitch, np.arctan2(r[1, 0], r[0, 0])])


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation a then b in a's frame: the Hamilton product a * b (w, x, y, z)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ])  # fmt: skip


def yaw_quat(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def tilt_angle(r: np.ndarray) -> float:
    """Angle between the base z axis and world up."""
    return float(np.arccos(np.clip(r[2, 2], -1.0, 1.0)))


def quat_yaw(w: float, x: float, y: float, z: float) -> float:
    """Yaw (rad) of the rotation (w, x, y, z)."""
    return float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def quat_pitch(w: float, x: float, y: float, z: float) -> float:
    """Pitch (rad, + nose down: about y, ZYX) of the rotation (w, x, y, z)."""
    return float(np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0)))
