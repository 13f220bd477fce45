"""The occupancy map's figures: how far the map and the pose are off after a long walk with a Go2's
odometry drift, with and without scan matching, what a scan costs, and what the map node holds.

    .venv/bin/python benchmarks/bench_map.py --sections walk --walk-m 100          # the drift walk
    .venv/bin/python benchmarks/bench_map.py --sections node --walk-m 100 --cap    # CPU per scan, memory
    .venv/bin/python benchmarks/bench_map.py --sections walk,node --walk-m 10      # a tiny setting
    .venv/bin/python benchmarks/bench_map.py --sections icp --walk-m 100           # with small_gicp installed

walk: a robot walks loops through a world (household by default: both rooms, through the doorway;
0.6 m/s, turning on the spot at 1 rad/s at each corner) until it has walked --walk-m metres. Its
/scan is the sim's, from the same MuJoCo world: the L1 lidar's rays cast with mj_multiRay at the true
pose and turned into ranges by geometry/scan.py (sim/lidar.py, as the sim node does, 10 Hz). Its
odometry is the sim's drift model at --drift (sim/odometry_drift.py; gain 1 is a Go2's leg odometry,
50 Hz). The map's pure core (world/occupancy.py, world/scan_match.py's Corrector: what the map node
does per scan) maps it twice: on the odometry alone, and with scan matching. Reported for each, and
for a map made on the true poses (the reference): the pose error at the end and over the walk
(position and heading, against the truth), and the map error: each occupied cell's distance to the
nearest occupied cell of the reference map (mean, 95th percentile, and the share over 0.1 m).

icp: the walk matched by small_gicp's ICP beside our matcher (CPU per scan, pose error), for the
choice of matcher; small_gicp is not a go2vlm dependency: `pip install small_gicp` first.

node: a map node alone in a process of its own (scan_matching on, real DDS publishers), its callbacks
called directly with the walk's /odom and /scan in their own stamps (sent from this process, which
casts the rays), /map and /map/costmap built every second of them (publish_period_s 1). Reported:
CPU time per scan (the callback: the pose, the match, the integration), the CPU of a /map +
/map/costmap, and the process's resident memory: idle (the node made, nothing mapped: Python, NumPy,
SciPy, cyclonedds), after the walk and its peak. With --cap the map is then grown to its cap (60 x
60 m at 5 cm) and published once more: the worst case.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import statistics
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(110, 200)))
os.environ.setdefault("GO2VLM_IFACE", "lo")

import numpy as np  # noqa: E402

from go2vlm.geometry.rotations import yaw_quat  # noqa: E402
from go2vlm.geometry.scan import cloud_to_ranges, to_base  # noqa: E402
from go2vlm.robot_profile.go2 import GO2  # noqa: E402
from go2vlm.world.map_node import LIDAR_XY  # noqa: E402
from go2vlm.world.occupancy import Beams, OccupancyMap  # noqa: E402
from go2vlm.world.poses import Pose2D, wrap_angle  # noqa: E402
from go2vlm.world.scan_match import Corrector  # noqa: E402

# Loops through both rooms of the household world, clear of the furniture (x, y in m).
ROUTES = {
    "household": [
        (-4.0, -1.2),
        (-1.5, -1.2),
        (-1.0, 0.0),
        (1.2, 0.0),
        (2.5, -1.5),
        (4.0, -1.8),
        (4.0, 0.3),
        (2.0, 0.0),
        (-1.0, 0.0),
        (-2.0, 1.3),
        (-4.0, 1.2),
    ],  # fmt: skip
}
SPEED, TURN_RATE, ODOM_HZ, SCAN_EVERY = 0.6, 1.0, 50.0, 5  # m/s, rad/s, Hz, odometry samples per scan


def walk(route: list[tuple[float, float]], length_m: float) -> Iterator[tuple[float, Pose2D]]:
    """(t, true pose) at ODOM_HZ along the route's loop, facing the way it goes, until length_m walked."""
    dt, t, walked = 1.0 / ODOM_HZ, 0.0, 0.0
    x, y = route[0]
    yaw = math.atan2(route[1][1] - y, route[1][0] - x)
    i = 1
    while walked < length_m:
        gx, gy = route[i % len(route)]
        heading = math.atan2(gy - y, gx - x)
        while abs(wrap_angle(heading - yaw)) > 1e-9:  # turn on the spot
            step = max(-TURN_RATE * dt, min(TURN_RATE * dt, wrap_angle(heading - yaw)))
            yaw = wrap_angle(yaw + step)
            t += dt
            yield t, Pose2D(x, y, yaw)
        while walked < length_m:
            d = math.hypot(gx - x, gy - y)
            if d < 1e-9:
                break
            s = min(SPEED * dt, d)
            x, y = x + s * math.cos(heading), y + s * math.sin(heading)
            walked += s
            t += dt
            yield t, Pose2D(x, y, yaw)
        i += 1


