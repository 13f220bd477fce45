"""The map node over real DDS: scans of a room at the pose of their stamps give a latched /map with the
room's walls where they are and a costmap inflated by the footprint; bad scans are refused with a
reason on /map/status and change nothing."""

from __future__ import annotations

import json
import math
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from busutil import wait_for
from maputil import BINS, room_scan

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node, running
from go2vlm.bus.service import ServiceClient
from go2vlm.errors import ConfigError
from go2vlm.geometry.rotations import yaw_quat
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Point, Pose, Quaternion
from go2vlm.msgs.go2vlm_msgs import MemoryFile
from go2vlm.msgs.nav_msgs import OccupancyGrid, Odometry
from go2vlm.msgs.sensor_msgs import LaserScan
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.statefiles import state_dir
from go2vlm.world.map_file import dumps, loads
from go2vlm.world.map_msg import Grid, grid_of
from go2vlm.world.occupancy import CIRCUMSCRIBED, FREE, INSCRIBED, LETHAL, UNKNOWN, GridParams, OccupancyMap
from go2vlm.world.poses import Pose2D

ROOM = (3.01, 2.02)  # half sizes of the room about the origin (m)


def room_ranges(pose: Pose2D) -> list[float]:
    return room_scan(pose, room=ROOM).ranges.tolist()


class Lidar(Node):
    """A robot stand-in: /odom at 50 Hz as it drives along x at `vx` (odometry off the truth by
    `odom_dx` and `odom_dyaw`), scans of the room at the true pose, and what the map node says."""

    name = "fake_lidar"

    def __init__(self, **kw: object) -> None:
        super().__init__(**kw)
        self.lock = threading.Lock()
        self.x, self.vx, self.odom_dx, self.odom_dyaw = -1.0, 0.0, 0.0, 0.0
        self.odom = self.create_publisher(Odometry, "/odom", QOS_DEFAULT)
        self.scan = self.create_publisher(LaserScan, "/scan", QOS_SENSOR)
        self.maps: list[OccupancyGrid] = []
        self.costmaps: list[OccupancyGrid] = []
        self.status: list[dict] = []
        self.corrected: list[Odometry] = []
        self.create_subscription(Odometry, "/map/odom", lambda m: self._keep(self.corrected, m), QOS_DEFAULT)
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
        p = Pose2D(p.x + self.odom_dx, p.y, p.yaw + self.odom_dyaw)
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
        assert cost.cells[cost.cell_of(ROOM[0] - 0.1, 0.0)] == INSCRIBED  # inside the inscribed radius of the wall
        assert CIRCUMSCRIBED <= cost.cells[cost.cell_of(ROOM[0] - 0.35, 0.0)] < INSCRIBED  # the band: a cost
        assert cost.cells[cost.cell_of(0.0, 0.0)] == FREE
        st = lidar.last_status()
        assert st["cells"]["occupied"] > 100 and st["published"] >= 1 and st["cap_m"] == 60.0
        # NaN beams are dropped and counted, the rest of the scan is used.
        ranges = room_ranges(lidar.pose())
        ranges[:10] = [math.nan] * 10
        lidar.send_scan(ranges)
        assert wait_for(lambda: lidar.last_status().get("dropped", {}).get("nan", 0) >= 10, 10)
        assert "10 NaN" in lidar.last_status()["last_drop"] and lidar.last_status()["refused"].get("nan") is None
        # A late subscriber hears the last map at once (latched).
        late = Node(node_name="late_listener")
        heard: list[OccupancyGrid] = []
        late.create_subscription(OccupancyGrid, "/map", heard.append, QOS_LATCHED)
        with running(late):
            assert wait_for(lambda: len(heard) >= 1, 10)


def test_an_odometry_jump_loses_the_map_until_a_scan_fits_it_again() -> None:
    """Picked up and put down where it was, odometry turned 60 degrees: the scans do not fit the map
    there, so nothing is written (lost) until odometry comes back; lost long enough, a new map."""
    node = make_node("map", params={"publish_period_s": 0.2, "status_period_s": 0.2, "lost_reset_s": 3.0})
    lidar = Lidar()
    with running(lidar, node):
        assert wait_for(lambda: lidar.scan.matched >= 1 and lidar.last_status().get("poses_s", 0) > 0.3, 10)

        def scans(until: Callable[[dict], bool]) -> bool:
            lidar.send_scan(room_ranges(lidar.pose()))
            return until(lidar.last_status())

        assert wait_for(lambda: scans(lambda st: st.get("integrated", 0) >= 10), 10, 0.05)
        assert wait_for(lambda: lidar.last(lidar.maps) is not None, 10)
        cells = lidar.last_status()["cells"]["occupied"]
        lidar.odom_dyaw = math.radians(60)  # the jump
        assert wait_for(lambda: scans(lambda st: st.get("state") == "lost"), 10, 0.05)
        st = lidar.last_status()
        assert st["odom_jumps"] == 1 and "turned 60 deg" in st["last_jump"] and st["refused"]["lost"] >= 1
        integrated = st["integrated"]
        assert wait_for(lambda: scans(lambda st: st["refused"].get("lost", 0) >= 5), 10, 0.05)
        assert lidar.last_status()["integrated"] == integrated, "a scan was written while lost"
        lidar.odom_dyaw = 0.0  # put back: odometry agrees with the map again
        assert wait_for(lambda: scans(lambda st: st.get("state") == "mapping" and st["integrated"] > integrated), 10,
                        0.05)  # fmt: skip
        st = lidar.last_status()
        assert st["odom_jumps"] == 2 and st["resets"] == 0 and st["cells"]["occupied"] >= cells * 0.9
        lidar.odom_dyaw = math.radians(-45)  # lost for good: after lost_reset_s of scans, a new map
        assert wait_for(lambda: scans(lambda st: st.get("resets", 0) == 1), 15, 0.05)
        st = lidar.last_status()
        assert st["state"] == "mapping" and "lost for" in st["last_reset"]


