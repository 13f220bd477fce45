"""Record and view benchmark: what `go2vlm record` and `go2vlm view` cost on top of the bus.

    python benchmarks/bench_record_view.py                         # 20 s per case, camera 30 Hz
    python benchmarks/bench_record_view.py --duration 10 --cases plain,record,view

A publisher process plays the demo's topics with synthetic content at the demo's rates: a 640x480
bgr8 camera (QOS_IMAGE) at --camera-hz, its camera_info, /odom, /imu, /joint_states, /tf, /clock
and /cmd_vel at 50 Hz, /sim/ground_truth and /follower/cmd_vel at 20 Hz, /detected_target with
every frame, /safety/status at 1 Hz, /sim/status at 2 Hz. One consumer process per case, its CPU
(user + system, /proc) measured while the publisher publishes:

  plain   a go2vlm Node that subscribes to every topic and takes the serialized samples (the bus cost)
  record  `go2vlm record -a` into a temporary folder; afterwards the bag's counts are compared with
          what the publisher sent (dropped = sent - recorded)
  view    `go2vlm view` with a Foxglove WebSocket client (this process) subscribed to the JPEG
          camera (at most 10 Hz), /tf, /odom, /cmd_vel, /detected_target and its annotations,
          /safety/status and the robot box
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import random
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

TICK = os.sysconf("SC_CLK_TCK")
W, H = 640, 480


def topics(camera_hz: float) -> list[tuple[str, str, str, float]]:
    """(topic, type, qos, Hz) of the demo."""
    return [
        ("/camera/image_raw", "sensor_msgs/msg/Image", "image", camera_hz),
        ("/camera/camera_info", "sensor_msgs/msg/CameraInfo", "latched", camera_hz),
        ("/detected_target", "geometry_msgs/msg/PointStamped", "default", camera_hz),
        ("/odom", "nav_msgs/msg/Odometry", "default", 50.0),
        ("/imu", "sensor_msgs/msg/Imu", "default", 50.0),
        ("/joint_states", "sensor_msgs/msg/JointState", "default", 50.0),
        ("/tf", "tf2_msgs/msg/TFMessage", "default", 50.0),
        ("/clock", "rosgraph_msgs/msg/Clock", "default", 50.0),
        ("/cmd_vel", "geometry_msgs/msg/Twist", "default", 50.0),
        ("/sim/ground_truth", "tf2_msgs/msg/TFMessage", "default", 20.0),
        ("/follower/cmd_vel", "geometry_msgs/msg/Twist", "default", 20.0),
        ("/safety/status", "std_msgs/msg/String", "latched", 1.0),
        ("/sim/status", "std_msgs/msg/String", "latched", 2.0),
    ]


def qos(name: str) -> Any:
    from go2vlm.bus import QOS_DEFAULT, QOS_IMAGE, QOS_LATCHED

    return {"image": QOS_IMAGE, "latched": QOS_LATCHED, "default": QOS_DEFAULT}[name]


def sample(type_name: str, i: int) -> Any:
    import numpy as np

    from go2vlm.msgs import get_type
    from go2vlm.msgs.geometry_msgs import TransformStamped

    cls = get_type(type_name)
    msg = cls()
    if type_name.endswith("/Image"):
        data = np.random.default_rng(i % 8).integers(0, 255, W * H * 3, dtype=np.uint8).tobytes()
        msg = cls(height=H, width=W, encoding="bgr8", step=W * 3, data=data)
    elif type_name.endswith("/CameraInfo"):
        msg.width, msg.height = W, H
    elif type_name.endswith("/JointState"):
        msg.name = [f"joint_{j}" for j in range(12)]
        msg.position = msg.velocity = msg.effort = [0.1 * j for j in range(12)]
    elif type_name.endswith("/TFMessage"):
        msg.transforms = [TransformStamped(child_frame_id="base_link") for _ in range(3)]
    elif type_name.endswith("/String"):
        msg.data = json.dumps({"i": i, "estop": False, "pad": "x" * 300})
    elif type_name.endswith("/PointStamped"):
        msg.point.x, msg.point.z = 0.1, 0.2
    return msg


def role_pub(args: argparse.Namespace) -> None:
    """Publish the demo's topics; wait for the consumer first; print the sent counts."""
    from go2vlm.bus import Node
    from go2vlm.msgs import get_type

    node = Node(node_name="bench_demo_pub")
    plan = []
    for topic, type_name, q, hz in topics(args.camera_hz):
        pub = node.create_publisher(get_type(type_name), topic, qos(q))
        plan.append([pub, sample(type_name, 0), 1.0 / hz, 0.0, type_name])
    deadline = time.monotonic() + 30
    while plan[0][0].matched == 0 and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(1.5)  # the consumer subscribes to the other topics too
    print("start", flush=True)
    start = time.monotonic()
    for p in plan:
        p[3] = start
    sent = {p[0].topic: 0 for p in plan}
    while (now := time.monotonic()) - start < args.duration:
        for p in plan:
            pub, msg, period, due, type_name = p
            if now >= due:
                if hasattr(msg, "header"):
                    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(time.time_ns(), 1_000_000_000)
                pub.publish(msg)
                sent[pub.topic] += 1
                p[3] = due + period
        time.sleep(max(0.0, min(p[3] for p in plan) - time.monotonic()))
    print("done", flush=True)
    time.sleep(1.0)
    print(json.dumps(sent), flush=True)
    node.shutdown()


