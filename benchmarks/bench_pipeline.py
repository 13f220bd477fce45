"""Seed pipeline benchmark: colour-detector throughput on one core, and end-to-end latency from a
camera frame's stamp to /cmd_vel.

    .venv/bin/python benchmarks/bench_pipeline.py                 # both
    .venv/bin/python benchmarks/bench_pipeline.py --only detector --frames 3000
    .venv/bin/python benchmarks/bench_pipeline.py --only latency --flips 60

Detector: the test pattern (640x480 bgr8) through (a) detect_color on an array and (b) the node's
whole per-frame path (Image message -> array -> detection -> PointStamped), with OpenCV limited to
one thread and the process pinned to one CPU. Reported per CPU-second of the benchmark thread (what
one core delivers, even on a busy machine) and per wall-clock second (what it got here).

Latency: color_detector, follower and safety run as real `go2vlm run` processes on a private DDS
domain on loopback; this process is the camera. It publishes the test pattern and its mirror image
(red circle at x=450, then x=190) in turn, so the commanded turn flips sign with every frame. For
each frame: stamp -> /detected_target received, -> first /follower/cmd_vel with the new sign, ->
first /cmd_vel with the new sign. The follower publishes at 20 Hz and the gate at 50 Hz, so they
add up to 50 ms and 20 ms (one output period each) on top of the processing.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import threading
import time

import numpy as np


def _pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, int(round(q * (len(s) - 1))))]


def bench_detector(frames: int, out: dict[str, object]) -> None:
    import cv2

    from go2vlm.msgs.geometry_msgs import Point, PointStamped
    from go2vlm.msgs.image import numpy_to_image, to_bgr
    from go2vlm.msgs.std_msgs import Header
    from go2vlm.perception.color import PRESETS, detect_color
    from go2vlm.sources.test_pattern_node import draw_pattern

    cv2.setNumThreads(1)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    img = draw_pattern(0)
    msg = numpy_to_image(img, "bgr8", header=Header(frame_id="camera"))
    ranges = PRESETS["red"]

    def node_path() -> None:
        bgr = to_bgr(msg)
        det = detect_color(bgr, ranges)
        assert det is not None
        x, y, z = det.normalized()
        PointStamped(header=Header(stamp=msg.header.stamp, frame_id="camera"), point=Point(x, y, z))

    for name, fn in (("detect_color(array)", lambda: detect_color(img, ranges)), ("node per-frame path", node_path)):
        for _ in range(50):
            fn()
        t0, c0 = time.perf_counter(), time.thread_time()
        for _ in range(frames):
            fn()
        dt = (time.perf_counter() - t0) / frames
        cpu = (time.thread_time() - c0) / frames  # CPU time: robust against other load on the machine
        out[f"detector {name}"] = {"frames_per_cpu_s": 1.0 / cpu, "cpu_ms_per_frame": cpu * 1e3, "wall_fps": 1.0 / dt}
        print(
            f"detector  {name:22s} 640x480, 1 core: {1.0 / cpu:6.0f} frames/CPU-s ({cpu * 1e3:.3f} ms CPU/frame),"
            f" wall {1.0 / dt:6.0f} frames/s"
        )


def bench_latency(flips: int, period_s: float, out: dict[str, object]) -> None:
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(20, 220)))
    os.environ.setdefault("GO2VLM_IFACE", "lo")
    import cv2

    from go2vlm.bus import QOS_DEFAULT, Node
    from go2vlm.msgs.geometry_msgs import PointStamped, Twist
    from go2vlm.msgs.image import numpy_to_image
    from go2vlm.msgs.sensor_msgs import Image
    from go2vlm.sources.test_pattern_node import draw_pattern

    circle_right = draw_pattern(0)  # x = 450: turn right (angular.z < 0)
    circle_left = cv2.flip(circle_right, 1)  # x = 640 - 450 = 190: turn left
    frames = [circle_right, circle_left]

    class Camera(Node):
        name = "bench_camera"

    cam = Camera()
    pub = cam.create_publisher(Image, "/camera/image_raw", QOS_DEFAULT)
    lock = threading.Lock()
    seen: dict[str, list[tuple[float, float]]] = {"target": [], "follower": [], "cmd": []}

    def rec(key: str, sign_of) -> object:
        def cb(msg: object) -> None:
            with lock:
                seen[key].append((time.monotonic(), sign_of(msg)))

        return cb

    cam.create_subscription(PointStamped, "/detected_target", rec("target", lambda m: -np.sign(m.point.x)), QOS_DEFAULT)
    cam.create_subscription(Twist, "/follower/cmd_vel", rec("follower", lambda m: np.sign(m.angular.z)), QOS_DEFAULT)
    cam.create_subscription(Twist, "/cmd_vel", rec("cmd", lambda m: np.sign(m.angular.z)), QOS_DEFAULT)
    cam.start()
    env = dict(os.environ)
    children = [
        subprocess.Popen([sys.executable, "-m", "go2vlm", "run", kind], env=env, stderr=subprocess.DEVNULL)
        for kind in ("safety", "follower", "color_detector")
    ]
    try:
        deadline = time.monotonic() + 30
        while pub.matched == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        for i in range(8):  # warm-up: discovery everywhere, first frames through
            pub.publish(numpy_to_image(frames[i % 2], "bgr8", header=cam.header("camera")))
            time.sleep(period_s)
        results: dict[str, list[float]] = {"target": [], "follower": [], "cmd": []}
        for i in range(flips):
            want = 1.0 if i % 2 else -1.0  # the sign of angular.z this frame must produce
            t_pub = time.monotonic()
            pub.publish(numpy_to_image(frames[i % 2], "bgr8", header=cam.header("camera")))
            time.sleep(period_s)
            with lock:
                for key in results:
                    hit = next((t for t, s in seen[key] if t >= t_pub and s == want), None)
                    if hit is not None:
                        results[key].append(hit - t_pub)
        for key, label in (("target", "/detected_target"), ("follower", "/follower/cmd_vel"), ("cmd", "/cmd_vel")):
            xs = [x * 1e3 for x in results[key]]
            if not xs:
                print(f"latency   stamp -> {label:18s} no samples")
                out[f"latency {label}"] = {"n": 0}
                continue
            out[f"latency {label}"] = {
                "median_ms": statistics.median(xs),
                "p95_ms": _pct(xs, 0.95),
                "max_ms": max(xs),
                "n": len(xs),
            }
            print(
                f"latency   stamp -> {label:18s} median {statistics.median(xs):6.1f} ms  p95 {_pct(xs, 0.95):6.1f} ms"
                f"  max {max(xs):6.1f} ms  (n={len(xs)})"
            )
    finally:
        for c in children:
            c.terminate()
        for c in children:
            c.wait(10)
        cam.shutdown()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", choices=("detector", "latency"), default=None)
    ap.add_argument("--frames", type=int, default=2000, help="detector: frames to time")
    ap.add_argument("--flips", type=int, default=40, help="latency: frames (each flips the turn)")
    ap.add_argument("--period", type=float, default=0.25, help="latency: seconds between frames")
    ap.add_argument("--json", default=None, help="also write the results here")
    args = ap.parse_args()
    out: dict[str, object] = {}
    if args.only in (None, "latency"):
        bench_latency(args.flips, args.period, out)  # before pinning this process to one core
    if args.only in (None, "detector"):
        bench_detector(args.frames, out)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
