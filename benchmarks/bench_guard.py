"""Collision guard benchmark: its cost per command, its reaction time over DDS, and where the real
sim stops when teleop drives it at a wall.

    ROS_DOMAIN_ID=157 GO2VLM_IFACE=lo nice -n 5 .venv/bin/python benchmarks/bench_guard.py
    .venv/bin/python benchmarks/bench_guard.py --skip-sim          # only the first two parts

1. `CollisionGuard.limit` on a 180-beam scan with a wall, per call (pure, in this process).
2. Reaction: a gate (in this process, real DDS on loopback) passes teleop at 0.5 m/s over clear scans;
   then one scan shows a wall 0.4 m ahead of the footprint. Time from that scan's publish to the first
   /cmd_vel below 0.5 m/s (it includes waiting for the gate's next 50 Hz tick).
3. Stopping distance: the sim (obstacles world, dynamic trot, real time) and the gate as processes;
   teleop at 0.5 and 1.0 m/s at wall_east, and 0.5 m/s sideways at wall_north, for 8 s; the
   footprint's gap to the wall at the end, from the sim's ground truth (margin 0.3 m).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import statistics
import sys
import threading
import time
from pathlib import Path

os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(110, 200)))
os.environ.setdefault("GO2VLM_IFACE", "lo")

from go2vlm.bus import QOS_DEFAULT, QOS_SENSOR, Node, running  # noqa: E402
from go2vlm.launch.registry import make_node  # noqa: E402
from go2vlm.msgs.geometry_msgs import Twist, Vector3  # noqa: E402
from go2vlm.msgs.sensor_msgs import LaserScan  # noqa: E402
from go2vlm.msgs.std_msgs import Header  # noqa: E402
from go2vlm.safety.guard import CollisionGuard, GuardConfig, Scan  # noqa: E402
from go2vlm.safety.limits import Limits, Velocity  # noqa: E402

BINS = 180
INC = 2 * math.pi / BINS


def wall_ranges(x: float) -> list[float]:
    """A wall across the robot's path at x (m from the base), as scan ranges."""
    out = []
    for i in range(BINS):
        a = -math.pi + i * INC
        c = math.cos(a)
        out.append(x / c if c > 0.2 and abs(x / c * math.sin(a)) < 3.0 else math.inf)
    return out


def bench_pure() -> list[dict[str, float]]:
    guard, lim = CollisionGuard(GuardConfig()), Limits(1.0, 1.0, 1.0, 2.0, 1.0, 3.0)
    rows = []
    guard.scan(Scan("base_link", wall_ranges(1.2), -math.pi, INC, 0.05, 10.0), 0.0)
    for v in (Velocity(0.5), Velocity(1.0), Velocity(0.0, 0.5), Velocity(0.0, 0.0, 1.0), Velocity(0.5, 0.0, 0.5)):
        n, t0 = 2000, time.perf_counter()
        for _ in range(n):
            out = guard.limit(v, 0.0, lim)
        us = (time.perf_counter() - t0) / n * 1e6
        print(f"limit({v.vx:g}, {v.vy:g}, {v.wz:g}) -> ({out.vx:.3f}, {out.vy:.3f}, {out.wz:.3f}): {us:.0f} us/call")
        rows.append({"vx": v.vx, "vy": v.vy, "wz": v.wz, "us_per_call": us})
    return rows


class _Io(Node):
    name = "guard_bench"


def bench_reaction(trials: int) -> dict[str, float]:
    gate = make_node("safety")
    io = _Io()
    got: list[tuple[float, float]] = []
    lock = threading.Lock()

    def on_cmd(m: Twist) -> None:
        with lock:
            got.append((time.perf_counter(), m.linear.x))

    io.create_subscription(Twist, "/cmd_vel", on_cmd, QOS_DEFAULT)
    scan_pub = io.create_publisher(LaserScan, "/scan", QOS_SENSOR)
    teleop = io.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)

    def scan(ranges: list[float]) -> None:
        scan_pub.publish(
            LaserScan(
                header=Header(frame_id="base_link"),
                angle_min=-math.pi,
                angle_max=math.pi - INC,
                angle_increment=INC,
                range_min=0.05,
                range_max=10.0,
                ranges=ranges,
            )  # fmt: skip
        )

    clear, wall = [math.inf] * BINS, wall_ranges(0.35 + 0.4)
    out = []
    with running(gate, io):
        for _ in range(trials):
            end = time.monotonic() + 1.5
            while time.monotonic() < end:  # clear scans, teleop at 0.5: full speed
                scan(clear)
                teleop.publish(Twist(linear=Vector3(x=0.5)))
                time.sleep(0.05)
            with lock:
                assert got and got[-1][1] == 0.5, got[-3:]
            t0 = time.perf_counter()
            scan(wall)
            teleop.publish(Twist(linear=Vector3(x=0.5)))
            deadline = time.monotonic() + 1.0
            hit = None
            while hit is None and time.monotonic() < deadline:
                with lock:
                    hit = next((t for t, x in got if t > t0 and x < 0.5), None)
                time.sleep(0.001)
            if hit is not None:
                out.append((hit - t0) * 1e3)
            time.sleep(0.6)  # let the wall scan go stale before the next trial (blind, then clear again)
    print(
        f"reaction (scan publish -> first slowed /cmd_vel), {len(out)}/{trials} trials: median "
        f"{statistics.median(out):.1f} ms, max {max(out):.1f} ms"
    )
    return {"trials": trials, "reacted": len(out), "median_ms": statistics.median(out), "max_ms": max(out)}


def bench_sim() -> list[dict[str, float | str]]:
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from busutil import Procs, wait_for  # noqa: PLC0415

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "safety"))
    from test_safety_guard_sim import WALL_EAST, WALL_NORTH, Probe, drive  # noqa: PLC0415

    cases = [
        ("forward 0.5 m/s", "[3.0, 1.5, 0.0]", 0.5, Twist(linear=Vector3(x=0.5)), WALL_EAST),
        ("forward 1.0 m/s", "[3.0, 1.5, 0.0]", 1.0, Twist(linear=Vector3(x=1.0)), WALL_EAST),
        ("sideways 0.5 m/s", "[1.5, 3.6, 0.0]", 0.5, Twist(linear=Vector3(y=0.5)), WALL_NORTH),
    ]
    rows: list[dict[str, float | str]] = []
    for name, spawn, vmax, twist, wall in cases:
        procs, probe = Procs(), Probe().start()
        try:
            procs.start("run", "sim", "--param", "world=obstacles", "--param", f"spawn={spawn}",
                        "--param", "camera=false", "--param", "world_camera=false")  # fmt: skip
            procs.start("run", "safety", "--param", f"max_vx_forward={vmax}")
            assert wait_for(lambda p=probe: len(p.gt) and len(p.scan) and len(p.status), 90)
            gap0 = probe.gap(wall)
            drive(probe, twist, 8.0)
            gaps = [probe.gap(wall)]
            print(f"{name}: start gap {gap0:.2f} m, stopped at {gaps[0]:.3f} m from the wall (margin 0.3)")
            rows.append({"case": name, "start_gap_m": gap0, "end_gap_m": gaps[0]})
        finally:
            probe.shutdown()
            procs.stop_all()
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=10)
    ap.add_argument("--skip-sim", action="store_true")
    ap.add_argument("--json", type=Path, default=None, help="also write the results here")
    a = ap.parse_args()
    out = {"limit": bench_pure(), "reaction": bench_reaction(a.trials), "sim": [] if a.skip_sim else bench_sim()}
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
