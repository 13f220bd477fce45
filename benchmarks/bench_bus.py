"""Bus benchmark: a 640x480 bgr8 sensor_msgs/Image between two processes on loopback.

    python benchmarks/bench_bus.py                      # 10 Hz, 30 Hz, max rate; ours vs naive
    python benchmarks/bench_bus.py --duration 5 --cases 30,max --types ours

Latency is header.stamp (set just before publish) to the subscription callback, both on this
machine's clock. Reliable, volatile, keep-last 10 (QOS_DEFAULT), through the go2vlm Node runtime on
both sides. "naive" declares Image.data as `sequence[byte]` (what a straight IDL translation gives)
instead of `bytes`: the declaration in tests/bus/bus_naive_types.py, whose wire type the bus tests
check against ours.
"""

import argparse
import json
import os
import random
import resource
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

from go2vlm.msgs.sensor_msgs import Image

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "bus"))
from bus_naive_types import NaiveImage  # noqa: E402

W, H = 640, 480
FRAME_BYTES = W * H * 3
TOPIC = "/bench/image_raw"


# "small": a 4x4 image through the same path, the floor of wake-up and scheduling latency.
TYPES = {"ours": Image, "naive": NaiveImage, "small": Image}


def size(kind: str) -> tuple[int, int]:
    return (4, 4) if kind == "small" else (W, H)


def frame(kind: str) -> object:
    w, h = size(kind)
    data = np.random.default_rng(0).integers(0, 255, w * h * 3, dtype=np.uint8).tobytes()
    cls = TYPES[kind]
    return cls(height=h, width=w, encoding="bgr8", step=w * 3, data=list(data) if kind == "naive" else data)


def cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def serialization(kind: str, n: int) -> dict[str, float]:
    msg = frame(kind)
    cls = TYPES[kind]
    raw = msg.serialize()
    t0 = time.perf_counter()
    for _ in range(n):
        msg.serialize()
    t1 = time.perf_counter()
    for _ in range(n):
        cls.deserialize(raw)
    t2 = time.perf_counter()
    return {"serialize_ms": (t1 - t0) / n * 1e3, "deserialize_ms": (t2 - t1) / n * 1e3}


def role_pub(args: argparse.Namespace) -> None:
    from go2vlm.bus import QOS_DEFAULT, Node

    node = Node(node_name="bench_pub")
    pub = node.create_publisher(TYPES[args.type], TOPIC, QOS_DEFAULT)
    msg = frame(args.type)
    deadline = time.monotonic() + 10
    while pub.matched == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.3)
    period = 1.0 / args.rate if args.rate > 0 else 0.0
    sent = 0
    start = time.monotonic()
    cpu0 = cpu_s()
    next_t = start
    while time.monotonic() - start < args.duration:
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(time.time_ns(), 1_000_000_000)
        pub.publish(msg)
        sent += 1
        if period:
            next_t += period
            time.sleep(max(0.0, next_t - time.monotonic()))
    elapsed = time.monotonic() - start
    cpu = cpu_s() - cpu0
    time.sleep(0.5)
    print(json.dumps({"sent": sent, "send_rate": sent / elapsed, "pub_cpu_ms": cpu / max(sent, 1) * 1e3}), flush=True)
    node.shutdown()


