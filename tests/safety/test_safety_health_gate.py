"""The safety gate obeys the health monitor over real DDS: a /lowstate stream (unitree_go/LowState)
with a hot motor caps the speed, then stops; a lost stream stops; a robot tipping over latches the
e-stop (and says so on /emergency_stop) until the deliberate release; every level is on /safety/status."""

from __future__ import annotations

import json
import math
import subprocess
import threading

import pytest
from busutil import GO2VLM, Recorder, env, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.msgs.unitree import LowState

# Slow: a /lowstate stream through every health level in turn, over the hysteresis times.
pytestmark = pytest.mark.slow


class _Io(Node):
    name = "health_io"


class Robot:
    """Publishes /lowstate at 50 Hz (wall time) from the fields set on it, while `on`."""

    def __init__(self, io: Node) -> None:
        self.pub = io.create_publisher(LowState, "/lowstate", QOS_SENSOR)
        self.temp, self.tilt_deg, self.soc, self.on = 40, 0.0, 90, True
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(0.02):
            if self.on:
                msg = LowState(power_v=28.0)
                msg.imu_state.rpy = [math.radians(self.tilt_deg), 0.0, 0.0]
                for m in msg.motor_state[:12]:
                    m.temperature = self.temp
                msg.bms_state.soc = self.soc
                self.pub.publish(msg)

    def __enter__(self) -> Robot:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def test_health_caps_stops_and_downs_through_the_gate() -> None:
    io = _Io()
    cmd, status, estops = Recorder(), Recorder(), Recorder()
    io.create_subscription(Twist, "/cmd_vel", cmd, QOS_DEFAULT)
    io.create_subscription(String, "/safety/status", status, QOS_LATCHED)
    io.create_subscription(Bool, "/emergency_stop", estops, QOS_DEFAULT)
    teleop = io.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)

    def vx() -> float | None:
        msgs = cmd.msgs()
        return msgs[-1].linear.x if msgs else None

    def health() -> dict:
        msgs = status.msgs()
        return json.loads(msgs[-1].data)["health"] if msgs else {}

    def sampled() -> bool:
        return health().get("motor_temp_max_c") is not None

    def drive_until(pred: object, timeout: float = 10.0) -> bool:
        return wait_for(lambda: (teleop.publish(Twist(linear=Vector3(x=0.4))), pred())[1], timeout, 0.05)  # type: ignore[operator]

    params = {"health_clear_s": 0.3, "accel_linear": 100.0, "guard": False, "max_vx_forward": 0.5}  # health alone
    with running(io), Robot(io) as robot:
        gate = make_node("safety", params=params)
        with running(gate):
            # Level ok holds before the first state sample too (armed by it): wait for the sample.
            assert drive_until(lambda: vx() == 0.4 and health().get("level") == "ok" and sampled())
            assert health()["motor_temp_max_c"] == 40 and health()["battery_pct"] == 90

            robot.temp = 95  # cap: the limit 0.5 halves, the command 0.4 is clamped to 0.25
            assert drive_until(lambda: vx() == 0.25 and health().get("level") == "cap")
            assert "motor 95 C (cap)" in health()["reasons"]
            robot.temp = 105  # stop
            assert drive_until(lambda: vx() == 0.0 and health().get("level") == "stop")
            robot.temp = 40  # healthy again: back after health_clear_s
            assert drive_until(lambda: vx() == 0.4 and health().get("level") == "ok")

            robot.soc = 10  # battery: cap
            assert drive_until(lambda: vx() == 0.25 and health().get("level") == "cap")
            robot.soc = 90
            assert drive_until(lambda: vx() == 0.4)

            robot.on = False  # the state stream is lost: stop
            assert drive_until(lambda: vx() == 0.0 and any("state stream lost" in r for r in health()["reasons"]))
            robot.on = True
            assert drive_until(lambda: vx() == 0.4 and health().get("level") == "ok")

            robot.tilt_deg = 60.0  # tipping over: down = the e-stop latches, and the robot ends hear it
            assert drive_until(lambda: gate.core.estopped and health().get("level") == "down")
            assert wait_for(lambda: any(m.data for m in estops.msgs()), 5.0)
            out = estop_release()  # while still tipped over: the gate latches again, and says why
            assert out.returncode == 1 and "health is at 'down'" in out.stderr and "tilt 60.0 deg" in out.stderr
            assert gate.core.estopped
            robot.tilt_deg = 0.0
            assert drive_until(lambda: health().get("level") == "ok")
            assert gate.core.estopped and vx() == 0.0  # leaving the stop takes the deliberate release
            out = estop_release()
            assert out.returncode == 0, out.stderr
            assert drive_until(lambda: not gate.core.estopped and vx() == 0.4)


def estop_release() -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*GO2VLM, "estop", "--release", "--timeout", "3"], capture_output=True, text=True, timeout=60, env=env()
    )