class WorldLidar:
    """The sim's /scan at a pose in a world: the L1 lidar's rays cast in MuJoCo, ranges as the sim makes them."""

    def __init__(self, world: str) -> None:
        import mujoco  # here: the node's own process (section node) must not hold MuJoCo

        from go2vlm.sim.lidar import Lidar
        from go2vlm.sim.worlds import world_model

        self.mj = mujoco
        self.model, _ = world_model(world)
        self.data = mujoco.MjData(self.model)
        base = self.model.body("base")
        self.qadr = int(self.model.jnt_qposadr[base.jntadr[0]])
        self.lidar = Lidar(self.model, base.id)
        self.tf = GO2.lidar_transforms()[GO2.lidar.frame]
        self.spec = GO2.scan_spec()

    def beams(self, pose: Pose2D) -> Beams:
        self.data.qpos[self.qadr : self.qadr + 3] = (pose.x, pose.y, GO2.stand_height)
        self.data.qpos[self.qadr + 3 : self.qadr + 7] = yaw_quat(pose.yaw)
        self.mj.mj_kinematics(self.model, self.data)
        ranges = cloud_to_ranges(to_base(self.lidar.scan(self.data), self.tf), self.spec)
        s = self.spec
        return Beams(ranges, s.angle_min, s.angle_increment, s.range_min, s.range_max, sensor=LIDAR_XY)


def map_error(grid: OccupancyMap, reference: OccupancyMap) -> dict[str, float]:
    """Each occupied cell's distance to the reference's nearest occupied cell (m)."""
    pts = grid.occupied_points()
    ref = reference.values() == 100
    from scipy import ndimage  # here: the node's own process (section node) must not hold SciPy

    d = ndimage.distance_transform_edt(~ref) * reference.resolution
    rows, cols = (np.floor((pts[:, 1] - reference.origin[1]) / reference.resolution).astype(int),
                  np.floor((pts[:, 0] - reference.origin[0]) / reference.resolution).astype(int))  # fmt: skip
    h, w = ref.shape
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    err = np.full(len(pts), 5.0)  # off the reference map altogether: counted as 5 m
    err[inside] = d[rows[inside], cols[inside]]
    return {"occupied_cells": int(len(pts)), "mean_m": round(float(err.mean()), 3), "p95_m": _p95(err),
            "over_0.1m": round(float((err > 0.1).mean()), 3)}  # fmt: skip


def _p95(values: Any) -> float:
    return round(float(np.percentile(values, 95)), 3)


def section_walk(args: argparse.Namespace) -> dict[str, Any]:
    from go2vlm.sim.odometry_drift import OdometryDrift  # go2vlm.sim brings MuJoCo

    lidar = WorldLidar(args.world)
    drift = OdometryDrift(args.drift, seed=args.seed)
    runs = {"reference": (OccupancyMap(), Corrector()), "odometry": (OccupancyMap(), Corrector()),
            "scan_matching": (OccupancyMap(), Corrector())}  # fmt: skip
    errors: dict[str, list[tuple[float, float]]] = {k: [] for k in runs}
    cpu: dict[str, list[float]] = {"integrate_ms": [], "match_ms": []}
    n, truth, walked = 0, Pose2D(0, 0, 0), 0.0
    last = None
    for _, truth in walk(ROUTES[args.world], args.walk_m):
        odom = Pose2D(*drift.update(truth.x, truth.y, truth.yaw))
        if last is not None:
            walked += math.hypot(truth.x - last.x, truth.y - last.y)
        last = truth
        n += 1
        if n % SCAN_EVERY:
            continue
        beams = lidar.beams(truth)
        points = beams.returns()
        for name, (grid, corrector) in runs.items():
            given = truth if name == "reference" else odom
            t0 = time.thread_time()
            pose, _ = corrector.locate(grid, points, given, name == "scan_matching")
            t1 = time.thread_time()
            grid.integrate(beams, pose)
            corrector.integrated()
            t2 = time.thread_time()
            if name == "scan_matching":
                cpu["match_ms"].append((t1 - t0) * 1e3)
                cpu["integrate_ms"].append((t2 - t1) * 1e3)
            errors[name].append((math.hypot(pose.x - truth.x, pose.y - truth.y), abs(wrap_angle(pose.yaw - truth.yaw))))
    out: dict[str, Any] = {"world": args.world, "walked_m": round(walked, 1), "drift_gain": args.drift,
                           "scans": len(errors["odometry"]), "runs": {}}  # fmt: skip
    reference = runs["reference"][0]
    for name, (grid, _) in runs.items():
        pos = [e[0] for e in errors[name]]
        yaw = [math.degrees(e[1]) for e in errors[name]]
        out["runs"][name] = {
            "end_position_error_m": round(pos[-1], 3),
            "end_heading_error_deg": round(yaw[-1], 2),
            "mean_position_error_m": round(statistics.fmean(pos), 3),
            "max_position_error_m": round(max(pos), 3),
            "map": map_error(grid, reference),
        }
    out["cpu_per_scan_ms"] = {k: {"mean": round(statistics.fmean(v), 3), "p95": _p95(v)} for k, v in cpu.items()}
    return out


