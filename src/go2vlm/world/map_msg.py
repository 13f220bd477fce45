"""The occupancy map on the wire: a grid of cells <-> a nav_msgs/OccupancyGrid, both ways. The one
conversion the map node, the planner, the view and the episode plot use.

An OccupancyGrid: `info.width` cells along x (columns), `info.height` along y (rows), `resolution`
m a cell, `origin` = the world pose of cell (0, 0)'s outer corner (yaw 0: the grid's axes are the
frame's), `data` row-major from row 0 (lowest y): -1 unknown, 0 free, 1..100 cost or occupied.
`header.frame_id` = the map's frame (odom), `header.stamp` = the stamp of the newest scan in it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.geometry_msgs import Point, Pose, Quaternion
from go2vlm.msgs.nav_msgs import MapMetaData, OccupancyGrid
from go2vlm.msgs.std_msgs import Header

__all__ = ["Grid", "grid_msg", "grid_of"]


@dataclass(frozen=True)
class Grid:
    """What a reader of /map or /map/costmap learns: cells [rows = y, cols = x] (int8), the world x, y
    of cell (0, 0)'s outer corner, the cell size (m), the frame and the stamp."""

    cells: np.ndarray
    origin: tuple[float, float]
    resolution: float
    frame_id: str
    stamp: float

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of world (x, y); may be outside the grid."""
        return int(np.floor((y - self.origin[1]) / self.resolution)), int(
            np.floor((x - self.origin[0]) / self.resolution)
        )

    def center_of(self, row: int, col: int) -> tuple[float, float]:
        return self.origin[0] + (col + 0.5) * self.resolution, self.origin[1] + (row + 0.5) * self.resolution


def grid_msg(
    cells: np.ndarray, origin: tuple[float, float], resolution: float, frame_id: str, stamp: float
) -> OccupancyGrid:
    rows, cols = cells.shape
    t = Time.from_sec(stamp)
    pose = Pose(position=Point(x=float(origin[0]), y=float(origin[1]), z=0.0), orientation=Quaternion(w=1.0))
    info = MapMetaData(map_load_time=t, resolution=float(resolution), width=cols, height=rows, origin=pose)
    return OccupancyGrid(header=Header(stamp=t, frame_id=frame_id), info=info,
                         data=np.ascontiguousarray(cells, dtype=np.int8).reshape(-1).tolist())  # fmt: skip


def grid_of(msg: OccupancyGrid) -> Grid:
    """A received grid; ValueError when its size and data disagree or its origin is turned (unsupported)."""
    info = msg.info
    rows, cols = int(info.height), int(info.width)
    if len(msg.data) != rows * cols:
        raise ValueError(f"grid of {cols} x {rows} cells carries {len(msg.data)} values")
    if not info.resolution > 0:
        raise ValueError(f"grid resolution {info.resolution}")
    q = info.origin.orientation
    if abs(q.z) > 1e-6 or abs(q.x) > 1e-6 or abs(q.y) > 1e-6:
        raise ValueError("a grid whose origin is turned is not supported")
    cells = np.asarray(msg.data, dtype=np.int8).reshape(rows, cols)
    return Grid(cells, (info.origin.position.x, info.origin.position.y), float(info.resolution),
                msg.header.frame_id, msg.header.stamp.to_sec())  # fmt: skip
