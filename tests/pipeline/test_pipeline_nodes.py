"""Single nodes over real DDS: late joiners, the debug image, a latched e-stop reaching a gate that
starts after it, and teleop overriding the follower."""

from __future__ import annotations

import json
import time

from busutil import Recorder, wait_for
from pipeutil import is_zero

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.image import numpy_to_image, to_bgr
from go2vlm.msgs.sensor_msgs import CameraInfo, Image
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.sources.test_pattern_node import draw_pattern


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


def test_latched_estop_reaches_a_gate_started_later_and_teleop_wins() -> None:
    io = _Io()
    cmd, status = Recorder(), Recorder()
    io.create_subscription(Twist, "/cmd_vel", cmd, QOS_DEFAULT)
    io.create_subscription(String, "/safety/status", status, QOS_LATCHED)
    estop = io.create_publisher(Bool, "/emergency_stop", QOS_LATCHED)
    release = io.create_publisher(String, "/emergency_stop/release", QOS_DEFAULT)
    teleop = io.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)
    follow = io.create_publisher(Twist, "/follower/cmd_vel", QOS_DEFAULT)
    estop.publish(Bool(data=True))  # before any gate exists
    with running(io):
        gate = make_node("safety", params={"max_vx_forward": 0.4})
        with running(gate):
            t_end = time.monotonic() + 1.5
            while time.monotonic() < t_end:
                follow.publish(Twist(angular=Vector3(z=0.5)))
                time.sleep(0.05)
            assert gate.core.estopped, "a latched e-stop must reach a gate that starts later"
            assert cmd.msgs() and all(is_zero(m) for m in cmd.msgs())
            release.publish(String(data="RELEASE"))
            assert wait_for(lambda: not gate.core.estopped, 3.0)
            t_end = time.monotonic() + 1.0
            while time.monotonic() < t_end:  # both live: teleop (priority 100) beats the follower (50)
                follow.publish(Twist(angular=Vector3(z=0.5)))
                teleop.publish(Twist(linear=Vector3(x=2.0)))
                time.sleep(0.05)
            last = cmd.msgs()[-1]
            assert last.linear.x == 0.4 and last.angular.z == 0.0, last  # clamped to max_vx_forward
            st = json.loads(status.msgs()[-1].data)
            assert st["active"] == "teleop" and st["estop"] is False


def test_follower_stops_then_yields_the_mux_after_losing_the_target() -> None:
    """Zeros for idle_after_lost_s after the loss, then silence, so lower-priority inputs get the gate."""
    from go2vlm.msgs.geometry_msgs import Point, PointStamped

    follower = make_node("follower", params={"lost_timeout_s": 0.3, "idle_after_lost_s": 0.4})
    io = _Io()
    cmds = Recorder()
    io.create_subscription(Twist, "/follower/cmd_vel", cmds, QOS_DEFAULT)
    target = io.create_publisher(PointStamped, "/detected_target", QOS_DEFAULT)
    with running(follower, io):
        time.sleep(0.5)
        assert len(cmds) == 0, "a follower that never saw a target must not hold the mux"
        assert wait_for(lambda: target.matched > 0, 5.0)
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            target.publish(PointStamped(point=Point(x=0.0, z=0.2)))
            time.sleep(0.05)
        t_lost = time.monotonic()
        time.sleep(1.5)
    items = list(cmds.items)
    moving = [t for t, m in items if not is_zero(m)]
    assert moving, "the follower never walked towards the target"
    after = [(t - t_lost, m) for t, m in items if t > t_lost]
    zeros = [dt for dt, m in after if is_zero(m)]
    assert zeros and zeros[0] < 0.45, "the loss must be followed by a zero command"
    assert all(is_zero(m) for dt, m in after if dt > 0.35)
    assert not [dt for dt, _ in after if dt > 0.3 + 0.4 + 0.3], "still publishing long after the target was lost"