def role_sub(args: argparse.Namespace) -> None:
    """The bus alone: every topic subscribed, samples taken, nothing else."""
    from go2vlm.bus import Node, QosProfile, running
    from go2vlm.msgs import get_type

    node = Node(node_name="bench_plain_sub")
    got = {"n": 0}

    def count(_s: Any) -> None:
        got["n"] += 1

    for topic, type_name, q, _hz in topics(args.camera_hz):
        p = qos(q)
        node.create_raw_subscription(get_type(type_name), topic, count, QosProfile(p.reliable, p.transient_local, 500))
    with running(node):
        print("ready", flush=True)
        sys.stdin.readline()
    print(json.dumps({"received": got["n"]}), flush=True)


def cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def start(cmd: list[str], **kw: Any) -> subprocess.Popen[str]:
    return subprocess.Popen(cmd, text=True, env=dict(os.environ), **kw)


def wait_line(proc: subprocess.Popen[str], pattern: str, stream: Any, timeout: float = 60) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = stream.readline()
        if not line and proc.poll() is not None:
            break
        if re.search(pattern, line):
            return line
    raise RuntimeError(f"no line matching {pattern!r}")


def measure(consumer: subprocess.Popen[str], args: argparse.Namespace) -> tuple[float, float, dict[str, int]]:
    """Run the publisher; the consumer's CPU seconds and the wall seconds while it published."""
    pub = start([sys.executable, __file__, "--role", "pub", *common(args)], stdout=subprocess.PIPE)
    wait_line(pub, "^start", pub.stdout)
    c0, t0 = cpu_s(consumer.pid), time.monotonic()
    wait_line(pub, "^done", pub.stdout, args.duration + 60)
    c1, t1 = cpu_s(consumer.pid), time.monotonic()
    sent = json.loads(pub.stdout.read().strip().splitlines()[-1])
    pub.wait(30)
    return c1 - c0, t1 - t0, sent


def common(args: argparse.Namespace) -> list[str]:
    return ["--duration", str(args.duration), "--camera-hz", str(args.camera_hz)]


def case_plain(args: argparse.Namespace) -> dict[str, Any]:
    sub = start(
        [sys.executable, __file__, "--role", "sub", *common(args)], stdin=subprocess.PIPE, stdout=subprocess.PIPE
    )
    wait_line(sub, "^ready", sub.stdout)
    cpu, wall, sent = measure(sub, args)
    sub.communicate("\n", timeout=30)
    return {"case": "plain", "cores": round(cpu / wall, 3), "sent": sum(sent.values())}


def case_record(args: argparse.Namespace) -> dict[str, Any]:
    tmp = Path(tempfile.mkdtemp(prefix="bench-record-"))
    bag = tmp / "bag"
    rec = start(
        [sys.executable, "-m", "go2vlm", "record", "-a", "-o", str(bag), "--no-progress"], stderr=subprocess.PIPE
    )
    wait_line(rec, "writing", rec.stderr)
    cpu, wall, sent = measure(rec, args)
    rec.send_signal(2)
    rec.communicate(timeout=60)
    import yaml

    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]}
    # Latched topics: the recorder also gets the sample sent before it subscribed.
    dropped = {t: n - counts.get(t, 0) for t, n in sent.items() if n - counts.get(t, 0) > 0}
    size = sum(f.stat().st_size for f in bag.iterdir())
    shutil.rmtree(tmp)
    return {
        "case": "record",
        "cores": round(cpu / wall, 3),
        "sent": sum(sent.values()),
        "recorded": meta["message_count"],
        "dropped": dropped,
        "MB_per_s": round(size / wall / 1e6, 1),
    }


