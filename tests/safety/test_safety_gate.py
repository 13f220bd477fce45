"""The safety gate: its parameters can only lower the Go2's ceilings; over real DDS, a latched e-stop
reaches a gate started after it, and teleop overrides the follower."""

from __future__ import annotations

import json
import time

import pytest
from busutil import Recorder, wait_for
from pipeutil import is_zero

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node, ParamError, build_config, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.safety.gate_node import SafetyGateConfig


def test_safety_params_can_only_lower_the_go2_ceilings() -> None:
    cfg = build_config(SafetyGateConfig, {"max_vx_forward": 3.8, "max_vyaw": 4.0})
    assert cfg.max_vx_forward == 3.8
    for name, value in (("max_vx_forward", 3.9), ("max_vx_backward", 2.6), ("max_vy", 1.1), ("max_vyaw", 4.5)):
        with pytest.raises(ParamError, match="above the maximum"):
            build_config(SafetyGateConfig, {name: value})
    with pytest.raises(ParamError):
        build_config(SafetyGateConfig, {"rate_hz": 10})
    with pytest.raises(ParamError, match="timeout_s"):
        build_config(SafetyGateConfig, {"inputs": [{"topic": "/a", "priority": 1, "timeout_s": 0}]})
    with pytest.raises(ParamError, match="output"):
        build_config(SafetyGateConfig, {"inputs": [{"topic": "/cmd_vel", "priority": 1}]})
    ok = build_config(SafetyGateConfig, {"inputs": "[{topic: /joy/cmd_vel, priority: 5}]"})
    assert ok.inputs == [{"topic": "/joy/cmd_vel", "priority": 5}]


class _Io(Node):
    name = "nodes_io"


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
        gate = make_node("safety", params={"max_vx_forward": 0.4, "guard": False})  # no scan here: not the test
        with running(gate):
            t_end = time.monotonic() + 1.5
            while time.monotonic() < t_end:
                follow.publish(Twist(angular=Vector3(z=0.5)))
                time.sleep(0.05)
            assert gate.core.estopped, "a latched e-stop must reach a gate that starts later"
            assert cmd.msgs() and all(is_zero(m) for m in cmd.msgs())
            release.publish(String(data="RELEASE"))
            assert wait_for(lambda: not gate.core.estopped, 3.0)

            # Both live: teleop (priority 100) beats the follower (50), clamped to max_vx_forward. Wait on
            # it: a gate killed by an earlier test (kill -9) stays a /cmd_vel writer in discovery until its
            # lease runs out, and this gate holds zero while that foreign writer is there.
            def teleop_drives() -> bool:
                follow.publish(Twist(angular=Vector3(z=0.5)))
                teleop.publish(Twist(linear=Vector3(x=2.0)))
                last = cmd.msgs()[-1]
                return bool(last.linear.x == 0.4 and last.angular.z == 0.0)

            assert wait_for(teleop_drives, 30, 0.05), cmd.msgs()[-1]

            def status_says_teleop() -> bool:
                st = json.loads(status.msgs()[-1].data)
                return bool(st["active"] == "teleop" and st["estop"] is False)

            assert wait_for(status_says_teleop, 10), status.msgs()[-1]