def section_icp(args: argparse.Namespace) -> dict[str, Any]:
    """The walk matched by small_gicp's point-to-point ICP (against the map's occupied cells within 6 m,
    from the same corrected guess) beside our matcher: what a maintained library would give. Needs
    `pip install small_gicp` (not a go2vlm dependency)."""
    import small_gicp

    from go2vlm.sim.odometry_drift import OdometryDrift

    lidar = WorldLidar(args.world)
    drift = OdometryDrift(args.drift, seed=args.seed)
    grids = {"small_gicp": OccupancyMap(), "ours": OccupancyMap()}
    ours, correction = Corrector(), Pose2D(0.0, 0.0, 0.0)
    cpu: dict[str, list[float]] = {k: [] for k in grids}
    err: dict[str, list[float]] = {k: [] for k in grids}
    for n, (_, truth) in enumerate(walk(ROUTES[args.world], args.walk_m), 1):
        odom = Pose2D(*drift.update(truth.x, truth.y, truth.yaw))
        if n % SCAN_EVERY:
            continue
        beams = lidar.beams(truth)
        points = beams.returns()
        grid = grids["small_gicp"]
        pose = correction.compose(odom)
        t0 = time.thread_time()
        occ = grid.occupied_points() if not grid.empty else np.zeros((0, 2))
        near = occ[np.hypot(occ[:, 0] - pose.x, occ[:, 1] - pose.y) < 6.0]
        if len(near) > 50:
            c, s = math.cos(pose.yaw), math.sin(pose.yaw)
            init = np.array([[c, -s, 0, pose.x], [s, c, 0, pose.y], [0, 0, 1, 0], [0, 0, 0, 1]])
            flat = np.zeros((len(near), 1)), np.zeros((len(points), 1))
            got = small_gicp.align(np.hstack([near, flat[0]]), np.hstack([points, flat[1]]), init_T_target_source=init,
                                   registration_type="ICP", max_correspondence_distance=0.3, num_threads=1)  # fmt: skip
            m = got.T_target_source
            pose = Pose2D(float(m[0, 3]), float(m[1, 3]), math.atan2(m[1, 0], m[0, 0]))
            correction = pose.compose(odom.inverse())
            cpu["small_gicp"].append((time.thread_time() - t0) * 1e3)
        grid.integrate(beams, pose)
        err["small_gicp"].append(math.hypot(pose.x - truth.x, pose.y - truth.y))
        t0 = time.thread_time()
        mine, _ = ours.locate(grids["ours"], points, odom, True)
        cpu["ours"].append((time.thread_time() - t0) * 1e3)
        grids["ours"].integrate(beams, mine)
        ours.integrated()
        err["ours"].append(math.hypot(mine.x - truth.x, mine.y - truth.y))
    return {k: {"cpu_ms": {"mean": round(statistics.fmean(cpu[k]), 3), "p95": _p95(cpu[k])},
                "end_position_error_m": round(err[k][-1], 3), "max_position_error_m": round(max(err[k]), 3),
                "mean_position_error_m": round(statistics.fmean(err[k]), 3)} for k in grids}  # fmt: skip


