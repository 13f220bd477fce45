"""Make docs/img/view_client.png: what a Foxglove WebSocket client received from `go2vlm view`.

    .venv/bin/python docs/foxglove/client_picture.py [--seconds 20]

Starts the follow loop on the MuJoCo sim (sim, color_detector, follower, safety) and `go2vlm view`,
connects as a Foxglove client (foxglove.sdk.v1), subscribes like the shipped layout does and draws
what came in: the last JPEG frame with the target from /detected_target, the follower's error and
/cmd_vel over time, the /odom track and /safety/status. It is not a screenshot of the Foxglove app.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import random
import re
import struct
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
WANTED = ["/camera/image_raw/compressed", "/detected_target", "/cmd_vel", "/odom", "/safety/status"]


async def client(port: int, seconds: float) -> dict[str, list[tuple[float, bytes]]]:
    import websockets

    got: dict[str, list[tuple[float, bytes]]] = {}
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], max_size=None) as ws:
        channels: dict[str, int] = {}
        subs: dict[int, str] = {}
        since: dict[str, float] = {}
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            try:
                frame = await asyncio.wait_for(ws.recv(), 0.5)
            except asyncio.TimeoutError:
                frame = None
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg["op"] == "advertise":
                    channels.update({c["topic"]: c["id"] for c in msg["channels"]})
            elif frame is not None and frame[0] == 1:
                topic = subs[struct.unpack_from("<I", frame, 1)[0]]
                got.setdefault(topic, []).append((time.monotonic() - t0, bytes(frame[13:])))
            for t in WANTED:  # (re)subscribe what has brought nothing yet
                if t in channels and not got.get(t) and time.monotonic() - since.get(t, -10) > 3:
                    subs[len(subs) + 1] = t
                    since[t] = time.monotonic()
                    await ws.send(
                        json.dumps({"op": "subscribe", "subscriptions": [{"id": len(subs), "channelId": channels[t]}]})
                    )
    return got


def draw(got: dict[str, list[tuple[float, bytes]]], out: Path) -> None:
    import cv2
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from go2vlm.msgs.geometry_msgs import PointStamped, Twist
    from go2vlm.msgs.nav_msgs import Odometry
    from go2vlm.msgs.sensor_msgs import CompressedImage
    from go2vlm.msgs.std_msgs import String

    image = CompressedImage.deserialize(got["/camera/image_raw/compressed"][-1][1])
    rgb = cv2.cvtColor(cv2.imdecode(np.frombuffer(image.data, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    targets = [(t, PointStamped.deserialize(d)) for t, d in got.get("/detected_target", [])]
    cmds = [(t, Twist.deserialize(d)) for t, d in got.get("/cmd_vel", [])]
    odom = [Odometry.deserialize(d).pose.pose.position for _, d in got.get("/odom", [])]
    status = json.loads(String.deserialize(got["/safety/status"][-1][1]).data)
    h, w = rgb.shape[:2]
    same = [
        p
        for _, p in targets
        if (p.header.stamp.sec, p.header.stamp.nanosec) == (image.header.stamp.sec, image.header.stamp.nanosec)
    ]
    fig = plt.figure(figsize=(13, 7.2))
    fig.suptitle(
        "What a Foxglove WebSocket client received from `go2vlm view`"
        " (drawn with matplotlib, not a Foxglove screenshot)",
        fontsize=11,
    )
    ax = fig.add_subplot(2, 3, (1, 2))
    ax.imshow(rgb)
    if same:
        p = same[0].point
        ax.add_patch(plt.Circle(((p.x + 1) * w / 2, (p.y + 1) * h / 2), p.z * w / 2, fill=False, color="cyan", lw=2))
        ax.text(
            (p.x + 1) * w / 2,
            (p.y + 1) * h / 2 - p.z * w / 2 - 8,
            f"target x={p.x:+.2f}",
            color="k",
            backgroundcolor="cyan",
        )
    ax.set_title(
        f"/camera/image_raw/compressed (JPEG {len(image.data) // 1000} kB, {w}x{h}) + /detected_target", fontsize=9
    )
    ax.axis("off")
    ax = fig.add_subplot(2, 3, 3)
    if odom:
        ax.plot([p.x for p in odom], [p.y for p in odom], color="tab:blue")
        ax.plot(odom[-1].x, odom[-1].y, "s", color="tab:blue")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title("/odom (the robot's track)", fontsize=9)
    ax.grid(alpha=0.3)
    ax = fig.add_subplot(2, 3, 4)
    ax.plot([t for t, _ in targets], [p.point.x for _, p in targets], ".", ms=3, color="tab:red")
    ax.axhline(0, color="0.5", lw=0.8)
    ax.set_title("follower error: /detected_target.point.x", fontsize=9)
    ax.set_xlabel("s")
    ax = fig.add_subplot(2, 3, 5)
    ax.plot([t for t, _ in cmds], [c.linear.x for _, c in cmds], label="linear.x")
    ax.plot([t for t, _ in cmds], [c.angular.z for _, c in cmds], label="angular.z")
    ax.legend(fontsize=8)
    ax.set_title("/cmd_vel (the safety gate's output)", fontsize=9)
    ax.set_xlabel("s")
    ax = fig.add_subplot(2, 3, 6)
    ax.axis("off")
    text = json.dumps({k: status[k] for k in ("active", "estop", "last_zero_reason", "output", "limits")}, indent=1)
    ax.text(0, 1, "/safety/status\n" + text, va="top", family="monospace", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=90)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "view_client.png")
    args = p.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 200)))
    os.environ.setdefault("GO2VLM_IFACE", "lo")
    os.environ.setdefault("MUJOCO_GL", "egl")
    go2vlm = [sys.executable, "-m", "go2vlm"]
    procs = [
        subprocess.Popen([*go2vlm, "run", "sim", "--param", "mode=kinematic", "--param", "world_camera=false"]),
        *(subprocess.Popen([*go2vlm, "run", kind]) for kind in ("color_detector", "follower", "safety")),
    ]
    view = subprocess.Popen([*go2vlm, "view", "--port", "0"], stderr=subprocess.PIPE, text=True)
    procs.append(view)
    try:
        assert view.stderr is not None
        port = 0
        while not port:
            line = view.stderr.readline()
            if not line:
                raise RuntimeError("the view stopped")
            m = re.search(r"ws://[\d.]+:(\d+)", line)
            port = int(m.group(1)) if m else 0
        got = asyncio.run(client(port, args.seconds))
    finally:
        for proc in reversed(procs):
            proc.send_signal(2)
        for proc in procs:
            proc.wait(30)
    draw(got, args.out)
    print(f"wrote {args.out}: " + ", ".join(f"{t} {len(v)}" for t, v in got.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
