"""Large rgb8 frames between two processes, for tests/bus/test_bus_large_images.py.

    python image_link.py recv --qos sensor --frames 30 --timeout 20   # prints "ready", then "got N"
    python image_link.py send 1280x720 --frames 30 --rate 10

The receiver counts the numbered frames that arrive on /bus/large_images; the sender publishes them
with QOS_IMAGE (the camera nodes' profile) once a reader has matched.
"""

from __future__ import annotations

import argparse
import sys
import time

from go2vlm.bus import PROFILES, Node
from go2vlm.msgs.sensor_msgs import Image
from testing_support.image_frames import send_frames

TOPIC = "/bus/large_images"


def recv(qos: str, frames: int, timeout: float) -> None:
    got: set[int] = set()
    node = Node(node_name="image_link_recv")
    node.create_subscription(Image, TOPIC, lambda m: got.add(int(m.header.frame_id)), PROFILES[qos])
    node.start()
    print("ready", flush=True)
    deadline = time.monotonic() + timeout  # wall time: a test's deadline
    while len(got) < frames and time.monotonic() < deadline:
        time.sleep(0.05)
    node.shutdown()
    print(f"got {len(got)}", flush=True)


def send(size: str, frames: int, rate: float) -> None:
    width, height = (int(v) for v in size.split("x"))
    send_frames(TOPIC, width, height, frames, rate, 20.0, "image_link_send")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("role", choices=("recv", "send"))
    ap.add_argument("size", nargs="?", default="1280x720")
    ap.add_argument("--qos", default="sensor", choices=sorted(PROFILES))
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--timeout", type=float, default=30.0)
    args = ap.parse_args()
    if args.role == "recv":
        recv(args.qos, args.frames, args.timeout)
    else:
        send(args.size, args.frames, args.rate)


if __name__ == "__main__":
    sys.exit(main())
