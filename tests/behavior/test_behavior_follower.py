"""The follower (the follow article's follower.py, section 5.3): its control law, and the node over real
DDS stopping and then yielding the mux after it loses the target."""

from __future__ import annotations

import time

import pytest
from busutil import Recorder, wait_for
from pipeutil import is_zero

from go2vlm.behavior.control import follow_command
from go2vlm.behavior.follower_node import FollowerConfig
from go2vlm.bus import QOS_DEFAULT, Node, build_config, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Twist


def test_follower_law_is_the_seeds() -> None:
    cfg = FollowerConfig()
    assert follow_command(0.40625, 0.25, cfg) == pytest.approx((0.0, -0.325))  # not aligned: turn only
    assert follow_command(0.1, 0.25, cfg) == pytest.approx((0.3 * 0.75, -0.08))  # aligned: walk
    assert follow_command(0.0, 1.5, cfg) == (0.0, 0.0)  # very close: never backwards
    assert follow_command(-0.9, 0.1, cfg) == pytest.approx((0.0, 0.72))
    assert follow_command(-2.0, 0.1, cfg)[1] == 1.0  # clamped to max_angular
    big = build_config(FollowerConfig, {"kp_linear": 5.0})
    assert follow_command(0.0, 0.0, big)[0] == 0.5  # clamped to max_linear
    damped = build_config(FollowerConfig, {"kd_angular": 0.5})
    assert follow_command(0.3, 0.2, damped, dx_dt=0.4)[1] == pytest.approx(-0.24 - 0.2)


class _Io(Node):
    name = "nodes_io"


def test_follower_stops_then_yields_the_mux_after_losing_the_target() -> None:
    """Zeros for idle_after_lost_s after the loss, then silence, so lower-priority inputs get the gate."""
    from go2vlm.msgs.geometry_msgs import Point, PointStamped

    follower = make_node("follower", params={"lost_timeout_s": 0.3, "idle_after_lost_s": 0.4})
    io = _Io()
    cmds = Recorder()
    io.create_subscription(Twist, "/follower/cmd_vel", cmds, QOS_DEFAULT)
    target = io.create_publisher(PointStamped, "/detected_target", QOS_DEFAULT)
    with running(follower, io):
        assert wait_for(lambda: target.matched > 0, 5.0)
        time.sleep(0.5)  # a window to see nothing in: its watchdog ticks every 10 ms
        assert len(cmds) == 0, "a follower that never saw a target must not hold the mux"

        def walking() -> bool:
            target.publish(PointStamped(point=Point(x=0.0, z=0.2)))
            return any(not is_zero(m) for m in cmds.msgs())

        assert wait_for(walking, 10.0), "the follower never walked towards the target"
        n_seen = len(cmds)
        # The target is gone: zeros (lost_timeout_s), then silence (idle_after_lost_s) for the mux.
        assert wait_for(lambda: any(is_zero(m) for m in cmds.msgs()[n_seen:]), 10.0), "no zero after the loss"
        assert wait_for(lambda: cmds.items and time.monotonic() - cmds.items[-1][0] > 1.0, 10.0), "never silent"
    after = cmds.msgs()[n_seen:]
    first_zero = next(i for i, m in enumerate(after) if is_zero(m))
    assert all(is_zero(m) for m in after[first_zero:]), "after the first zero, only zeros until silence"