async def _client(port: int, stop_after: float, counts: dict[str, int]) -> None:
    import websockets

    wanted = [
        "/camera/image_raw/compressed",
        "/tf",
        "/odom",
        "/cmd_vel",
        "/detected_target",
        "/detected_target/annotations",
        "/safety/status",
        "/view/robot",
    ]
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], max_size=None) as ws:
        channels: dict[str, int] = {}
        subs: dict[int, str] = {}
        subscribed: set[str] = set()
        since: dict[str, float] = {}
        deadline = time.monotonic() + stop_after
        while time.monotonic() < deadline:
            try:
                frame = await asyncio.wait_for(ws.recv(), 0.5)
            except asyncio.TimeoutError:
                frame = None
            except websockets.ConnectionClosed:
                return  # the server stopped: the case is over
            if isinstance(frame, str):
                msg = json.loads(frame)
                if os.environ.get("BENCH_DEBUG"):
                    print(round(time.monotonic(), 2), frame[:300], file=sys.stderr)
                if msg["op"] == "advertise":
                    channels.update({c["topic"]: c["id"] for c in msg["channels"]})
                elif msg["op"] == "status" and "unknown channel" in msg.get("message", ""):
                    # advertised while we connected, not yet known to our session: subscribe again
                    gone = int(re.findall(r"\d+", msg["message"])[-1])
                    subscribed -= {t for t, cid in channels.items() if cid == gone}
            elif frame is not None and frame[0] == 1:
                topic = subs[struct.unpack_from("<I", frame, 1)[0]]
                counts[topic] = counts.get(topic, 0) + 1
            # A subscription that brought nothing for 3 s may have raced the channel's advertisement.
            stale = {t for t in subscribed if not counts.get(t) and time.monotonic() - since.get(t, 0) > 3}
            subscribed -= stale
            new = [t for t in wanted if t in channels and t not in subscribed]
            if new:
                payload = []
                for t in new:
                    subs[len(subs) + 1] = t
                    payload.append({"id": len(subs), "channelId": channels[t]})
                    subscribed.add(t)
                    since[t] = time.monotonic()
                await ws.send(json.dumps({"op": "subscribe", "subscriptions": payload}))


def case_view(args: argparse.Namespace) -> dict[str, Any]:
    view = start([sys.executable, "-m", "go2vlm", "view", "--port", "0"], stderr=subprocess.PIPE)
    try:
        port = int(re.search(r"ws://[\d.]+:(\d+)", wait_line(view, "ws://", view.stderr)).group(1))  # type: ignore[union-attr]
        threading.Thread(target=view.stderr.read, daemon=True).start()  # keep its log pipe flowing
        counts: dict[str, int] = {}
        client = threading.Thread(target=lambda: asyncio.run(_client(port, args.duration + 20, counts)), daemon=True)
        client.start()
        cpu, wall, _sent = measure(view, args)
    finally:
        view.send_signal(2)
        view.communicate(timeout=60)
    return {
        "case": "view",
        "cores": round(cpu / wall, 3),
        "client_images_per_s": round(counts.get("/camera/image_raw/compressed", 0) / wall, 1),
        "client_messages": sum(counts.values()),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--role", choices=["main", "pub", "sub"], default="main")
    p.add_argument("--cases", default="plain,record,view")
    p.add_argument("--duration", type=float, default=20.0, help="seconds of publishing per case")
    p.add_argument("--camera-hz", type=float, default=30.0)
    p.add_argument("--json", default=None, help="also write the results here")
    args = p.parse_args()
    if args.role == "pub":
        role_pub(args)
        return 0
    if args.role == "sub":
        role_sub(args)
        return 0
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 200)))
    os.environ.setdefault("GO2VLM_IFACE", "lo")
    print(f"# camera {W}x{H} bgr8 at {args.camera_hz:g} Hz + the demo's other topics; {os.cpu_count()} CPUs")
    results = {}
    for case in args.cases.split(","):
        results[case] = {"plain": case_plain, "record": case_record, "view": case_view}[case.strip()](args)
        print(json.dumps({**results[case], "load_avg_1min": os.getloadavg()[0]}), flush=True)
    if "plain" in results and "record" in results:
        extra = results["record"]["cores"] - results["plain"]["cores"]
        print(json.dumps({"record_beyond_bus_cores": round(extra, 3)}), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
