"""msgs/sizes.py: one check for every message type with a size; what a real node sends passes, anything
over a cap or whose declared size and data disagree is refused with the reason, before anything is
allocated for it (the bus runs it on every sample: tests/attack/test_attack_sizes.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from go2vlm.msgs.geometry_msgs import Point
from go2vlm.msgs.image import numpy_to_image
from go2vlm.msgs.nav_msgs import MapMetaData, OccupancyGrid, Path
from go2vlm.msgs.pointcloud import xyz_cloud
from go2vlm.msgs.sensor_msgs import Image, LaserScan
from go2vlm.msgs.sizes import SizeCaps, SizeError, check_size
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.msgs.visualization_msgs import Marker, MarkerArray
from go2vlm.world.map_msg import grid_msg

CAPS = SizeCaps()
SMALL = SizeCaps(max_msg_cells=100, max_msg_points=10, max_msg_items=3)


def test_what_nodes_send_passes() -> None:
    for msg in (
        grid_msg(np.zeros((40, 60), dtype=np.int8), (1.0, -2.0), 0.05, "odom", 1.0),
        numpy_to_image(np.zeros((480, 640, 3), dtype=np.uint8), "bgr8"),
        xyz_cloud(Header(frame_id="lidar"), np.zeros((5, 3))),
        LaserScan(ranges=[1.0] * 360),
        Path(poses=[]),
        String(data="x" * 1000),  # no size of its own: passes
    ):
        check_size(msg, CAPS)


def _grid(w: int, h: int, n: int, res: float = 0.05) -> OccupancyGrid:
    return OccupancyGrid(info=MapMetaData(resolution=res, width=w, height=h), data=[0] * n)


@pytest.mark.parametrize(
    ("msg", "says"),
    [
        (_grid(30000, 30000, 16), "30000 x 30000 cells, more than"),
        (_grid(0, 0, 0), "no cells"),
        (_grid(4, 4, 16, math.inf), "not a finite size"),
        (_grid(4, 4, 16, 0.0), "not a finite size"),
        (_grid(4, 4, 16, math.nan), "not a finite size"),
        (_grid(4, 4, 15), "carries 15 values"),
        (Image(width=20000, height=20000, step=60000, data=bytes(64)), "more than"),
        (Image(width=640, height=480, step=1920, data=bytes(100)), "step 1920"),
        (Image(width=640, height=480, step=100, data=bytes(48000)), "step 100"),
        (LaserScan(ranges=[1.0] * 4, intensities=[1.0]), "1 intensities"),
        (MarkerArray(markers=[Marker(points=[Point()] * 11)]), "11 points"),
        (MarkerArray(markers=[Marker()] * 4), "4 markers"),
    ],
)
def test_over_a_cap_or_inconsistent_is_refused_with_the_reason(msg: object, says: str) -> None:
    with pytest.raises(SizeError, match=says):
        check_size(msg, SMALL if isinstance(msg, MarkerArray) else CAPS)


def test_a_cloud_that_does_not_add_up_is_refused() -> None:
    cloud = xyz_cloud(Header(frame_id="lidar"), np.zeros((5, 3)))
    cloud.data = cloud.data[:-1]
    with pytest.raises(SizeError, match="carries"):
        check_size(cloud, CAPS)
    with pytest.raises(SizeError, match="more than the 10"):
        check_size(xyz_cloud(Header(frame_id="lidar"), np.zeros((11, 3))), SMALL)
