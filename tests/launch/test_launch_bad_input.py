"""Bad input over real DDS: malformed images, NaN targets and absurd twists are rejected with a
rate-limited error and a counter; the nodes keep running and nothing moves because of them."""

from __future__ import annotations

import math
import time

from busutil import Recorder, wait_for
from pipeutil import finite, is_zero

from go2vlm.bus import QOS_DEFAULT, Node, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Point, PointStamped, Twist, Vector3
from go2vlm.msgs.image import numpy_to_image
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.std_msgs import Header
from go2vlm.sources.test_pattern_node import draw_pattern


class _Io(Node):
    name = "bad_input_io"


def _bad_images() -> dict[str, Image]:
    h = Header(frame_id="camera")
    return {
        "wrong step": Image(header=h, height=480, width=640, encoding="bgr8", step=100, data=bytes(480 * 100)),
        "truncated data": Image(header=h, height=480, width=640, encoding="bgr8", step=1920, data=bytes(1000)),
        "unknown encoding": Image(header=h, height=4, width=4, encoding="yuv_weird", step=12, data=bytes(48)),
        "0x0": Image(header=h, height=0, width=0, encoding="bgr8", step=0, data=b""),
        "20000x20000": Image(header=h, height=20000, width=20000, encoding="bgr8", step=60000, data=bytes(64)),
    }


def _refused(node: Node) -> int:
    """Images dropped by the bus's size check (msgs/sizes.py: a truncated one, 20000x20000) or refused
    by the node itself (an unknown encoding)."""
    return node.counters.get("bad_images", 0) + node.counters.get("refused_size", 0)


def test_bad_input_is_rejected_counted_and_moves_nothing(capsys) -> None:
    detector = make_node("color_detector")
    follower = make_node("follower")
    gate = make_node("safety")
    io = _Io()
    cmd, targets = Recorder(), Recorder()
    io.create_subscription(Twist, "/cmd_vel", cmd, QOS_DEFAULT)
    io.create_subscription(PointStamped, "/detected_target", targets, QOS_DEFAULT)
    img_pub = io.create_publisher(Image, "/camera/image_raw", QOS_DEFAULT)
    target_pub = io.create_publisher(PointStamped, "/detected_target", QOS_DEFAULT)
    teleop_pub = io.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)
    with running(detector, follower, gate, io):
        assert wait_for(lambda: img_pub.matched > 0 and len(cmd) > 5, 10.0)
        sent = 0
        for case, msg in _bad_images().items():
            for _ in range(3):
                img_pub.publish(msg)
                sent += 1
                assert wait_for(lambda s=sent: _refused(detector) >= s, 5.0), case
        time.sleep(0.3)
        assert _refused(detector) == sent
        assert len(targets) == 0, "a malformed image produced a target"
        assert all(is_zero(m) for m in cmd.msgs()), "something moved on malformed images"

        # NaN / absurd targets are dropped by the follower; nothing moves.
        for p in (Point(math.nan, 0, 0.2), Point(math.inf, 0, 0.2), Point(0.1, 0, -1.0), Point(1e9, 0, 0.1)):
            target_pub.publish(PointStamped(header=Header(frame_id="camera"), point=p))
        assert wait_for(lambda: follower.counters.get("bad_targets", 0) >= 4, 5.0)
        time.sleep(0.3)
        assert all(is_zero(m) for m in cmd.msgs())

        # The detector still works: a good frame turns the robot.
        img_pub.publish(numpy_to_image(draw_pattern(0), "bgr8", header=io.header("camera")))
        assert wait_for(lambda: len(targets) >= 1, 5.0), "detector stopped working after bad input"
        assert wait_for(lambda: any(m.angular.z < -0.1 for m in cmd.msgs()[-5:]), 5.0)

        # NaN / inf / absurd twists from the higher-priority teleop input are rejected and count as
        # absent: the follower's command stays in charge, the output stays finite and within limits.
        t0 = time.monotonic()
        bad_twists = [
            Twist(linear=Vector3(x=math.nan)),
            Twist(angular=Vector3(z=math.inf)),
            Twist(linear=Vector3(y=-1e12)),
            Twist(angular=Vector3(x=math.nan)),
        ]
        for tw in bad_twists:
            teleop_pub.publish(tw)
            img_pub.publish(numpy_to_image(draw_pattern(1), "bgr8", header=io.header("camera")))
            time.sleep(0.05)
        assert wait_for(lambda: gate.core.counters.get("rejected_teleop", 0) >= 4, 5.0)
        after = [m for ts, m in cmd.items if ts >= t0]
        assert after and all(finite(m) for m in after)
        assert all(abs(m.angular.z) <= 1.0 and abs(m.linear.x) <= 0.5 for m in after)
        assert gate.core.active != "teleop"
        for node in (detector, follower, gate):
            assert node.running, f"{node.node_name} died"

    err = capsys.readouterr().err
    image_errors = err.count("dropping a malformed image")
    assert 1 <= image_errors <= 3, f"{image_errors} image errors logged for {sent} bad images: not rate-limited"
    assert "20000x20000" in err or "0x0" in err or "step" in err
