"""The map node over real DDS: scans of a room at the pose of their stamps give a latched /map with the
room's walls where they are and a costmap inflated by the footprint; bad scans are refused with a
reason on /map/status and change nothing."""

from __future__ import annotations

import json
import math
import threading

import numpy as np
from busutil import wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node, running
from go2vlm.geometry.rotations import yaw_quat
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Point, Pose, Quaternion
from go2vlm.msgs.nav_msgs import OccupancyGrid, Odometry
from go2vlm.msgs.sensor_msgs import LaserScan
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.world.map_msg import Grid, grid_of
from go2vlm.world.occupancy import FREE, INSCRIBED, LETHAL, UNKNOWN
from go2vlm.world.poses import Pose2D

ROOM = (3.0, 2.0)  # half sizes of the room about the origin (m)
BINS = 180


def room_ranges(pose: Pose2D) -> list[float]:
    a = pose.yaw - math.pi + (2 * math.pi / BINS) * np.arange(BINS)
    dx, dy = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(dx > 0, (ROOM[0] - pose.x) / dx, np.where(dx < 0, (-ROOM[0] - pose.x) / dx, np.inf))
        ty = np.where(dy > 0, (ROOM[1] - pose.y) / dy, np.where(dy < 0, (-ROOM[1] - pose.y) / dy, np.inf))
    return np.minimum(tx, ty).astype(np.float32).tolist()


class Lidar(Node):
    """A robot stand-in: /odom at 50 Hz as it drives along x at `vx`, and what it publishes by hand."""

    name = "fake_lidar"

    def __init__(self, **kw: object) -> None:
        super().__init__(**kw)
        self.lock = threading.Lock()
        self.x, self.vx = -1.0, 0.0
        self.odom = self.create_publisher(Odometry, "/odom", QOS_DEFAULT)
        self.scan = self.create_publisher(LaserScan, "/scan", QOS_SENSOR)
        self.maps: list[OccupancyGrid] = []
        self.costmaps: list[OccupancyGrid] = []
        self.status: list[dict] = []
        self.create_subscription(OccupancyGrid, "/map", lambda m: self._keep(self.maps, m), QOS_LATCHED)
        self.create_subscription(OccupancyGrid, "/map/costmap", lambda m: self._keep(self.costmaps, m), QOS_LATCHED)
        self.create_subscription(String, "/map/status", lambda m: self._keep(self.status, json.loads(m.data)),
                                 QOS_LATCHED)  # fmt: skip
        self.create_timer(0.02, self.tick)

    def _keep(self, into: list, m: object) -> None:
        with self.lock:
            into.append(m)

    def pose(self) -> Pose2D:
        with self.lock:
            return Pose2D(self.x, 0.0, 0.3)

    def tick(self) -> None:
        with self.lock:
            self.x = min(self.x + self.vx * 0.02, 1.5)
        p = self.pose()
        q = yaw_quat(p.yaw)
        msg = Odometry(header=Header(stamp=self.stamp(), frame_id="odom"), child_frame_id="base_link")
        msg.pose.pose = Pose(position=Point(x=p.x, y=p.y), orientation=Quaternion(z=float(q[3]), w=float(q[0])))
        self.odom.publish(msg)

    def send_scan(self, ranges: list[float], frame: str = "base_link", stamp: float | None = None) -> None:
        t = self.now() - 0.03 if stamp is None else stamp  # a scan a little older than the newest pose
        self.scan.publish(LaserScan(header=Header(stamp=self.stamp(t), frame_id=frame), angle_min=-math.pi,
                                    angle_max=math.pi - 2 * math.pi / BINS, angle_increment=2 * math.pi / BINS,
                                    range_min=0.05, range_max=10.0, ranges=ranges))  # fmt: skip

    def last_status(self) -> dict:
        with self.lock:
            return self.status[-1] if self.status else {}

    def last(self, which: list[OccupancyGrid]) -> Grid | None:
        with self.lock:
            return grid_of(which[-1]) if which else None


def _near_wall(grid: Grid, tol: float) -> bool:
    rows, cols = np.nonzero(grid.cells == LETHAL)
    x = grid.origin[0] + (cols + 0.5) * grid.resolution
    y = grid.origin[1] + (rows + 0.5) * grid.resolution
    dx, dy = np.abs(x) - ROOM[0], np.abs(y) - ROOM[1]
    d = np.where((dx <= 0) & (dy <= 0), np.minimum(-dx, -dy), np.hypot(np.maximum(dx, 0), np.maximum(dy, 0)))
    return len(d) > 100 and bool((d <= tol).all())


def test_scans_become_a_latched_map_and_costmap_and_bad_scans_a_reason() -> None:
    node = make_node("map", params={"publish_period_s": 0.2, "status_period_s": 0.2})
    lidar = Lidar()
    with running(lidar, node):
        assert wait_for(lambda: lidar.scan.matched >= 1 and lidar.odom.matched >= 1, 10)
        assert wait_for(lambda: lidar.last_status().get("poses_s", 0) > 0.3, 10)
        # Bad scans: another frame, no stamp, a broken geometry; nothing is mapped.
        lidar.send_scan(room_ranges(lidar.pose()), frame="utlidar_lidar")
        lidar.send_scan(room_ranges(lidar.pose()), stamp=0.0)
        assert wait_for(lambda: {"wrong_frame", "no_stamp"} <= set(lidar.last_status().get("refused", {})), 10)
        assert lidar.last_status()["integrated"] == 0 and lidar.last(lidar.maps) is None
        # The robot drives through the room; every scan is placed at the pose of its stamp.
        lidar.vx = 1.0

        def mapped() -> bool:
            lidar.send_scan(room_ranges(lidar.pose()))
            return lidar.last_status().get("integrated", 0) >= 20 and lidar.pose().x >= 1.5

        assert wait_for(mapped, 20, 0.05)
        assert wait_for(lambda: lidar.last(lidar.maps) is not None and lidar.last(lidar.costmaps) is not None, 10)
        grid = lidar.last(lidar.maps)
        assert grid is not None and grid.frame_id == "odom"
        assert _near_wall(grid, grid.resolution * 1.5), "occupied cells off the walls: scans placed at the wrong pose"
        assert grid.cells[grid.cell_of(0.0, 0.0)] == FREE
        assert set(np.unique(grid.cells)) <= {UNKNOWN, FREE, LETHAL}
        cost = lidar.last(lidar.costmaps)
        assert cost is not None and cost.cells.shape == grid.cells.shape and cost.origin == grid.origin
        assert cost.cells[cost.cell_of(ROOM[0] - 0.1, 0.0)] == LETHAL  # inside the inscribed radius of the wall
        assert cost.cells[cost.cell_of(ROOM[0] - 0.3, 0.0)] == INSCRIBED
        assert cost.cells[cost.cell_of(0.0, 0.0)] == FREE
        st = lidar.last_status()
        assert st["cells"]["occupied"] > 100 and st["published"] >= 1 and st["cap_m"] == 60.0
        # NaN beams are dropped and counted, the rest of the scan is used.
        ranges = room_ranges(lidar.pose())
        ranges[:10] = [math.nan] * 10
        lidar.send_scan(ranges)
        assert wait_for(lambda: lidar.last_status().get("dropped", {}).get("nan", 0) >= 10, 10)
        # A late subscriber hears the last map at once (latched).
        late = Node(node_name="late_listener")
        heard: list[OccupancyGrid] = []
        late.create_subscription(OccupancyGrid, "/map", heard.append, QOS_LATCHED)
        with running(late):
            assert wait_for(lambda: len(heard) >= 1, 10)
