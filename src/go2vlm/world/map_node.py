"""map: an occupancy grid of the house from the lidar, the costmap a planner reads, and (with
scan_matching) the odometry corrected against the map.

Every /scan is placed in the world at the robot's pose at the scan's stamp (world/poses.py, the pose
history the object memory uses), its free space ray-cast and its returns marked, in a log-odds grid
(world/occupancy.py) that grows with the house up to a cap. The map never commands anything.

Topics
  subscribes  <scan_topic>      sensor_msgs/LaserScan (sensor-data QoS; /scan), frame base_link: the
                                ranges from the base origin, 360 degrees (geometry/scan.py)
              <odom_topic>      nav_msgs/Odometry (reliable; /odom), in odom_frame: the pose history
  publishes   /map              nav_msgs/OccupancyGrid, latched (transient-local, keep-last 1), frame
                                odom_frame (odom), or map_frame (map) with scan_matching: -1 unknown,
                                0 free, 100 occupied; rows = y, cols = x, origin = the world x, y of
                                cell (0, 0)'s outer corner; header.stamp = the newest scan in it. When
                                it changed, at most every publish_period_s
              /map/costmap      nav_msgs/OccupancyGrid, latched, the same cells inflated by the
                                footprint (robot_profile), codes of world/occupancy.py: 100 an
                                obstacle, 99 within the inscribed radius + padding_m (never entered),
                                90..98 within the circumscribed radius + padding_m (a collision at
                                some headings: a cost, the planner checks the footprint there),
                                89..1 falling out to inflation_m, 0 free, -1 unknown. With /map
              /map/odom         nav_msgs/Odometry (reliable), only with scan_matching: every /odom
                                sample corrected by the newest scan match, frame map_frame, child
                                base_link, the twist as /odom's
              /tf               tf2_msgs/TFMessage (reliable), only with scan_matching: map_frame ->
                                odom_frame (the correction) at each scan, so that rviz2 and Foxglove
                                show the map under the robot
  services    /map/map_file     go2vlm_msgs/srv/MemoryFile: save | load | check the map file beside a
                                memory file (path = the memory file as the object memory takes it: a
                                name, or a path in $XDG_STATE_HOME/go2vlm/objects (statefiles.py);
                                home -> objects/home.map.npz; world/map_file.py). Map files only,
                                opened by folder descriptor, never through a symlink. A save never
                                replaces a file without overwrite; one that would take the map
                                files past max_files or max_files_mib is refused (the
                                status's `files` says when a cap is reached). A load (and a check)
                                reads and checks the whole file first: a file of another world,
                                frame or resolution, larger than the cap, or corrupt is refused with
                                one line and the map stays as it was. `go2vlm objects --save/--load`
                                calls it with the object memory's, all or nothing. Every request is
                                answered, a failure with its reason (bus/service.py)
              /map/status       std_msgs/String, latched JSON: state (mapping | lost), frame, size,
                                cells (occupied, free, unknown), scans (integrated, refused.<reason>,
                                dropped beams and the last drop), matches, the correction, odometry
                                jumps and resets, the last refusal, the map files (`files`: count,
                                bytes, caps, full) and the service's error replies; every
                                status_period_s and on a new refusal

Parameters
  scan_topic (/scan), odom_topic (/odom), odom_frame ("odom"), map_frame ("map"), resolution_m
  (0.05 m), max_size_m (60.0 m: the cap, a side), padding_m (0.05 m: the clearance standing),
  inflation_m (0.8 m), history_s
  (10.0 s of poses), pose_wait_s (0.5 s: a scan newer than the newest pose waits this long),
  scan_matching (false), match_window_m (6.0 m), lost_reset_s (10.0 s), world ("": the place the map
  is of; a map file of another world is refused), map_file ("": a memory file whose map to load at
  start; one that is corrupt, of another world, frame or resolution stops the node with one line,
  exit 2; a missing one starts empty), save_on_exit (false), max_files (64), max_files_mib (1024
  MiB), publish_period_s (1.0 s), status_period_s (1.0 s).

Refused scans, counted on the status (refused.<reason>), never integrated: wrong_frame (not in
base_link), no_stamp, bad_geometry, older_than_history, pose_gap, no_pose, newer_than_pose (no pose
came within pose_wait_s), beyond_cap (the robot is outside the largest map the cap allows),
odom_jump (stamped before an odometry jump), lost (see below). Dropped beams, counted
(dropped.<kind>) with the last drop on the status, the rest of the scan used: nan (NaN ranges, no
measurement), invalid (-inf, negative), beyond_cap (the part of a scan past the cap). +inf is no
return within range_max (REP 117): free space, as far as range_max. Bounded: the grid is at most
max_size_m a side (60 m at 5 cm: 1440000 cells, 6 MB of log-odds), history_s of poses, 16 scans
waiting for their pose.

Odometry jumps (a teleport, a robot picked up and put down): an /odom sample farther from the last
than the robot can move or turn in between (1.5 x its speed ceilings, at least 0.25 m or 20 deg) is
a jump. The pose history starts again at it (no scan is placed on a pose interpolated across it; a
scan stamped before it is refused, odom_jump), and the next scan is checked against the map at the
pose odometry gives (matched first, with scan_matching). A scan that agrees with the map, or that
falls where the map knows nothing (fewer than 40 returns on seen cells: a new place), is integrated
and mapping goes on. One that disagrees is refused and the map is `lost`: nothing is written while
lost, each scan is checked again, and the first that agrees ends it. Lost for lost_reset_s (scan
stamps; 0 = never) the node starts a new, empty map (a reset, on the status): the old one was of
another place or another odometry, and a half-right map is worse than none.

Scan matching (scan_matching: true, for odometry that drifts): each scan is matched against the map
(world/scan_match.py: a correlative search then Gauss-Newton on a likelihood field of the map within
match_window_m of the robot) from the pose odometry gives, corrected by the last match. A match that
holds becomes the correction (map_frame <- odom_frame), the scan is integrated at the matched pose,
and /map/odom carries every /odom sample corrected. A weak match keeps the last correction.

Time: stamps only (the scans', the poses'); publish_period_s and status_period_s in the node's clock.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from go2vlm.bus import Node, core_params, from_core, param
from go2vlm.bus.topics import MAP, MAP_COSTMAP, MAP_FILE_SERVICE, MAP_ODOM, MAP_STATUS, ODOM, SCAN, TF
from go2vlm.errors import ConfigError
from go2vlm.geometry.footprint import Clearance
from go2vlm.geometry.rotations import quat_mul, quat_yaw, yaw_quat
from go2vlm.msgs.base_state import transform_stamped
from go2vlm.msgs.geometry_msgs import Quaternion
from go2vlm.msgs.go2vlm_msgs import MemoryFile, MemoryFile_Request, MemoryFile_Response
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.sensor_msgs import LaserScan
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.msgs.tf2_msgs import TFMessage
from go2vlm.robot_profile import go2 as spec
from go2vlm.statefiles import FileCaps, Quota, StateFileError, read_bounded, write_atomic
from go2vlm.world.map_file import MAP_KIND, MAX_FILE_BYTES, MapFileError, dumps, loads, map_path
from go2vlm.world.map_msg import grid_msg
from go2vlm.world.occupancy import Beams, CostmapParams, GridParams, OccupancyMap, ScanRefused, inflate
from go2vlm.world.poses import Pose2D, PoseHistory, PoseUnavailable, PoseWait, odometry_jump
from go2vlm.world.scan_match import Corrector, fit

__all__ = ["MapConfig", "MapNode"]

MAX_PENDING = 16
FIELD_EVERY = 5  # scans between two rebuilds of the matcher's field (the map changes slowly)
# /scan is binned from the base origin; the lidar's rays start here, in the base frame (geometry/scan.py).
LIDAR_XY = (spec.GO2.lidar.pos[0], spec.GO2.lidar.pos[1])
_GRID = GridParams()


@dataclass
class MapConfig:
    scan_topic: str = param(SCAN.name, help="sensor_msgs/LaserScan in base_link: the lidar ranges")
    odom_topic: str = param(ODOM.name, help="nav_msgs/Odometry in odom_frame: the pose history")
    odom_frame: str = param(spec.GO2.frames.odom, help="/odom's frame: the map's without scan matching")
    map_frame: str = param("map", help="the map's frame with scan_matching (/map/odom's)")
    resolution_m: float = param(_GRID.resolution_m, help="cell size (m)", min=0.01, max=0.5)
    max_size_m: float = param(_GRID.max_size_m, help="the map's cap, a side (m)", min=4.0, max=200.0)
    padding_m: float = param(
        Clearance().creep_m, help="added to the footprint's radii in the costmap (m): the clearance at a creep",
        min=0.0, max=1.0,
    )  # fmt: skip
    inflation_m: float = param(0.8, help="the costmap's cost falls to 0 at this distance (m)", min=0.1, max=5.0)
    history_s: float = param(10.0, help="poses kept: the oldest scan placed (s)", min=1.0, max=600.0)
    pose_wait_s: float = param(0.5, help="a scan newer than the newest pose waits this long (s)", min=0.0, max=5.0)
    scan_matching: bool = param(False, help="correct odometry by matching each scan against the map (/map/odom)")
    match_window_m: float = param(6.0, help="the matcher sees the map this far round the robot (m)", min=2.0,
                                  max=30.0)  # fmt: skip
    lost_reset_s: float = param(10.0, help="lost this long after an odometry jump: a new map (s; 0 = never)",
                                min=0.0, max=3600.0)  # fmt: skip
    world: str = param("", help="the place this map is of; a map file of another world is refused")
    map_file: str = param("", help="the memory file whose map (NAME.map.npz beside it) to load at start ('' = none)")
    save_on_exit: bool = param(False, help="write map_file's map when the node stops")
    max_files: int = from_core(FileCaps, "max_files")
    max_files_mib: float = from_core(FileCaps, "max_files_mib")
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

    def quota(self) -> Quota:
        return core_params(FileCaps, self).quota(MAP_KIND)


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
        self.frame = cfg.map_frame if cfg.scan_matching else cfg.odom_frame
        self.corrector = Corrector(window_m=cfg.match_window_m, field_every=FIELD_EVERY)
        self._waiting: PoseWait[LaserScan] = PoseWait(cfg.pose_wait_s, MAX_PENDING)
        self._last_odom: tuple[float, Pose2D] | None = None
        self._jump_t = -math.inf  # the stamp of the newest odometry jump
        self._check = False  # the next scan is checked against the map (after a jump, while lost)
        self._lost_since: float | None = None
        self.newest_scan = 0.0
        self.refused: dict[str, int] = {}
        self.dropped: dict[str, int] = {"nan": 0, "invalid": 0, "beyond_cap": 0}
        self.last_refusal = self.last_drop = self.last_jump = self.last_reset = ""
        self._dirty = False
        if cfg.map_file:
            try:
                path = map_path(cfg.map_file)
            except StateFileError as exc:
                raise ConfigError(f"map_file: {exc}") from None
            self._load_at_start(path)
        self.pub_map = MAP.publisher(self)
        self.pub_costmap = MAP_COSTMAP.publisher(self)
        self.pub_status = MAP_STATUS.publisher(self)
        self.pub_odom = MAP_ODOM.publisher(self) if cfg.scan_matching else None
        self.pub_tf = TF.publisher(self) if cfg.scan_matching else None
        ODOM.subscription(self, self.on_odom, name=cfg.odom_topic)
        SCAN.subscription(self, self.on_scan, name=cfg.scan_topic)
        self.create_service(MemoryFile, MAP_FILE_SERVICE, self.map_file)
        self.create_timer(cfg.publish_period_s, self.publish_map)
        self.create_timer(cfg.status_period_s, self.publish_status)
        self.publish_status()
        self.log.info(f"mapping {self.resolve(cfg.scan_topic)} in {self.frame} at {cfg.resolution_m:g} m, at most "
                      f"{cfg.max_size_m:g} m a side, scan matching {'on' if cfg.scan_matching else 'off'}")  # fmt: skip

    # -- inputs ------------------------------------------------------------------------------
    def on_odom(self, msg: Odometry) -> None:
        cfg = self.config
        if msg.header.frame_id and msg.header.frame_id != cfg.odom_frame:
            n = self.count("odom_wrong_frame")
            self.log.throttled("error", 5.0, f"ignoring /odom in frame {msg.header.frame_id!r} ({n} so far); "
                               f"odom_frame is {cfg.odom_frame!r}", key="odom")  # fmt: skip
            return
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        t, pose = msg.header.stamp.to_sec(), Pose2D(p.x, p.y, quat_yaw(q.w, q.x, q.y, q.z))
        if not all(math.isfinite(v) for v in (t, pose.x, pose.y, pose.yaw)):
            self.count("bad_odom")
            return
        last = self._last_odom
        if last is not None and t > last[0]:
            ceil = spec.GO2.ceilings
            why = odometry_jump(t - last[0], last[1], pose, ceil.vx_forward, ceil.vyaw)
            if why:
                self._odometry_jumped(t, why)
        if not self.poses.add(t, pose.x, pose.y, pose.yaw):
            return
        self._last_odom = (t, pose)
        if self.pub_odom is not None:
            self._publish_corrected(msg, pose)
        for arrived, scan in self._waiting.due():
            self._take(scan, arrived)

    def _odometry_jumped(self, t: float, why: str) -> None:
        self.count("odom_jumps")
        self.last_jump = f"{why}, at {t:.3f} s"
        self.log.warning(f"odometry jump: {self.last_jump}; checking the next scan against the map")
        self.poses.clear()  # no scan is placed on a pose interpolated across the jump
        self._jump_t = t
        self._check = True
        self.publish_status()

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
        if stamp < self._jump_t:
            self._refuse("odom_jump", f"the scan at {stamp:.3f} s is older than the odometry jump")
            return
        try:
            odom = self._waiting.pose_for(self.poses, stamp, msg, arrived, self.now())
        except PoseUnavailable as exc:
            self._refuse(exc.reason, str(exc))
            return
        if odom is None:
            return  # waits for its pose
        beams = Beams(np.asarray(msg.ranges, dtype=np.float32), msg.angle_min, msg.angle_increment, msg.range_min,
                      msg.range_max, sensor=LIDAR_XY)  # fmt: skip
        points = beams.returns()
        pose, m = self.corrector.locate(self.grid, points, odom, self.config.scan_matching)
        if m is not None:
            self.count(f"match.{m.reason or 'ok'}")
            self._publish_tf(msg.header)
        if self._check and not self._agrees(points, pose, stamp):
            return
        try:
            got = self.grid.integrate(beams, pose)
        except ScanRefused as exc:
            self._refuse(exc.reason, str(exc))
            return
        self.count("integrated")
        self.corrector.integrated()
        for kind in self.dropped:
            self.dropped[kind] += getattr(got, kind)
        if got.nan or got.invalid:
            self.last_drop = (f"the scan at {stamp:.3f} s had {got.nan} NaN and {got.invalid} invalid range(s): "
                              f"dropped, the rest used")  # fmt: skip
        self.newest_scan = max(self.newest_scan, stamp)
        self._dirty = True

    def _agrees(self, points: np.ndarray, pose: Pose2D, stamp: float) -> bool:
        """After an odometry jump, and while lost: does this scan fit the map where odometry puts it?"""
        params = self.corrector.params
        score, _, known = (0.0, 0, 0) if self.grid.empty else fit(self.corrector.field(self.grid, pose), points, pose)
        if known < params.min_points or score >= params.min_score:
            if self._lost_since is not None:
                self.count("relocalised")
                self.log.info(f"the scan at {stamp:.3f} s fits the map again (score {score:.2f}): mapping")
            self._check, self._lost_since = False, None
            return True
        if self._lost_since is None:
            self._lost_since = stamp
        lost_s = stamp - self._lost_since
        reset = self.config.lost_reset_s
        if reset > 0 and lost_s >= reset:
            self._reset(f"lost for {lost_s:.1f} s after an odometry jump ({self.last_jump}): a new map")
            return True
        self._refuse("lost", f"after an odometry jump the scan at {stamp:.3f} s does not fit the map (score "
                     f"{score:.2f} on {known} seen cells): not integrated")  # fmt: skip
        return False

    def _reset(self, why: str) -> None:
        self.count("resets")
        self.last_reset = why
        self.log.warning(f"map reset: {why}")
        self.grid = OccupancyMap(self.config.grid_params())
        self.corrector.reset()
        self._check, self._lost_since = False, None
        self.publish_status()

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
    def _publish_corrected(self, msg: Odometry, odom: Pose2D) -> None:
        assert self.pub_odom is not None
        c = self.corrector.correction
        p = c.compose(odom)
        o = msg.pose.pose.orientation  # turned by the correction's yaw: its pitch and roll kept
        q_in = np.array([o.w, o.x, o.y, o.z])
        norm = float(np.linalg.norm(q_in))
        q = quat_mul(yaw_quat(c.yaw), q_in / norm) if norm > 1e-6 else yaw_quat(p.yaw)
        out = Odometry(header=Header(stamp=msg.header.stamp, frame_id=self.config.map_frame),
                       child_frame_id=msg.child_frame_id, twist=msg.twist)  # fmt: skip
        out.pose.pose.position.x, out.pose.pose.position.y = p.x, p.y
        out.pose.pose.position.z = msg.pose.pose.position.z
        out.pose.pose.orientation = Quaternion(x=float(q[1]), y=float(q[2]), z=float(q[3]), w=float(q[0]))
        self.pub_odom.publish(out)

    def _publish_tf(self, scan: Header) -> None:
        assert self.pub_tf is not None
        c = self.corrector.correction
        head = Header(stamp=scan.stamp, frame_id=self.config.map_frame)
        self.pub_tf.publish(TFMessage(transforms=[transform_stamped(head, self.config.odom_frame, (c.x, c.y, 0.0),
                                                                    yaw_quat(c.yaw))]))  # fmt: skip

    def publish_map(self) -> None:
        """/map and /map/costmap, when a scan changed the grid since the last ones."""
        if not self._dirty or self.grid.empty:
            return
        self._dirty = False
        grid = self.grid
        values = grid.values()
        self.pub_map.publish(grid_msg(values, grid.origin, grid.resolution, self.frame, self.newest_scan))
        cost = inflate(values, grid.resolution, self.costmap_params)  # one big message alive at a time
        self.pub_costmap.publish(grid_msg(cost, grid.origin, grid.resolution, self.frame, self.newest_scan))
        self.count("published")

    # -- the map file ------------------------------------------------------------------------
    def map_file(self, req: MemoryFile_Request) -> MemoryFile_Response:
        """save | load | check the map beside the memory file `req.path`; `objects` = occupied cells."""
        try:
            path = map_path(str(req.path))
        except StateFileError as exc:
            return MemoryFile.Response(False, f"refused: {exc}", 0)
        if req.command == "save":
            try:
                n = self.save(path, overwrite=bool(req.overwrite))
            except StateFileError as exc:
                self.publish_status()  # a cap reached shows there
                return MemoryFile.Response(False, f"refused {path}: {exc}", 0)
            except OSError as exc:
                return MemoryFile.Response(False, f"cannot write {path}: {exc.strerror or exc}", 0)
            return MemoryFile.Response(True, f"saved the map ({n} occupied cells) to {path}", n)
        if req.command in ("load", "check"):
            if not path.exists():
                return MemoryFile.Response(True, f"no map file {path}: the map stays as it is", 0)
            try:
                grid = self._read(path)
            except (MapFileError, StateFileError, OSError) as exc:
                return MemoryFile.Response(False, f"refused {path}: {_one_line(exc)}", 0)
            n = grid.counts()["occupied"]
            if req.command == "load":
                self._replace(grid)
                self.log.info(f"loaded the map from {path}")
            return MemoryFile.Response(True, f"{req.command}ed the map ({n} occupied cells) from {path}", n)
        return MemoryFile.Response(False, f"unknown command {str(req.command)[:20]!r}: use save, load or check", 0)

    def _read(self, path: Path) -> OccupancyMap:
        cfg = self.config
        return loads(read_bounded(path, MAX_FILE_BYTES), cfg.world, self.frame, self.grid.params)

    def _replace(self, grid: OccupancyMap) -> None:
        """A whole new map (checked): the correction and any jump check are of the old one."""
        self.grid = grid
        self.corrector.reset()
        self._check, self._lost_since = False, None
        self._dirty = True
        self.publish_map()
        self.publish_status()

    def _load_at_start(self, path: Path) -> None:
        if not path.exists():
            self.log.info(f"no map file {path} yet: starting empty")
            return
        try:
            self.grid = self._read(path)
        except (MapFileError, StateFileError, OSError) as exc:
            raise ConfigError(f"map_file {path}: {_one_line(exc)}") from None
        self._dirty = True

    def save(self, path: Path, overwrite: bool = False) -> int:
        """Write the map to `path` (fsync, then rename; an existing file only with `overwrite`); the
        number of occupied cells written."""
        data = dumps(self.grid, self.config.world, self.frame, self.newest_scan)
        write_atomic(path, data, overwrite=overwrite, quota=self.config.quota())
        return self.grid.counts()["occupied"] if not self.grid.empty else 0

    def close(self) -> None:
        cfg = self.config
        if cfg.save_on_exit and cfg.map_file:
            try:
                path = map_path(cfg.map_file)
                self.save(path, overwrite=True)
                self.log.info(f"saved the map to {path}")
            except (StateFileError, OSError) as exc:
                self.log.error(f"cannot save the map to {path}: {exc}")

    def status(self) -> dict[str, Any]:
        g = self.grid
        rows, cols = g.shape
        c = self.corrector.correction
        return {
            "state": "lost" if self._lost_since is not None else "mapping",
            "frame": self.frame,
            "resolution_m": g.resolution,
            "size_m": [round(cols * g.resolution, 2), round(rows * g.resolution, 2)],
            "origin": [round(v, 3) for v in g.origin],
            "cap_m": g.params.max_size_m,
            "cells": g.counts() if not g.empty else {"occupied": 0, "free": 0, "unknown": 0},
            "scans": self.counters.get("scans", 0),
            "integrated": self.counters.get("integrated", 0),
            "refused": dict(sorted(self.refused.items())),
            "dropped": dict(self.dropped),
            "last_drop": self.last_drop,
            "last_refusal": self.last_refusal,
            "scan_matching": self.config.scan_matching,
            "matches": {k[6:]: v for k, v in sorted(self.counters.items()) if k.startswith("match.")},
            "correction": [round(c.x, 3), round(c.y, 3), round(math.degrees(c.yaw), 2)],
            "odom_jumps": self.counters.get("odom_jumps", 0),
            "last_jump": self.last_jump,
            "resets": self.counters.get("resets", 0),
            "last_reset": self.last_reset,
            "newest_scan": round(self.newest_scan, 3),
            "poses_s": round((self.poses.newest or 0.0) - (self.poses.oldest or 0.0), 2),
            "published": self.counters.get("published", 0),
            "files": self.config.quota().usage(),
            "services": self.service_stats(),
            "refused_inputs": self.input_refusals(),
        }

    def publish_status(self) -> None:
        self.pub_status.publish(String(data=json.dumps(self.status(), ensure_ascii=False)))


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())
