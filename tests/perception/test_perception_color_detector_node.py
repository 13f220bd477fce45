"""The color_detector node over real DDS: the debug image is drawn only while someone subscribes to it."""

from __future__ import annotations

import time

from busutil import Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_SENSOR, Node, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.image import numpy_to_image, to_bgr
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.sources.test_pattern_node import draw_pattern


class _Io(Node):
    name = "nodes_io"


def test_debug_image_only_while_subscribed() -> None:
    det = make_node("color_detector")
    io = _Io()
    pub = io.create_publisher(Image, "/camera/image_raw", QOS_DEFAULT)
    with running(det, io):
        assert wait_for(lambda: pub.matched > 0, 5.0)
        pub.publish(numpy_to_image(draw_pattern(0), "bgr8", header=io.header("camera")))
        assert wait_for(lambda: det.frames >= 1, 5.0)
        assert det.debug_pub.count == 0, "debug image drawn with nobody watching"
        dbg = Recorder()
        io.create_subscription(Image, "/color_detector/debug_image", dbg, QOS_SENSOR)
        time.sleep(0.8)  # the node re-checks for subscribers twice a second
        for _ in range(3):
            pub.publish(numpy_to_image(draw_pattern(1), "bgr8", header=io.header("camera")))
            time.sleep(0.1)
        assert wait_for(lambda: len(dbg) > 0, 5.0)
    annotated = to_bgr(dbg.msgs()[-1])
    rim = annotated[150 + 50 : 150 + 64, 450 + 50 : 450 + 64]  # the circle's rim at 45 degrees
    assert (rim == [0, 255, 255]).all(axis=-1).any(), "no yellow detection circle drawn"