def _proc_mb(key: str) -> float:
    """VmRSS or VmHWM (the peak) of this process, MB."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) / 1024
    return float("nan")


def _node_child(conn: Any, cap: bool) -> None:
    """The map node alone in a process (no MuJoCo, no benchmark): fed through `conn`, it reports its
    CPU per callback and its memory."""
    from go2vlm.geometry.rotations import yaw_quat
    from go2vlm.launch.registry import make_node
    from go2vlm.msgs.builtin_interfaces import Time
    from go2vlm.msgs.geometry_msgs import Quaternion
    from go2vlm.msgs.nav_msgs import Odometry
    from go2vlm.msgs.sensor_msgs import LaserScan
    from go2vlm.msgs.std_msgs import Header

    node = make_node("map", params={"scan_matching": True})
    idle = _proc_mb("VmRSS")
    scan_ms: list[float] = []
    publish_ms: list[float] = []
    next_pub = 1.0
    while True:
        item = conn.recv()
        if item is None:
            break
        t, (x, y, yaw), beams = item
        q = yaw_quat(yaw)
        odom = Odometry(header=Header(stamp=Time.from_sec(t), frame_id="odom"), child_frame_id="base_link")
        odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
        odom.pose.pose.orientation = Quaternion(x=0.0, y=0.0, z=float(q[3]), w=float(q[0]))
        node.on_odom(odom)
        if beams is None:
            continue
        angle_min, inc, rmin, rmax, ranges = beams
        scan = LaserScan(header=Header(stamp=Time.from_sec(t), frame_id="base_link"), angle_min=angle_min,
                         angle_max=angle_min + (len(ranges) - 1) * inc, angle_increment=inc, range_min=rmin,
                         range_max=rmax, ranges=ranges)  # fmt: skip
        t0 = time.thread_time()
        node.on_scan(scan)
        scan_ms.append((time.thread_time() - t0) * 1e3)
        if t >= next_pub:
            next_pub += 1.0
            t0 = time.thread_time()
            node.publish_map()
            publish_ms.append((time.thread_time() - t0) * 1e3)
    status = node.status()
    out: dict[str, Any] = {
        "scans": len(scan_ms),
        "scan_cpu_ms": {"mean": round(statistics.fmean(scan_ms), 3), "p95": _p95(scan_ms)},
        "publish_cpu_ms": {"mean": round(statistics.fmean(publish_ms), 2), "max": round(max(publish_ms), 2)},
        "map_m": status["size_m"],
        "matches": status["matches"],
        "rss_mb": {"idle": round(idle, 1), "after": round(_proc_mb("VmRSS"), 1), "peak": round(_proc_mb("VmHWM"), 1)},
    }  # fmt: skip
    if cap:  # grown to its cap: rings of returns across the whole 60 x 60 m, then one publish
        grid = node.grid
        ring = Beams(np.full(180, 3.0, np.float32), -math.pi, 2 * math.pi / 180, 0.05, 10.0)
        half = grid.params.max_size_m / 2 - 4.0
        for gx in np.linspace(-half, half, 6):
            for gy in np.linspace(-half, half, 6):
                grid.integrate(ring, Pose2D(float(gx), float(gy), 0.0))
        node._dirty = True
        t0 = time.thread_time()
        node.publish_map()
        rss = {"after": round(_proc_mb("VmRSS"), 1), "peak": round(_proc_mb("VmHWM"), 1)}
        out["cap"] = {"map_m": [round(v * grid.resolution, 1) for v in grid.shape[::-1]],
                      "publish_cpu_ms": round((time.thread_time() - t0) * 1e3, 1), "rss_mb": rss}  # fmt: skip
    node.close()
    conn.send(out)


def section_node(args: argparse.Namespace) -> dict[str, Any]:
    import multiprocessing as mp

    from go2vlm.sim.odometry_drift import OdometryDrift

    lidar = WorldLidar(args.world)
    drift = OdometryDrift(args.drift, seed=args.seed)
    ctx = mp.get_context("spawn")
    ours, theirs = ctx.Pipe()
    child = ctx.Process(target=_node_child, args=(theirs, args.cap))
    child.start()
    for n, (t, truth) in enumerate(walk(ROUTES[args.world], args.walk_m), 1):
        beams = None
        if n % SCAN_EVERY == 0:
            b = lidar.beams(truth)
            beams = (b.angle_min, b.angle_increment, b.range_min, b.range_max, b.ranges.tolist())
        ours.send((t, drift.update(truth.x, truth.y, truth.yaw), beams))
    ours.send(None)
    out: dict[str, Any] = {"world": args.world, **ours.recv()}
    child.join(60)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sections", default="walk,node")
    ap.add_argument("--world", default="household", choices=sorted(ROUTES))
    ap.add_argument("--walk-m", type=float, default=100.0)
    ap.add_argument("--drift", type=float, default=1.0, help="the sim's odometry drift gain (1: a Go2's)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cap", action="store_true", help="node: grow the map to its cap and publish it")
    ap.add_argument("--json", "--out", dest="out", type=Path, default=None, help="write the figures as JSON here")
    args = ap.parse_args()
    results: dict[str, Any] = {"machine": {"cpus": os.cpu_count(), "load": os.getloadavg()}, "args": vars(args)}
    for name in args.sections.split(","):
        results[name] = {"walk": section_walk, "node": section_node, "icp": section_icp}[name](args)
        print(json.dumps({name: results[name]}, indent=1), flush=True)
    if args.out is not None:
        args.out.write_text(json.dumps(results, indent=1, default=str) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
