"""The go2 driver over WebRTC next to DDS, against the sim on loopback: what reaches the driver's
ROS side per second (state, lowstate, scan, camera), the camera's latency, and a Move's round trip
(sent, applied on the sim's physics thread, answered), and the CPU it all costs (the process's
CPU time per second of wall time, next to the sim alone).

Usage: PYTHONPATH=src python benchmarks/bench_webrtc.py [--seconds 20] [--calls 200] [--json out.json]

One process: the sim (kinematic, vision_test, head camera 640x480 at 10 Hz, `webrtc: true` on a free
loopback port, which also serves the Unitree DDS), the go2 driver (first `transport: webrtc`, then
`transport: dds`) and a probe node that counts the driver's topics. Wall-clock figures: quote the
load average (printed) beside them.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import socket
import statistics
import time
from typing import Any

from go2vlm.bus import QOS_IMAGE, QOS_SENSOR, Node
from go2vlm.launch.registry import make_node
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.sensor_msgs import Image, LaserScan
from go2vlm.msgs.unitree import LowState
from go2vlm.robots.go2 import protocol as p
from go2vlm.robots.go2.client import RpcClient

REMAP = {
    k: "/sim" + k for k in ("/cmd_vel", "/odom", "/imu", "/tf", "/scan", "/camera/image_raw", "/camera/camera_info")
}


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def pct(values: list[float], q: float) -> float:
    return sorted(values)[min(len(values) - 1, int(q * len(values)))] if values else float("nan")


class Counter:
    def __init__(self) -> None:
        self.times: list[float] = []
        self.lat: list[float] = []

    def __call__(self, msg: Any) -> None:
        now = time.time()
        self.times.append(time.monotonic())
        stamp = getattr(getattr(msg, "header", None), "stamp", None)
        if stamp is not None:
            self.lat.append(now - (stamp.sec + stamp.nanosec * 1e-9))

    def rate(self, t0: float, t1: float) -> float:
        return sum(1 for t in self.times if t0 <= t <= t1) / (t1 - t0)


def measure(seconds: float, probe: Node) -> dict[str, Counter]:
    counters = {name: Counter() for name in ("odom", "lowstate", "scan", "camera")}
    subs = [
        probe.create_subscription(Odometry, "/odom", counters["odom"]),
        probe.create_subscription(LowState, "/go2/lowstate", counters["lowstate"], QOS_SENSOR),
        probe.create_subscription(LaserScan, "/scan", counters["scan"], QOS_SENSOR),
        probe.create_subscription(Image, "/camera/image_raw", counters["camera"], QOS_IMAGE),
    ]
    time.sleep(seconds)
    for sub in subs:
        probe.destroy_subscription(sub)
    return counters


def rates(counters: dict[str, Counter], seconds: float) -> dict[str, float]:
    t1 = max((c.times[-1] for c in counters.values() if c.times), default=time.monotonic())
    t0 = t1 - seconds + 2.0  # the first 2 s: discovery and the link coming up
    return {f"{k}_hz": round(c.rate(t0, t1), 2) for k, c in counters.items()}


def video_latency(sent: collections.deque, got: collections.deque) -> list[float]:
    """Match received frames to sent ones by RTP timestamp (sent pts + one constant offset, mod 2^32)."""
    if not sent or not got:
        return []
    offsets = collections.Counter((rx - tx) % 2**32 for rx, _ in list(got)[:20] for tx, _ in sent)
    offset, _ = offsets.most_common(1)[0]
    by_pts = {tx % 2**32: t for tx, t in sent}
    return [t_rx - by_pts[(rx - offset) % 2**32] for rx, t_rx in got if (rx - offset) % 2**32 in by_pts]


def move_rtt(call: Any, n: int) -> list[float]:
    out = []
    for i in range(n):
        t0 = time.perf_counter()
        result = call({"x": 0.05 if i % 2 else -0.05, "y": 0.0, "z": 0.0})
        if result.ok:
            out.append(time.perf_counter() - t0)
    return out


def cpu_ms(fn: Any, n: int, clock: Any = time.thread_time) -> float:
    """CPU milliseconds per call of `fn` (this thread's, or the process's with `clock=time.process_time`
    for work on threads of its own, as x264's): steady on a loaded machine."""
    fn()
    t0 = clock()
    for _ in range(n):
        fn()
    return round((clock() - t0) / n * 1e3, 3)


def codec_costs() -> dict[str, float]:
    """What each message costs to put on the data channel and to take off it, in CPU time."""
    import av
    import numpy as np

    from go2vlm.msgs.unitree import LowState, SportModeState
    from go2vlm.robots.go2.webrtc import codec

    state, low = SportModeState(position=[1.0, 2.0, 0.3]), LowState(power_v=29.0)
    state_text = codec.message(p.DC_MSG, p.RTC_SPORT_STATE, codec.to_jsonable(state))
    low_text = codec.message(p.DC_MSG, p.RTC_LOW_STATE, codec.to_jsonable(low))
    rng = np.random.default_rng(0)
    cloud = rng.uniform([-5, -5, -0.3], [5, 5, 1.0], (720, 3))  # the sim lidar's 720 rays
    header, payload = codec.voxelize(cloud, np.zeros(3), 0.0)
    frame = codec.encode_binary({"type": p.DC_MSG, "topic": p.RTC_LIDAR_VOXELS, "data": header}, payload)

    def voxels(msg: dict[str, Any], data: bytes | None) -> Any:
        return codec.voxel_points(msg["data"], data or b"")

    out = {
        "sportmodestate_json_bytes": len(state_text),
        "sportmodestate_encode_ms": cpu_ms(
            lambda: codec.message(p.DC_MSG, p.RTC_SPORT_STATE, codec.to_jsonable(state)), 500
        ),
        "sportmodestate_decode_ms": cpu_ms(
            lambda: codec.sport_state_from_json(codec.decode(state_text)[0]["data"]), 500
        ),
        "lowstate_json_bytes": len(low_text),
        "lowstate_encode_ms": cpu_ms(lambda: codec.message(p.DC_MSG, p.RTC_LOW_STATE, codec.to_jsonable(low)), 200),
        "lowstate_decode_ms": cpu_ms(lambda: codec.low_state_from_json(codec.decode(low_text)[0]["data"]), 200),
        "voxel_map_bytes": len(frame),
        "voxel_map_encode_ms": cpu_ms(lambda: codec.voxelize(cloud, np.zeros(3), 0.0), 100),
        "voxel_map_decode_ms": cpu_ms(lambda: voxels(*codec.decode(frame)), 100),
    }
    # The video: one 640x480 frame through H.264 (libx264, as aiortc encodes) and back.
    enc = av.CodecContext.create("libx264", "w")
    enc.width, enc.height, enc.pix_fmt = 640, 480, "yuv420p"
    enc.options = {"preset": "ultrafast", "tune": "zerolatency"}
    dec = av.CodecContext.create("h264", "r")
    img = rng.integers(0, 255, (480, 640, 3), dtype=np.uint8)
    img[:, :320] = 90  # half flat, half noise: a hard frame
    packets: list[Any] = []

    def encode() -> None:
        packets.extend(enc.encode(av.VideoFrame.from_ndarray(img, format="rgb24").reformat(format="yuv420p")))

    out["h264_encode_640x480_ms"] = cpu_ms(encode, 30, time.process_time)
    good = [pk for pk in packets if pk.size]
    out["h264_decode_640x480_ms"] = (
        cpu_ms(lambda: [dec.decode(pk) for pk in good[:1]], 1, time.process_time) if good else None
    )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=20.0, help="measuring time per transport")
    ap.add_argument("--calls", type=int, default=200, help="Move round trips per transport")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    port = free_port()
    sim = make_node(
        "sim",
        params={
            "mode": "kinematic",
            "world": "vision_test",
            "world_camera": False,
            "webrtc": True,
            "webrtc_port": port,
        },
        remap=REMAP,
    )
    probe = Node(node_name="bench_webrtc")
    sim.start()
    probe.start()
    out: dict[str, Any] = {"load_average_start": os.getloadavg(), "codec": codec_costs()}
    print("codec", json.dumps(out["codec"]), flush=True)
    try:
        time.sleep(3.0)  # the sim's start-up
        cpu0, wall0 = time.process_time(), time.monotonic()
        time.sleep(args.seconds / 2)
        out["sim_alone_cpu_cores"] = round((time.process_time() - cpu0) / (time.monotonic() - wall0), 2)
        print("sim alone", out["sim_alone_cpu_cores"], flush=True)
        for transport in ("webrtc", "dds"):
            params = {"transport": transport, "rpc_timeout_s": 5.0, "stand_on_start": True}
            if transport == "webrtc":
                params.update(ip="127.0.0.1", signal_port=port)
            driver = make_node("go2", params=params)
            driver.start()
            try:
                cpu0, wall0 = time.process_time(), time.monotonic()
                counters = measure(args.seconds, probe)
                res: dict[str, Any] = rates(counters, args.seconds)
                # The whole process (sim, driver, probe): the sim's share is the same for both routes.
                res["process_cpu_cores"] = round((time.process_time() - cpu0) / (time.monotonic() - wall0), 2)
                if transport == "webrtc":
                    link = driver.link.link
                    peer = sim.webrtc.peer
                    lat = video_latency(peer.sent_frames, link.frame_log)

                    def call(params: dict, link: Any = link) -> p.RpcResult:
                        return link.request(p.RTC_SPORT_REQUEST, p.MOVE, params, timeout_s=5.0).wait(5.0)

                else:
                    lat = counters["camera"].lat
                    client = RpcClient(probe, p.SPORT_SERVICE, timeout_s=5.0)
                    client.wait_for_server(10.0)

                    def call(params: dict, client: RpcClient = client) -> p.RpcResult:
                        return client.call(p.MOVE, params)

                rtt = move_rtt(call, args.calls)
                res["camera_latency_ms"] = {
                    "median": round(statistics.median(lat) * 1e3, 1) if lat else None,
                    "p95": round(pct(lat, 0.95) * 1e3, 1) if lat else None,
                    "frames": len(lat),
                    "what": "server in -> decoded at the driver" if transport == "webrtc" else "request -> published",
                }
                res["move_rtt_ms"] = {
                    "median": round(statistics.median(rtt) * 1e3, 2) if rtt else None,
                    "p95": round(pct(rtt, 0.95) * 1e3, 2) if rtt else None,
                    "calls": len(rtt),
                }
                out[transport] = res
                print(transport, json.dumps(res), flush=True)
            finally:
                driver.shutdown()
    finally:
        probe.shutdown()
        sim.shutdown()
    out["load_average_end"] = os.getloadavg()
    print(json.dumps(out, indent=1))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
