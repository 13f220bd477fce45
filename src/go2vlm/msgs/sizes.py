"""How big a message taken from the bus may be: one check for every message type that has a size.

    check_size(msg, SizeCaps())     # None, or SizeError("a grid of 30000 x 30000 cells, more than ...")

A grid (nav_msgs/OccupancyGrid), an image (sensor_msgs/Image), a point cloud (sensor_msgs/PointCloud2),
a scan (sensor_msgs/LaserScan) and the arrays (detections, markers, a path's poses, transforms) declare
their size in their fields; a reader allocates by it (a grid of height x width cells). The check runs
on the fields, before any consumer allocates: the declared size within its cap, the data as long as
the size says, a grid's resolution finite and > 0 and its origin finite, nothing empty that cannot be
(a grid of no cells). The bus (bus/endpoints.py) runs it on every sample a subscription takes, and
before that checks the serialized size against `max_msg_bytes` before the sample is decoded at all,
so a 30000 x 30000 costmap is never turned into a list of 900 million cells. A refused sample never
reaches the callback; the node counts it and keeps the reason (`Node.input_refusals`, on statuses).

The caps are declared parameters of `SizeCaps`; a node whose Config takes one over with
`from_core(SizeCaps, ...)` sets it, every other node has the defaults.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from go2vlm.declare import param
from go2vlm.msgs.nav_msgs import OccupancyGrid, Path
from go2vlm.msgs.sensor_msgs import Image, LaserScan, PointCloud2
from go2vlm.msgs.tf2_msgs import TFMessage
from go2vlm.msgs.vision_msgs import Detection2DArray, Detection3DArray
from go2vlm.msgs.visualization_msgs import MarkerArray

__all__ = ["SizeCaps", "SizeError", "check_size"]


class SizeError(ValueError):
    """A message larger than its cap, or whose declared size and data disagree; the message says which."""


@dataclass(frozen=True)
class SizeCaps:
    max_msg_cells: int = param(
        16_000_000, help="a grid or an image taken from the bus holds at most this many cells (pixels)", min=1,
        max=1_000_000_000,
    )  # fmt: skip
    max_msg_points: int = param(
        4_000_000, help="a point cloud or a scan taken from the bus holds at most this many points", min=1,
        max=1_000_000_000,
    )  # fmt: skip
    max_msg_items: int = param(
        100_000, help="an array taken from the bus (detections, markers, poses, transforms) holds at most this "
        "many items", min=1, max=100_000_000,
    )  # fmt: skip
    max_msg_bytes: int = param(
        32 * 2**20, help="a sample taken from the bus is at most this many bytes serialized (checked before it "
        "is decoded)", min=1024, max=2**31,
    )  # fmt: skip


def _grid(msg: OccupancyGrid, caps: SizeCaps) -> None:
    info = msg.info
    w, h = int(info.width), int(info.height)
    if w * h > caps.max_msg_cells:
        raise SizeError(f"a grid of {w} x {h} cells, more than the {caps.max_msg_cells} cells a grid may hold")
    if w * h == 0:
        raise SizeError(f"a grid of {w} x {h} cells: no cells")
    if not (math.isfinite(info.resolution) and info.resolution > 0):
        raise SizeError(f"a grid at {info.resolution} m a cell: not a finite size > 0")
    p = info.origin.position
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
        raise SizeError("a grid whose origin is not finite")
    if len(msg.data) != w * h:
        raise SizeError(f"a grid of {w} x {h} cells carries {len(msg.data)} values")


def _image(msg: Image, caps: SizeCaps) -> None:
    w, h, step = int(msg.width), int(msg.height), int(msg.step)
    if w * h > caps.max_msg_cells:
        raise SizeError(f"an image of {w}x{h} pixels, more than the {caps.max_msg_cells} an image may hold")
    if step * h > len(msg.data) or (w and step < w):
        raise SizeError(f"an image of {w}x{h} pixels, step {step}, carries {len(msg.data)} bytes of data")


def _cloud(msg: PointCloud2, caps: SizeCaps) -> None:
    w, h, step, row = int(msg.width), int(msg.height), int(msg.point_step), int(msg.row_step)
    if w * h > caps.max_msg_points:
        raise SizeError(f"a cloud of {w} x {h} points, more than the {caps.max_msg_points} a cloud may hold")
    if len(msg.fields) > caps.max_msg_items:
        raise SizeError(f"a cloud of {len(msg.fields)} fields")
    if w * h and (step <= 0 or row < w * step or row * h > len(msg.data)):
        raise SizeError(
            f"a cloud of {w} x {h} points, {step} bytes a point, {row} a row, carries {len(msg.data)} bytes"
        )


def _scan(msg: LaserScan, caps: SizeCaps) -> None:
    n = len(msg.ranges)
    if n > caps.max_msg_points:
        raise SizeError(f"a scan of {n} ranges, more than the {caps.max_msg_points} a scan may hold")
    if len(msg.intensities) not in (0, n):
        raise SizeError(f"a scan of {n} ranges carries {len(msg.intensities)} intensities")


def _items(field: str) -> Callable[[object, SizeCaps], None]:
    def check(msg: object, caps: SizeCaps) -> None:
        items = getattr(msg, field)
        if len(items) > caps.max_msg_items:
            raise SizeError(f"{len(items)} {field}, more than the {caps.max_msg_items} an array may hold")
        if isinstance(msg, MarkerArray):  # each marker's own points and colours, too
            for m in msg.markers:
                if len(m.points) > caps.max_msg_points or len(m.colors) > caps.max_msg_points:
                    raise SizeError(f"a marker of {len(m.points)} points, more than {caps.max_msg_points}")

    return check


# By ROS 2 type name (`__idl_typename__`): what to check in each (a service's wire type or any class
# of that name is the same message on the wire).
_CHECKS: dict[str, Callable[..., None]] = {
    OccupancyGrid.__idl_typename__: _grid,
    Image.__idl_typename__: _image,
    PointCloud2.__idl_typename__: _cloud,
    LaserScan.__idl_typename__: _scan,
    Detection2DArray.__idl_typename__: _items("detections"),
    Detection3DArray.__idl_typename__: _items("detections"),
    MarkerArray.__idl_typename__: _items("markers"),
    Path.__idl_typename__: _items("poses"),
    TFMessage.__idl_typename__: _items("transforms"),
}


def check_size(msg: object, caps: SizeCaps) -> None:
    """SizeError when `msg` is larger than `caps` allow or its declared size and data disagree; a
    message type without a size passes."""
    check = _CHECKS.get(str(getattr(type(msg), "__idl_typename__", "")))
    if check is not None:
        check(msg, caps)