def run_case(kind: str, rate: float, duration: float) -> dict[str, object]:
    from go2vlm.bus import QOS_DEFAULT, Node

    node = Node(node_name=f"bench_sub_{kind}_{int(rate)}")
    lat: list[float] = []
    recv: list[float] = []
    lock = threading.Lock()

    def on_image(msg: object) -> None:
        now = time.time_ns()
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec  # type: ignore[attr-defined]
        with lock:
            lat.append((now - stamp) / 1e6)
            recv.append(time.monotonic())

    node.create_subscription(TYPES[kind], TOPIC, on_image, QOS_DEFAULT)
    node.start()
    cpu0 = cpu_s()
    cmd = [sys.executable, __file__, "--role", "pub", "--type", kind, "--rate", str(rate), "--duration", str(duration)]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=duration + 60, env=dict(os.environ))
    cpu = cpu_s() - cpu0
    node.shutdown()
    if out.returncode != 0:
        raise RuntimeError(f"publisher failed: {out.stderr[-2000:]}")
    pub_stats = json.loads(out.stdout.strip().splitlines()[-1])
    with lock:
        lat_ms, times = lat[5:], recv[5:]  # skip the warm-up
    if len(times) < 2:
        return {"type": kind, "rate": rate, "received": len(lat), **pub_stats}
    span = times[-1] - times[0]
    got = (len(times) - 1) / span
    q = statistics.quantiles(lat_ms, n=100)
    w, h = size(kind)
    return {
        "type": kind,
        "target_hz": rate if rate > 0 else "max",
        "sent": pub_stats["sent"],
        "received": len(lat),
        "achieved_hz": round(got, 1),
        "MB_per_s": round(got * w * h * 3 / 1e6, 1),
        "median_ms": round(statistics.median(lat_ms), 2),
        "p99_ms": round(q[98], 2),
        "max_ms": round(max(lat_ms), 2),
        "pub_cpu_ms_per_frame": round(pub_stats["pub_cpu_ms"], 2),
        "sub_cpu_ms_per_frame": round(cpu / max(len(lat), 1) * 1e3, 2),
        "load_avg_1min": os.getloadavg()[0],
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--role", choices=["main", "pub"], default="main")
    p.add_argument("--type", choices=list(TYPES), default="ours")
    p.add_argument("--types", default="ours,naive", help="comma list: ours, naive, small")
    p.add_argument("--rate", type=float, default=30.0, help="(pub role) Hz, 0 = as fast as possible")
    p.add_argument("--cases", default="10,30,max", help="comma list of rates in Hz, or max")
    p.add_argument("--duration", type=float, default=5.0, help="seconds per case")
    p.add_argument("--ser-n", type=int, default=20, help="frames for the serialization timing")
    p.add_argument("--json", default=None, help="also write every result line here (a JSON list)")
    args = p.parse_args()
    rows: list[dict[str, object]] = []

    def emit(row: dict[str, object]) -> None:
        rows.append(row)
        print(json.dumps(row), flush=True)

    if args.role == "pub":
        role_pub(args)
        return 0
    # A private domain on loopback unless the caller chose one.
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 200)))
    os.environ.setdefault("GO2VLM_IFACE", "lo")
    if args.ser_n > 0:
        print(
            f"# {W}x{H} bgr8 ({FRAME_BYTES} B), domain {os.environ['ROS_DOMAIN_ID']}, "
            f"iface {os.environ['GO2VLM_IFACE']}, {os.cpu_count()} CPUs, python {sys.version.split()[0]}"
        )
    kinds = [k.strip() for k in args.types.split(",") if k.strip()]
    for kind in [k for k in kinds if k != "small" and args.ser_n > 0]:
        s = serialization(kind, args.ser_n if kind == "ours" else max(3, args.ser_n // 5))
        emit({"type": kind, **{k: round(v, 3) for k, v in s.items()}})
    if len(kinds) > 1:
        # One receiving process per type: "ours" and "naive" share a DDS type name, and a process
        # keeps one Topic (one Python class) per name.
        for kind in kinds:
            cmd = [
                sys.executable,
                __file__,
                "--types",
                kind,
                "--cases",
                args.cases,
                "--duration",
                str(args.duration),
                "--ser-n",
                "0",
            ]
            child = subprocess.run(cmd, check=True, env=dict(os.environ), stdout=subprocess.PIPE, text=True)
            for line in child.stdout.splitlines():
                if line.startswith("{"):
                    emit(json.loads(line))
                else:
                    print(line, flush=True)
    else:
        for case in args.cases.split(","):
            rate = 0.0 if case.strip() == "max" else float(case)
            emit(run_case(kinds[0], rate, args.duration))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
