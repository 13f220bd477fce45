"""The driver with no robot on the network: it says so, counts, keeps running, and never spins."""

from __future__ import annotations

import json
import time

from busutil import Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.std_msgs import Bool, String


def test_driver_without_robot_keeps_running() -> None:
    driver = make_node("go2", params={"camera_rate_hz": 10.0, "rpc_timeout_s": 0.2})
    gate = make_node("safety")  # /cmd_vel comes from the gate, the one writer the driver obeys
    probe = Node(node_name="go2_offline_probe")
    status = Recorder()
    probe.create_subscription(String, "/go2/status", lambda m: status(json.loads(m.data)), QOS_LATCHED)
    cmd = probe.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)
    estop = probe.create_publisher(Bool, "/emergency_stop", QOS_LATCHED)
    command = probe.create_publisher(String, "/go2/command", QOS_DEFAULT)
    with running(driver, gate, probe):
        assert wait_for(lambda: len(status) > 0 and status.msgs()[-1]["commander"]["ok"], 5.0)
        assert status.msgs()[-1]["connected"] is False
        for _ in range(10):
            cmd.publish(Twist(linear=Vector3(0.3, 0.0, 0.0)))
            time.sleep(0.05)
        command.publish(String(data="stand"))
        estop.publish(Bool(data=True))
        time.sleep(1.5)
        assert driver.running and driver.estop.engaged
        assert driver.counters.get("not_connected", 0) > 0 and driver.counters.get("rpc_errors", 0) > 0
        # Damp is retried while the e-stop holds, at a bounded rate (no tight loop without a robot).
        assert 1 <= driver.damps_sent <= 10
        assert driver.moves_sent == 0
        assert driver.frames == 0 and driver.video.sent == 0  # no camera polling while nothing answers


def test_driver_relays_lowstate_for_the_gate() -> None:
    """The robot's rt/lowstate (/lowstate) reaches the safety gate as /go2/lowstate."""
    from go2vlm.bus import QOS_SENSOR
    from go2vlm.msgs.unitree import LowState

    driver = make_node("go2", params={"camera_rate_hz": 0.0, "rpc_timeout_s": 0.2})
    probe = Node(node_name="go2_lowstate_probe")
    relayed = Recorder()
    probe.create_subscription(LowState, "/go2/lowstate", relayed, QOS_SENSOR)
    robot = probe.create_publisher(LowState, "/lowstate", QOS_SENSOR)
    msg = LowState(power_v=29.5)
    msg.motor_state[2].temperature = 77
    msg.bms_state.soc = 63
    with running(driver, probe):
        assert wait_for(lambda: (robot.publish(msg), len(relayed) > 0)[1], 10.0, 0.01)
    got = relayed.msgs()[-1]
    assert got.motor_state[2].temperature == 77 and got.bms_state.soc == 63 and got.power_v == 29.5