def test_scan_matching_corrects_drifting_odometry_on_map_odom() -> None:
    node = make_node("map", params={"scan_matching": True, "publish_period_s": 0.2, "status_period_s": 0.2})
    lidar = Lidar()
    with running(lidar, node):
        assert wait_for(lambda: lidar.scan.matched >= 1 and lidar.last_status().get("poses_s", 0) > 0.3, 10)
        assert wait_for(lambda: len(lidar.corrected) > 5, 10)
        lidar.vx = 0.5

        def drive() -> bool:  # odometry overshoots: 10 % more than the robot moves
            lidar.odom_dx = 0.1 * (lidar.pose().x + 1.0)
            lidar.send_scan(room_ranges(lidar.pose()))
            return lidar.pose().x >= 1.5

        assert wait_for(drive, 20, 0.05)
        assert wait_for(lambda: lidar.last_status().get("matches", {}).get("ok", 0) >= 10, 10)
        for _ in range(5):
            lidar.send_scan(room_ranges(lidar.pose()))
        assert wait_for(lambda: lidar.last_status().get("newest_scan", 0) > lidar.now() - 0.3, 5)
        with lidar.lock:
            last = lidar.corrected[-1]
        assert last.header.frame_id == "map" and last.child_frame_id == "base_link"
        assert abs(lidar.odom_dx) > 0.2
        assert abs(last.pose.pose.position.x - lidar.pose().x) < 0.08, (last.pose.pose.position.x, lidar.pose())
        grid = lidar.last(lidar.maps)
        assert grid is not None and grid.frame_id == "map"
        assert _near_wall(grid, grid.resolution * 2.5), "walls smeared: scans placed on the drifting odometry"


def test_the_map_is_saved_and_loaded_all_or_nothing(tmp_path: Path) -> None:
    files_dir = state_dir() / "objects"  # the files must be under the state directory (statefiles.py)
    files_dir.mkdir(parents=True, exist_ok=True)
    node = make_node("map", params={"world": "home", "publish_period_s": 0.2, "status_period_s": 0.2})
    lidar = Lidar()
    with running(lidar, node), ServiceClient(MemoryFile, "/map/map_file", lidar.participant) as files:
        assert wait_for(lambda: lidar.scan.matched >= 1 and lidar.last_status().get("poses_s", 0) > 0.3, 10)

        def mapped() -> bool:
            lidar.send_scan(room_ranges(lidar.pose()))
            return lidar.last_status().get("integrated", 0) >= 10

        assert wait_for(mapped, 10, 0.05)
        memory = files_dir / "home.json"  # the object memory's file: the map goes beside it
        rep = files.call(MemoryFile.Request(command="save", path=str(memory)), 10)
        assert rep.success and rep.objects > 100 and (files_dir / "home.map.npz").exists(), rep.message
        saved = loads((files_dir / "home.map.npz").read_bytes(), "home", "odom", GridParams())
        cells = lidar.last_status()["cells"]
        # Refused, one line each, and the map stays as it was.
        other = OccupancyMap()
        other.integrate(room_scan(Pose2D(0, 0, 0), room=(1.51, 1.02)), Pose2D(0, 0, 0))
        (files_dir / "office.map.npz").write_bytes(dumps(other, "office", "odom", 1.0))
        (files_dir / "broken.map.npz").write_bytes((files_dir / "home.map.npz").read_bytes()[:300])
        for name, says in (("office.json", "world 'office'"), ("broken.json", "not a map file")):
            for command in ("check", "load"):
                rep = files.call(MemoryFile.Request(command=command, path=str(files_dir / name)), 10)
                assert not rep.success and says in rep.message and "\n" not in rep.message, rep.message
        rep = files.call(MemoryFile.Request(command="load", path=str(files_dir / "none.json")), 10)
        assert rep.success and "no map file" in rep.message
        assert lidar.last_status()["cells"] == cells
        # A map of this world loads whole: the smaller room replaces the one mapped.
        (files_dir / "small.map.npz").write_bytes(dumps(other, "home", "odom", 1.0))
        rep = files.call(MemoryFile.Request(command="load", path=str(files_dir / "small.json")), 10)
        assert rep.success and rep.objects == other.counts()["occupied"], rep.message
        assert wait_for(lambda: lidar.last_status()["cells"] == other.counts(), 5), lidar.last_status()
        assert wait_for(lambda: (g := lidar.last(lidar.maps)) is not None and g.cells.shape == other.shape, 5)
        assert saved.counts()["occupied"] == cells["occupied"]
    # At start: the map beside memory_file's name is loaded; a bad one stops the node with one line.
    again = make_node("map", params={"world": "home", "map_file": str(memory)})
    try:
        assert again.grid.counts() == saved.counts() and again.grid.origin == saved.origin
    finally:
        again.shutdown()
    with pytest.raises(ConfigError, match="world 'office'"):
        make_node("map", params={"world": "home", "map_file": str(files_dir / "office.json")})
