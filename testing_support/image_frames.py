"""Numbered rgb8 frames for the large-image test and benchmark (tests/bus/image_link.py,
benchmarks/bench_images.py): the same sender, so the test checks what the benchmark measures."""

from __future__ import annotations

import time

import numpy as np

from go2vlm.bus import QOS_IMAGE, Node
from go2vlm.msgs.sensor_msgs import Image

__all__ = ["send_frames"]


def send_frames(topic: str, width: int, height: int, frames: int, rate: float, wait_s: float, node_name: str) -> None:
    """Publish `frames` random rgb8 frames (header.frame_id = their index) at `rate` Hz with QOS_IMAGE
    (the camera nodes' profile), once a reader has matched or after `wait_s`."""
    node = Node(node_name=node_name)
    pub = node.create_publisher(Image, topic, QOS_IMAGE)
    deadline = time.monotonic() + wait_s
    while pub.matched < 1 and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(0.5)  # the reader sees us too
    pixels = np.random.default_rng(0).integers(0, 255, width * height * 3, dtype=np.uint8).tobytes()
    next_t = time.monotonic()
    for i in range(frames):
        msg = Image(height=height, width=width, encoding="rgb8", step=width * 3, data=pixels)
        msg.header.frame_id = str(i)
        pub.publish(msg)
        next_t += 1.0 / rate
        time.sleep(max(0.0, next_t - time.monotonic()))
    time.sleep(1.0)  # reliable repairs finish before the writer goes
    node.shutdown()
