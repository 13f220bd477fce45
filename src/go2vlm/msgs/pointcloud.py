"""numpy <-> sensor_msgs/PointCloud2 for xyz clouds, without sensor_msgs_py, and cloud -> LaserScan.

`xyz_cloud` packs an (N, 3) array as an unorganised cloud of float32 x, y, z (and intensity when
given). `cloud_xyz` reads x, y, z back from any layout that has them as FLOAT32 or FLOAT64 fields
(the L1 lidar adds intensity, ring and time), either byte order. A cloud whose fields, steps or data
length do not add up raises `ValueError` naming the fields.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from go2vlm.geometry.scan import ScanSpec, Stance, cloud_to_ranges, to_base
from go2vlm.msgs.sensor_msgs import FLOAT32, FLOAT64, LaserScan, PointCloud2, PointField
from go2vlm.msgs.std_msgs import Header

__all__ = ["MAX_POINTS", "cloud_xyz", "laser_scan", "scan_from_cloud", "xyz_cloud"]

MAX_POINTS = 2_000_000  # refuse absurd headers before allocating anything
_DTYPES: dict[int, np.dtype[Any]] = {FLOAT32: np.dtype(np.float32), FLOAT64: np.dtype(np.float64)}


def xyz_cloud(header: Header, xyz: np.ndarray, intensity: np.ndarray | None = None) -> PointCloud2:
    """An unorganised float32 cloud (height 1) of the points `xyz` (N, 3)."""
    pts = np.asarray(xyz, dtype=np.float32).reshape(-1, 3)
    names = ["x", "y", "z"] + ([] if intensity is None else ["intensity"])
    cols = [pts] if intensity is None else [pts, np.asarray(intensity, dtype=np.float32).reshape(-1, 1)]
    packed = np.ascontiguousarray(np.hstack(cols), dtype="<f4")
    step = 4 * len(names)
    return PointCloud2(
        header=header,
        height=1,
        width=len(pts),
        fields=[PointField(name=n, offset=4 * i, datatype=FLOAT32, count=1) for i, n in enumerate(names)],
        is_bigendian=False,
        point_step=step,
        row_step=step * len(pts),
        data=packed.tobytes(),
        is_dense=bool(np.isfinite(pts).all()),
    )


def cloud_xyz(msg: PointCloud2) -> np.ndarray:
    """The cloud's points as an (N, 3) float64 array (NaN points kept: the caller decides)."""
    n = int(msg.height) * int(msg.width)
    if n > MAX_POINTS:
        raise ValueError(f"cloud of {msg.height}x{msg.width} points is beyond {MAX_POINTS}")
    fields = {f.name: f for f in msg.fields}
    missing = [k for k in "xyz" if k not in fields]
    if missing:
        raise ValueError(f"cloud has no field(s) {missing} (fields: {sorted(fields)})")
    step, row = int(msg.point_step), int(msg.row_step)
    if n == 0:
        return np.zeros((0, 3))
    if step <= 0 or row < step * int(msg.width) or len(msg.data) < row * int(msg.height):
        raise ValueError(
            f"cloud layout does not add up: point_step {step}, row_step {row}, {msg.height}x{msg.width} points, "
            f"{len(msg.data)} data bytes"
        )
    buf = np.frombuffer(bytes(msg.data), dtype=np.uint8)[: row * int(msg.height)].reshape(int(msg.height), row)
    buf = buf[:, : step * int(msg.width)].reshape(n, step)
    out = np.empty((n, 3))
    for i, k in enumerate("xyz"):
        f = fields[k]
        dt = _DTYPES.get(int(f.datatype))
        if dt is None:
            raise ValueError(f"cloud field {k!r} has datatype {f.datatype}; FLOAT32 ({FLOAT32}) or FLOAT64 expected")
        if int(f.offset) + dt.itemsize > step:
            raise ValueError(f"cloud field {k!r} at offset {f.offset} does not fit point_step {step}")
        raw = np.ascontiguousarray(buf[:, int(f.offset) : int(f.offset) + dt.itemsize])
        out[:, i] = raw.view(dt.newbyteorder(">" if msg.is_bigendian else "<")).reshape(n)
    return out


def laser_scan(header: Header, spec: ScanSpec, ranges: np.ndarray, scan_time: float = 0.0) -> LaserScan:
    return LaserScan(
        header=header,
        angle_min=spec.angle_min,
        angle_max=spec.angle_max,
        angle_increment=spec.angle_increment,
        time_increment=0.0,
        scan_time=scan_time,
        range_min=spec.range_min,
        range_max=spec.range_max,
        ranges=[float(r) for r in ranges],
        intensities=[],
    )


def scan_from_cloud(
    msg: PointCloud2,
    spec: ScanSpec,
    transforms: Mapping[str, tuple[np.ndarray, np.ndarray]],
    base_frame: str,
    scan_time: float = 0.0,
    stance: Stance | None = None,
) -> LaserScan | None:
    """The /scan of a lidar cloud, in `base_frame`; `transforms` maps each frame a cloud may come in
    to its (R, t) into the base frame; `stance` the robot's, to measure the band from the floor
    (geometry/scan.py). None for a cloud without a single point (a blind sensor: no
    scan at all, so that consumers see it go stale, rather than a scan that says "all free").
    Raises ValueError for a cloud in an unknown frame or with a broken layout."""
    tf = transforms.get(msg.header.frame_id)
    if tf is None:
        raise ValueError(f"cloud in frame {msg.header.frame_id!r}; known frames: {sorted(transforms)}")
    pts = cloud_xyz(msg)
    if not np.isfinite(pts).all(axis=1).any():
        return None
    ranges = cloud_to_ranges(to_base(pts, tf), spec, stance)
    return laser_scan(Header(stamp=msg.header.stamp, frame_id=base_frame), spec, ranges, scan_time)
