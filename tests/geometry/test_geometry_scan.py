"""Cloud -> scan -> points (geometry/scan.py) and numpy <-> PointCloud2 (msgs/pointcloud.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.geometry.scan import ScanSpec, Stance, cloud_to_ranges, mount_transform, scan_points, to_base
from go2vlm.msgs.pointcloud import cloud_xyz, scan_from_cloud, xyz_cloud
from go2vlm.msgs.sensor_msgs import FLOAT64, PointCloud2, PointField
from go2vlm.msgs.std_msgs import Header
from go2vlm.robot_profile.go2 import GO2

SPEC = ScanSpec()


def test_nearest_point_per_bin_in_the_band() -> None:
    pts = np.array(
        [
            [2.0, 0.0, 0.0],  # ahead
            [3.0, 0.0, 0.0],  # behind it in the same bin
            [0.0, 1.0, 0.1],  # left
            [-1.0, 0.0, -0.30],  # the floor: below the band
            [0.0, -1.0, 0.5],  # above the band
            [0.1, 0.0, 0.0],  # inside the robot's own box
            [np.nan, 0.0, 0.0],
        ]
    )
    r = cloud_to_ranges(pts, ScanSpec(self_hx=0.37, self_hy=0.175))
    ahead = int(round(-SPEC.angle_min / SPEC.angle_increment))
    left = int(round((math.pi / 2 - SPEC.angle_min) / SPEC.angle_increment))
    assert r[ahead] == pytest.approx(2.0) and r[left] == pytest.approx(1.0)
    assert np.isinf(np.delete(r, [ahead, left])).all()


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), min_size=1, max_size=30))
def test_scan_points_are_the_nearest_returns(xy: list[tuple[float, float]]) -> None:
    pts = np.array([[x, y, 0.0] for x, y in xy])
    r = cloud_to_ranges(pts, SPEC)
    back = scan_points(r, SPEC.angle_min, SPEC.angle_increment, SPEC.range_min, SPEC.range_max)
    near = [math.hypot(x, y) for x, y in xy if math.hypot(x, y) >= SPEC.range_min]
    if near:
        assert np.hypot(back[:, 0], back[:, 1]).min() == pytest.approx(min(near), rel=1e-5)
        # Each scan point lies within half a bin of a cloud point's bearing.
        assert len(back) <= len(near)


@pytest.mark.parametrize(
    "ranges, geo",
    [
        ([math.nan], (0.0, 0.1, 0.05, 10.0)),
        ([-math.inf], (0.0, 0.1, 0.05, 10.0)),
        ([-1.0], (0.0, 0.1, 0.05, 10.0)),
        ([], (0.0, 0.1, 0.05, 10.0)),
        ([1.0], (0.0, math.inf, 0.05, 10.0)),
        ([1.0], (0.0, 0.0, 0.05, 10.0)),
        ([1.0] * 100, (0.0, 0.1, 0.05, 10.0)),  # more than a turn
    ],
)
def test_garbage_scans_raise(ranges: list[float], geo: tuple[float, float, float, float]) -> None:
    with pytest.raises(ValueError):
        scan_points(ranges, *geo)


def test_free_space_and_too_close() -> None:
    pts = scan_points([math.inf, 20.0, 0.01, 1.0], 0.0, 0.1, 0.05, 10.0)
    assert len(pts) == 2  # inf and beyond range_max are free; under range_min is kept (not free)


def test_pointcloud_round_trip_and_layouts() -> None:
    xyz = np.random.default_rng(0).normal(size=(50, 3))
    msg = PointCloud2.deserialize(xyz_cloud(Header(frame_id="f"), xyz, np.ones(50)).serialize())
    assert np.allclose(cloud_xyz(msg), xyz, atol=1e-6)
    # float64, big-endian, padded points
    data = np.zeros((3, 4), dtype=">f8")
    data[:, 1:] = xyz[:3]
    fields = [PointField(name=n, offset=8 * (i + 1), datatype=FLOAT64, count=1) for i, n in enumerate("xyz")]
    big = PointCloud2(height=1, width=3, fields=fields, is_bigendian=True, point_step=32, row_step=96,
                      data=data.tobytes())  # fmt: skip
    assert np.allclose(cloud_xyz(big), xyz[:3])
    with pytest.raises(ValueError, match="layout"):
        cloud_xyz(PointCloud2(height=1, width=3, fields=fields, point_step=32, row_step=96, data=b"\0" * 10))
    with pytest.raises(ValueError, match="no field"):
        cloud_xyz(PointCloud2(height=1, width=1, fields=fields[:2], point_step=32, row_step=32, data=b"\0" * 32))


def test_scan_from_cloud_frames() -> None:
    tfs = GO2.lidar_transforms()
    r, t = mount_transform(GO2.lidar.pos, GO2.lidar.pitch)
    wall_base = np.array([[2.0, y, 0.0] for y in np.linspace(-0.5, 0.5, 11)])
    in_lidar = (wall_base - t) @ r  # base -> lidar frame
    assert np.allclose(to_base(in_lidar, (r, t)), wall_base)
    scan = scan_from_cloud(xyz_cloud(Header(frame_id=GO2.lidar.frame), in_lidar), SPEC, tfs, GO2.frames.base)
    assert scan is not None and scan.header.frame_id == GO2.frames.base
    assert min(scan.ranges) == pytest.approx(2.0, abs=1e-4)
    assert scan_from_cloud(xyz_cloud(Header(frame_id=GO2.lidar.frame), np.zeros((0, 3))), SPEC, tfs, "b") is None
    with pytest.raises(ValueError, match="frame"):
        scan_from_cloud(xyz_cloud(Header(frame_id="odom"), in_lidar), SPEC, tfs, GO2.frames.base)


@settings(max_examples=100, deadline=None)
@given(st.floats(0.08, 0.40), st.floats(-0.35, 0.35), st.floats(-0.35, 0.35))
def test_with_its_stance_the_band_is_measured_from_the_floor(height: float, roll: float, pitch: float) -> None:
    """The floor round the robot is never an obstacle, however the base stands, lies or tilts (a Go2
    lying damped, its base 0.1 m up, saw the floor inside the base frame's band, and its guard held it
    after an e-stop's release); a 0.16 m brick 0.6 m ahead stays one. In the base frame alone the
    lying robot's floor is an obstacle."""
    spec = GO2.scan_spec()
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    rot = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]]) @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    xs, ys = np.meshgrid(np.linspace(-3, 3, 61), np.linspace(-3, 3, 61))
    floor = np.column_stack((xs.ravel(), ys.ravel(), np.zeros(xs.size)))
    brick = np.array([(0.6, y, z) for y in np.linspace(-0.08, 0.08, 5) for z in np.linspace(0.0, 0.16, 9)])
    world = np.vstack((floor, brick)) - (0.0, 0.0, height)  # relative to the base, in the level frame
    base = world @ rot  # R^T p: into the tilted base's axes
    r = cloud_to_ranges(base, spec, Stance.of(rot, height))
    ahead = int(round(-spec.angle_min / spec.angle_increment))
    assert r[ahead] == pytest.approx(0.6, abs=0.05)
    others = np.ones(spec.bins, bool)
    others[ahead - 5 : ahead + 6] = False  # the brick spans +-8 degrees
    assert np.isinf(r[others]).all()
    lying = cloud_to_ranges(floor - (0.0, 0.0, 0.1), spec)
    assert np.isfinite(lying).all()  # the base frame's band holds the floor of a lying robot
