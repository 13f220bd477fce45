"""test_pattern (the VLM article's test image publisher, section 3.3): the frame it draws, and a late
joiner over real DDS getting a frame long before the period."""

from __future__ import annotations

import time

import numpy as np
from busutil import Recorder, wait_for

from go2vlm.bus import QOS_LATCHED, QOS_SENSOR, Node, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.image import to_bgr
from go2vlm.msgs.sensor_msgs import CameraInfo, Image
from go2vlm.sources.test_pattern_node import draw_pattern


def test_test_pattern_matches_the_seed() -> None:
    img = draw_pattern(7)
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    assert img[300, 200].tolist() == [0, 255, 0]
    assert img[150, 450].tolist() == [0, 0, 255]
    assert img[470, 630].tolist() == [0, 0, 0]
    assert img[20:60, 50:200].max() == 255  # the white "Frame 7" text
    assert not np.array_equal(img, draw_pattern(8))


class _Io(Node):
    name = "nodes_io"


def test_late_joiner_gets_a_frame_long_before_the_period() -> None:
    cam = make_node("test_pattern", params={"period_s": 30.0})
    with running(cam):
        time.sleep(1.0)  # the start-up frame is long gone
        io = _Io()
        images, infos = Recorder(), Recorder()
        io.create_subscription(Image, "/camera/image_raw", images, QOS_SENSOR)
        io.create_subscription(CameraInfo, "/camera/camera_info", infos, QOS_LATCHED)
        t0 = time.monotonic()
        with running(io):
            assert wait_for(lambda: len(images) > 0 and len(infos) > 0, 5.0), "late joiner waited for the period"
            assert time.monotonic() - t0 < 5.0
    img = images.msgs()[0]
    assert (img.width, img.height, img.encoding, img.step, img.header.frame_id) == (640, 480, "bgr8", 1920, "camera")
    assert to_bgr(img)[150, 450].tolist() == [0, 0, 255]
    info = infos.msgs()[0]
    assert (info.width, info.height) == (640, 480) and info.k[0] > 0
