"""For the map tests: exact scans of a rectangular room, and how far a point is from its walls."""

from __future__ import annotations

import math

import numpy as np

from go2vlm.world.occupancy import Beams
from go2vlm.world.poses import Pose2D

__all__ = ["BINS", "INC", "ROOM", "room_scan", "wall_distance"]

ROOM = (4.01, 3.02)  # half sizes of a rectangular room about the origin (m), walls inside cells
BINS = 180
INC = 2 * math.pi / BINS


def room_scan(pose: Pose2D, room: tuple[float, float] = ROOM, bins: int = BINS, range_max: float = 10.0) -> Beams:
    """The exact ranges from `pose` to the walls of an axis-aligned room (inf beyond range_max)."""
    a = pose.yaw - math.pi + INC * np.arange(bins)
    dx, dy = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(dx > 0, (room[0] - pose.x) / dx, np.where(dx < 0, (-room[0] - pose.x) / dx, np.inf))
        ty = np.where(dy > 0, (room[1] - pose.y) / dy, np.where(dy < 0, (-room[1] - pose.y) / dy, np.inf))
    r = np.minimum(tx, ty)
    r[r > range_max] = np.inf
    return Beams(r.astype(np.float32), -math.pi, INC, 0.05, range_max)


def wall_distance(x: np.ndarray, y: np.ndarray, room: tuple[float, float] = ROOM) -> np.ndarray:
    """How far a point is from the room's walls (the wall segments, not their lines)."""
    ax, ay = np.abs(x), np.abs(y)
    dx, dy = ax - room[0], ay - room[1]
    inside = (dx <= 0) & (dy <= 0)
    return np.where(inside, np.minimum(-dx, -dy), np.hypot(np.maximum(dx, 0), np.maximum(dy, 0)))
