"""map: an occupancy grid of the house from the lidar, and the costmap a planner reads.

Every /scan is placed in the world at the robot's pose at the scan's stamp (world/poses.py, the pose
history the object memory uses), its free space ray-cast and its returns marked, in a log-odds grid
(world/occupancy.py) that grows with the house up to a cap. The map never commands anything.

Topics
  subscribes  <scan_topic>      sensor_msgs/LaserScan (sensor-data QoS; /scan), frame base_link: the
                                ranges from the base origin, 360 degrees (geometry/scan.py)
              <odom_topic>      nav_msgs/Odometry (reliable; /odom), in world_frame: the pose history
  publishes   /map              nav_msgs/OccupancyGrid, latched (transient-local, keep-last 1), frame
                                world_frame (odom): -1 unknown, 0 free, 100 occupied; rows = y, cols =
                                x, origin = the world x, y of cell (0, 0)'s outer corner; header.stamp
                                = the newest scan in it. When it changed, at most every publish_period_s
              /map/costmap      nav_msgs/OccupancyGrid, latched, the same cells inflated by the
                                footprint (robot_profile): 100 lethal (occupied, or within the
                                inscribed radius + padding_m), 99 within the circumscribed radius +
                                padding_m (a collision at some headings), 98..1 falling out to
                                inflation_m, 0 free, -1 unknown. With /map
              /map/status       std_msgs/String, latched JSON: frame, size, cells (occupied, free,
                                unknown), scans (integrated, refused.<reason>, dropped beams), the last
                                refusal; every status_period_s and on a new refusal

Parameters
  scan_topic (/scan), odom_topic (/odom), world_frame ("odom"), resolution_m (0.05 m), max_size_m
  (60.0 m: the cap, a side), padding_m (0.05 m), inflation_m (0.8 m), history_s (10.0 s of poses),
  pose_wait_s (0.5 s: a scan newer than the newest pose waits this long), publish_period_s (1.0 s),
  status_period_s (1.0 s).

Refused scans, counted on the status (refused.<reason>), never integrated: wrong_frame (not in
base_link), no_stamp, bad_geometry, older_than_history, pose_gap, no_pose, newer_than_pose (no pose
came within pose_wait_s), beyond_cap (the robot is outside the largest map the cap allows). Dropped
beams, counted (dropped.<kind>): nan (NaN ranges), invalid (-inf, negative), beyond_cap (the part of
a scan past the cap). Bounded: the grid is at most max_size_m a side (60 m at 5 cm: 1440000 cells,
6 MB of log-odds), history_s of poses, 16 scans waiting for their pose.

Time: stamps only (the scans', the poses'); publish_period_s and status_period_s in the node's clock.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from go2vlm.bus import Node, param
from go2vlm.bus.topics import MAP, MAP_COSTMAP, MAP_STATUS, ODOM, SCAN
from go2vlm.geometry.rotations import quat_yaw
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.sensor_msgs import LaserScan
from go2vlm.msgs.std_msgs import String
from go2vlm.robot_profile import go2 as spec
from go2vlm.world.map_msg import grid_msg
from go2vlm.world.occupancy import Beams, CostmapParams, GridParams, OccupancyMap, ScanRefused, inflate
from go2vlm.world.poses import PoseHistory, PoseUnavailable, PoseWait

__all__ = ["MapConfig", "MapNode"]

MAX_PENDING = 16
_GRID = GridParams()


@dataclass
class MapConfig:
    scan_topic: str = param(SCAN.name, help="sensor_msgs/LaserScan in base_link: the lidar ranges")
    odom_topic: str = param(ODOM.name, help="nav_msgs/Odometry in world_frame: the pose history")
    world_frame: str = param(spec.GO2.frames.odom, help="the frame the map is in (/odom's)")
    resolution_m: float = param(_GRID.resolution_m, help="cell size (m)", min=0.01, max=0.5)
    max_size_m: float = param(_GRID.max_size_m, help="the map's cap, a side (m)", min=4.0, max=200.0)
    padding_m: float = param(0.05, help="added to the footprint's radii in the costmap (m)", min=0.0, max=1.0)
    inflation_m: float = param(0.8, help="the costmap's cost falls to 0 at this distance (m)", min=0.1, max=5.0)
    history_s: float = param(10.0, help="poses kept: the oldest scan placed (s)", min=1.0, max=600.0)
    pose_wait_s: float = param(0.5, help="a scan newer than the newest pose waits this long (s)", min=0.0, max=5.0)
    publish_period_s: float = param(1.0, help="/map and /map/costmap at most this often (s)", min=0.1, max=60.0)
    status_period_s: float = param(1.0, help="/map/status period besides on a new refusal", min=0.1, max=60.0)

    def validate(self) -> None:
        self.grid_params()
        self.costmap_params()

    def grid_params(self) -> GridParams:
        return GridParams(resolution_m=self.resolution_m, max_size_m=self.max_size_m)

    def costmap_params(self) -> CostmapParams:
        return CostmapParams.for_footprint(
            spec.FOOTPRINT_LENGTH, spec.FOOTPRINT_WIDTH, self.padding_m, self.inflation_m
        )


class MapNode(Node):
    """The ``map`` node; its contract (topics, parameters) is the module docstring."""

    name = "map"
    Config = MapConfig

    def __init__(self, config: MapConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        cfg: MapConfig = self.config
        self.grid = OccupancyMap(cfg.grid_params())
        self.costmap_params = cfg.costmap_params()
        self.poses = PoseHistory(horizon_s=cfg.history_s)
        self._waiting: PoseWait[LaserScan] = PoseWait(cfg.pose_wait_s, MAX_PENDING)
        self.newest_scan = 0.0
        self.refused: dict[str, int] = {}
        self.dropped: dict[str, int] = {"nan": 0, "invalid": 0, "beyond_cap": 0}
        self.last_refusal = ""
        self._dirty = False
        self.pub_map = MAP.publisher(self)
        self.pub_costmap = MAP_COSTMAP.publisher(self)
        self.pub_status = MAP_STATUS.publisher(self)
        ODOM.subscription(self, self.on_odom, name=cfg.odom_topic)
        SCAN.subscription(self, self.on_scan, name=cfg.scan_topic)
        self.create_timer(cfg.publish_period_s, self.publish_map)
        self.create_timer(cfg.status_period_s, self.publish_status)
        self.publish_status()
        self.log.info(f"mapping {self.resolve(cfg.scan_topic)} in {cfg.world_frame} at {cfg.resolution_m:g} m, "
                      f"at most {cfg.max_size_m:g} m a side")  # fmt: skip

    # -- inputs ------------------------------------------------------------------------------
    def on_odom(self, msg: Odometry) -> None:
        if msg.header.frame_id and msg.header.frame_id != self.config.world_frame:
            n = self.count("odom_wrong_frame")
            self.log.throttled("error", 5.0, f"ignoring /odom in frame {msg.header.frame_id!r} ({n} so far); "
                               f"world_frame is {self.config.world_frame!r}", key="odom")  # fmt: skip
            return
        p = msg.pose.pose
        q = p.orientation
        if self.poses.add(msg.header.stamp.to_sec(), p.position.x, p.position.y, quat_yaw(q.w, q.x, q.y, q.z)):
            self._retry_waiting()

    def on_scan(self, msg: LaserScan) -> None:
        self.count("scans")
        if msg.header.frame_id != spec.BASE_FRAME:
            self._refuse("wrong_frame", f"a scan in frame {msg.header.frame_id!r}, not {spec.BASE_FRAME!r}")
            return
        if msg.header.stamp.to_sec() <= 0.0:
            self._refuse("no_stamp", "a scan without a stamp: where was the robot?")
            return
        self._take(msg, self.now())

    def _take(self, msg: LaserScan, arrived: float) -> None:
        stamp = msg.header.stamp.to_sec()
        try:
            pose = self._waiting.pose_for(self.poses, stamp, msg, arrived, self.now())
        except PoseUnavailable as exc:
            self._refuse(exc.reason, str(exc))
            return
        if pose is None:
            return  # waits for its pose
        beams = Beams(np.asarray(msg.ranges, dtype=np.float32), msg.angle_min, msg.angle_increment, msg.range_min,
                      msg.range_max)  # fmt: skip
        try:
            got = self.grid.integrate(beams, pose)
        except ScanRefused as exc:
            self._refuse(exc.reason, str(exc))
            return
        self.count("integrated")
        for kind in self.dropped:
            self.dropped[kind] += getattr(got, kind)
        self.newest_scan = max(self.newest_scan, stamp)
        self._dirty = True

    def _retry_waiting(self) -> None:
        for arrived, msg in self._waiting.due():
            self._take(msg, arrived)

    def _refuse(self, reason: str, detail: str) -> None:
        self.count(f"refused.{reason}")
        self.refused[reason] = self.refused.get(reason, 0) + 1
        new = f"{reason}: {detail}"
        if new.split(":")[0] != self.last_refusal.split(":")[0]:
            self.last_refusal = new
            self.log.throttled("warning", 5.0, f"refused a scan: {new}", key=f"refused.{reason}")
            self.publish_status()
        self.last_refusal = new

    # -- outputs -----------------------------------------------------------------------------
    def publish_map(self) -> None:
        """/map and /map/costmap, when a scan changed the grid since the last ones."""
        if not self._dirty or self.grid.empty:
            return
        self._dirty = False
        cfg, grid = self.config, self.grid
        values = grid.values()
        cost = inflate(values, grid.resolution, self.costmap_params)
        self.pub_map.publish(grid_msg(values, grid.origin, grid.resolution, cfg.world_frame, self.newest_scan))
        self.pub_costmap.publish(grid_msg(cost, grid.origin, grid.resolution, cfg.world_frame, self.newest_scan))
        self.count("published")

    def status(self) -> dict[str, Any]:
        g = self.grid
        rows, cols = g.shape
        return {
            "frame": self.config.world_frame,
            "resolution_m": g.resolution,
            "size_m": [round(cols * g.resolution, 2), round(rows * g.resolution, 2)],
            "origin": [round(v, 3) for v in g.origin],
            "cap_m": g.params.max_size_m,
            "cells": g.counts() if not g.empty else {"occupied": 0, "free": 0, "unknown": 0},
            "scans": self.counters.get("scans", 0),
            "integrated": self.counters.get("integrated", 0),
            "refused": dict(sorted(self.refused.items())),
            "dropped": dict(self.dropped),
            "last_refusal": self.last_refusal,
            "newest_scan": round(self.newest_scan, 3),
            "poses_s": round((self.poses.newest or 0.0) - (self.poses.oldest or 0.0), 2),
            "published": self.counters.get("published", 0),
        }

    def publish_status(self) -> None:
        self.pub_status.publish(String(data=json.dumps(self.status(), ensure_ascii=False)))
