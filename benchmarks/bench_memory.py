"""The object memory's figures: its cost per answer and its memory after an hour of answers, and how
right it is after a 360-degree look.

    .venv/bin/python benchmarks/bench_memory.py --sections cost --hours 1
    .venv/bin/python benchmarks/bench_memory.py --sections accuracy --episodes 6 [--latency 5]

cost: an object_memory node in this process (real DDS publishers, /objects after every answer:
publish_period_s 0), its callbacks called directly with an hour of a turning robot's input, in its own
stamps: /odom at 50 Hz, /scan at 10 Hz, 640x480 camera frames at 10 Hz (the colour check keeps them
small), and one answer per frame (every object in view, labelled with its colour: the colour check
runs on every box). Reported: CPU time per answer (the callback, placement, fusion, colour check and
the /objects it publishes), and the Python memory the node holds (tracemalloc) after 1 min, 10 min and
the whole run.

accuracy: episodes in vision_test and distractors (the goals and distractors suites' seeded spawns),
the goal "look for the yellow ball" (there is none: the robot searches one whole turn, 13.5 s at 0.5
rad/s), grounded by the sim's ground truth (the oracle graph, its answers at once, or --latency L: the
same answers L sim seconds late through answer_delay); then the memory against the ground truth
(metrics.json's `memory`): every object within 0.3 m, no phantom. Kinematic, --fast, sim time.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import random
import statistics
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(110, 200)))
os.environ.setdefault("GO2VLM_IFACE", "lo")

import numpy as np  # noqa: E402

from go2vlm.geometry.rotations import yaw_quat  # noqa: E402
from go2vlm.msgs.builtin_interfaces import Time  # noqa: E402
from go2vlm.msgs.geometry_msgs import Quaternion  # noqa: E402
from go2vlm.msgs.image import camera_info, numpy_to_image  # noqa: E402
from go2vlm.msgs.nav_msgs import Odometry  # noqa: E402
from go2vlm.msgs.sensor_msgs import LaserScan  # noqa: E402
from go2vlm.msgs.std_msgs import Header  # noqa: E402
from go2vlm.msgs.vision_msgs import detection_array  # noqa: E402
from go2vlm.world.poses import Pose2D  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: testing_support/ (dev-only)
from testing_support.world_views import CAM, cylinder_box, cylinder_scan  # noqa: E402

# Three cylinders round the robot (the colour check needs their colours in the frames).
OBJECTS = {"red cylinder": ((3.0, 0.5), (0, 0, 230)), "green cylinder": ((-1.0, 3.0), (0, 200, 0)),
           "blue cylinder": ((-2.5, -2.0), (230, 0, 0))}  # fmt: skip
R, H = 0.3, 1.0


def _stamp(t: float) -> Header:
    return Header(stamp=Time.from_sec(t), frame_id="odom")


def _scan(pose: Pose2D) -> LaserScan:
    pts = np.concatenate([cylinder_scan(pose, xy, R) for xy, _ in OBJECTS.values()])
    ranges = [math.inf] * 180
    for x, y in pts:
        k = int(round((math.atan2(y, x) + math.pi) / (2 * math.pi / 180))) % 180
        ranges[k] = min(ranges[k], math.hypot(x, y))
    return LaserScan(angle_min=-math.pi, angle_increment=2 * math.pi / 180, range_min=0.05, range_max=10.0,
                     ranges=ranges)  # fmt: skip


def bench_cost(hours: float) -> dict[str, Any]:
    from go2vlm.launch.registry import make_node

    node = make_node("object_memory", params={"publish_period_s": 0.0})
    node.on_camera_info(camera_info(CAM))
    tracemalloc.start()
    per_answer: list[float] = []
    marks: dict[str, float] = {}
    wz, t, dt = 0.5, 1000.0, 0.02
    n = int(hours * 3600 / dt)
    cpu0 = time.process_time()
    for k in range(n):
        t += dt
        pose = Pose2D(0.0, 0.0, wz * (t - 1000.0))
        odom = Odometry(header=_stamp(t), child_frame_id="base_link")
        q = yaw_quat(pose.yaw)
        odom.pose.pose.orientation = Quaternion(x=0.0, y=0.0, z=float(q[3]), w=float(q[0]))
        node.on_odom(odom)
        if k % 5:
            continue
        scan = _scan(pose)
        scan.header = Header(stamp=Time.from_sec(t), frame_id="base_link")
        node.on_scan(scan)
        img = np.full((480, 640, 3), 150, np.uint8)
        boxes = []
        for label, (xy, bgr) in OBJECTS.items():
            box = cylinder_box(pose, xy, R, H)
            if box is not None:
                x1, y1, x2, y2 = (int(v) for v in box)
                img[y1:y2, x1:x2] = bgr
                boxes.append((label, box, 1.0))
        node.on_image(numpy_to_image(img, "bgr8", Header(stamp=Time.from_sec(t), frame_id="camera_optical_frame")))
        answer = detection_array(Header(stamp=Time.from_sec(t), frame_id="camera_optical_frame"), boxes)
        c0 = time.process_time()
        node.on_answers(answer)
        per_answer.append(time.process_time() - c0)
        for mark, secs in (("1 min", 60), ("10 min", 600)):
            if mark not in marks and t - 1000.0 >= secs:
                marks[mark] = tracemalloc.get_traced_memory()[0]
    marks[f"{hours:g} h"] = tracemalloc.get_traced_memory()[0]
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    cpu = time.process_time() - cpu0
    objs = node.memory.snapshot()
    node.shutdown()
    ms = sorted(1000 * v for v in per_answer)
    return {
        "answers": len(per_answer),
        "per_answer_ms": {
            "p50": round(statistics.median(ms), 3),
            "p95": round(ms[int(0.95 * len(ms))], 3),
            "max": round(ms[-1], 3),
        },  # fmt: skip
        "traced_memory_kib": {k: round(v / 1024) for k, v in marks.items()},
        "traced_peak_kib": round(peak / 1024),
        "cpu_s": round(cpu, 1),
        "objects": [(o.label, round(o.x, 3), round(o.y, 3), round(o.confidence, 3), o.seen) for o in objs],
        "counters": dict(node.counters),
    }


def bench_accuracy(episodes: int, latency: float) -> list[dict[str, Any]]:
    from go2vlm.apps.episodes import RunOptions, run_episode
    from go2vlm.apps.episodes.suites import load_suite
    from go2vlm.bus import ShutdownRequested

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_vlm_latency import GRAPH

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        graph = Path(tmp) / "delayed.yaml"
        graph.write_text(GRAPH)
        for suite in ("goals", "distractors"):
            s = load_suite(suite)
            for k in range(episodes):
                ep = s.episode(k, "oracle")
                params = {"commander": {"search_timeout_s": 13.5}}
                if latency > 0:
                    params["answer_delay"] = {"latency_s": latency}
                ep = dataclasses.replace(ep, goal="look for the yellow ball", params=params,
                                         graph=str(graph) if latency > 0 else None,
                                         duration_s=40.0 + 20.0 * latency)  # fmt: skip
                m = run_episode(ep, RunOptions(fast=True, video=False), ShutdownRequested()).metrics
                mem = m["memory"] or {"objects": [], "phantoms": None, "max_error_m": None}
                row = {"world": ep.world, "spawn": ep.spawn, "final_state": m["final_state"],
                       "objects": [(o["label"], o["error_m"], o["confidence"]) for o in mem["objects"]],
                       "phantoms": mem["phantoms"], "max_error_m": mem["max_error_m"]}  # fmt: skip
                rows.append(row)
                print(json.dumps(row), file=sys.stderr, flush=True)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sections", default="cost,accuracy")
    ap.add_argument("--hours", type=float, default=1.0, help="cost: hours of answers")
    ap.add_argument("--episodes", type=int, default=6, help="accuracy: spawns per world")
    ap.add_argument("--latency", type=float, default=0.0, help="accuracy: answers this many sim seconds late")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    out: dict[str, Any] = {}
    if "cost" in args.sections:
        out["cost"] = bench_cost(args.hours)
        print(json.dumps(out["cost"], indent=1))
    if "accuracy" in args.sections:
        rows = bench_accuracy(args.episodes, args.latency)
        out["accuracy"] = rows
        for world in ("vision_test", "distractors"):
            rs = [r for r in rows if r["world"] == world]
            errs = [e for r in rs for _, e, _ in r["objects"] if e is not None]
            print(
                f"{world}: {len(rs)} looks, objects remembered {sum(len(r['objects']) for r in rs)}, "
                f"max error {max(errs, default=float('nan')):.3f} m, phantoms {sum(r['phantoms'] or 0 for r in rs)}"
            )
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
