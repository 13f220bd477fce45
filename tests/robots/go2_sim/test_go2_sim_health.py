"""Never past its health, as real processes over real DDS: the sim publishes /lowstate (rt/lowstate:
motor temperatures from its thermal model, a draining battery, the IMU), and each fault injected into
the running sim (`go2vlm param set /sim fault_...`) gets the safety gate's response: a hot motor caps
the speed, then stops; a tilt stops; a lost state stream stops; an empty battery latches the e-stop
and the sim Damps, until the deliberate release. Every level is on /safety/status."""

from __future__ import annotations

import json
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from busutil import GO2VLM, Procs, Recorder, env, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.unitree import LowState

SIM = ["run", "sim", *("--param", "mode=kinematic", "--param", "camera=false", "--param", "world_camera=false")]
GATE = ["run", "safety", "--param", "health_clear_s=0.5", "--param", "max_vx_forward=0.5"]  # the cap halves 0.5

pytestmark = pytest.mark.slow


class Probe(Node):
    name = "health_probe"

    def __init__(self) -> None:
        super().__init__()
        self.cmd, self.low = Recorder(), Recorder()
        self.gate: dict[str, Any] = {}
        self.sim: dict[str, Any] = {}
        self.create_subscription(Twist, "/cmd_vel", self.cmd, QOS_DEFAULT)
        self.create_subscription(LowState, "/lowstate", self.low, QOS_SENSOR)
        self.create_subscription(String, "/safety/status", self._on_gate, QOS_LATCHED)
        self.create_subscription(String, "/sim/status", self._on_sim, QOS_LATCHED)
        self.teleop = self.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)
        self.release = self.create_publisher(String, "/emergency_stop/release", QOS_DEFAULT)
        self._stop = threading.Event()
        self._driver = threading.Thread(target=self._drive, daemon=True)

    def _on_gate(self, msg: String) -> None:
        self.gate = json.loads(msg.data)

    def _on_sim(self, msg: String) -> None:
        self.sim = json.loads(msg.data)

    def _drive(self) -> None:
        while not self._stop.wait(0.05):
            self.teleop.publish(Twist(linear=Vector3(x=0.3)))

    def start(self) -> Probe:
        super().start()
        self._driver.start()
        return self

    def close(self) -> None:
        self._stop.set()

    def vx(self) -> float | None:
        msgs = self.cmd.msgs()
        return msgs[-1].linear.x if msgs else None

    def level(self) -> str | None:
        return (self.gate.get("health") or {}).get("level")


@pytest.fixture
def probe() -> Iterator[Probe]:
    p = Probe().start()
    try:
        yield p
    finally:
        p.shutdown()


def set_sim(name: str, value: str) -> None:
    out = subprocess.run(
        [*GO2VLM, "param", "set", "/sim", name, value], capture_output=True, text=True, timeout=60, env=env()
    )
    assert out.returncode == 0, out.stderr


def test_each_fault_gets_its_response(procs: Procs, probe: Probe, tmp_path: Path) -> None:
    with open(tmp_path / "sim.log", "w") as sim_log, open(tmp_path / "gate.log", "w") as gate_log:
        procs.start(*SIM, stdout=sim_log)
        procs.start(*GATE, stdout=gate_log)
    assert wait_for(lambda: probe.vx() == 0.3 and probe.level() == "ok" and len(probe.low) > 0, 60), probe.gate
    assert wait_for(lambda: probe.gate["health"]["samples"] > 0, 10), probe.gate  # status is on change or 1 Hz

    # The sim's rt/lowstate: 12 motors warm from the ambient, a full battery draining, the pack voltage.
    low = probe.low.msgs()[-1]
    temps = [m.temperature for m in low.motor_state]
    assert all(t >= 25 for t in temps[:12]) and temps[12:] == [0] * 8
    assert 95 <= low.bms_state.soc <= 100 and 30.0 < low.power_v <= 33.6
    assert probe.gate["health"]["battery_pct"] >= 95 and probe.gate["health"]["motor_temp_max_c"] >= 25

    set_sim("fault_motor_temp_c", "100")  # cap: the 0.5 m/s limit halves, so 0.3 becomes 0.25
    assert wait_for(lambda: probe.vx() == 0.25 and probe.level() == "cap", 20), probe.gate
    assert any("motor 100 C" in r for r in probe.gate["health"]["reasons"])
    set_sim("fault_motor_temp_c", "110")  # stop
    assert wait_for(lambda: probe.vx() == 0.0 and probe.level() == "stop", 20), probe.gate
    assert probe.gate["last_zero_reason"].startswith("health: motor 110 C")
    set_sim("fault_motor_temp_c", "0")
    assert wait_for(lambda: probe.vx() == 0.3 and probe.level() == "ok", 20), probe.gate

    set_sim("fault_tilt_deg", "40")  # tilt: stop
    assert wait_for(lambda: probe.vx() == 0.0 and probe.level() == "stop", 20), probe.gate
    set_sim("fault_tilt_deg", "0")
    assert wait_for(lambda: probe.vx() == 0.3 and probe.level() == "ok", 20), probe.gate

    set_sim("fault_lowstate_silent", "true")  # the state stream is lost: stop
    assert wait_for(lambda: probe.vx() == 0.0 and "state stream lost" in probe.gate["last_zero_reason"], 20)
    set_sim("fault_lowstate_silent", "false")
    assert wait_for(lambda: probe.vx() == 0.3 and probe.level() == "ok", 20), probe.gate

    set_sim("fault_battery_pct", "2")  # empty: down = the e-stop latches, and the sim Damps
    assert wait_for(lambda: probe.level() == "down" and probe.gate["estop"] is True, 20), probe.gate
    assert wait_for(lambda: probe.sim.get("estop") is True and probe.sim.get("mode") == "damped", 20), probe.sim
    set_sim("fault_battery_pct", "-1")
    assert wait_for(lambda: probe.level() == "ok", 20), probe.gate
    assert probe.gate["estop"] is True and probe.vx() == 0.0, "leaving the stop takes the deliberate release"
    probe.release.publish(String(data="RELEASE"))
    assert wait_for(lambda: probe.vx() == 0.3 and probe.sim.get("estop") is False, 20), (probe.gate, probe.sim)


def test_a_real_tip_over_latches_the_estop(procs: Procs, probe: Probe) -> None:
    """No injected fault: a hard kick (/sim/push) rolls the trotting sim over; the tilt it reports on
    /lowstate takes the gate to "down", which latches the e-stop, and the sim Damps."""
    procs.start("run", "sim", "--param", "camera=false", "--param", "world_camera=false", stdout=subprocess.DEVNULL)
    procs.start(*GATE, stdout=subprocess.DEVNULL)
    push = probe.create_publisher(Twist, "/sim/push", QOS_DEFAULT)
    assert wait_for(lambda: probe.vx() == 0.3 and probe.sim.get("mode") == "walking" and push.matched > 0, 60)
    for _ in range(6):  # airborne and rolling fast; again if the first sample met a reader not yet matched
        push.publish(Twist(linear=Vector3(0.0, 5.0, 2.0), angular=Vector3(25.0, 0.0, 0.0)))
        if wait_for(lambda: probe.level() == "down", 3.0):
            break
    assert probe.level() == "down" and any("tilt" in r for r in probe.gate["health"]["reasons"]), probe.gate
    assert wait_for(lambda: probe.gate["estop"] is True and probe.vx() == 0.0, 10), probe.gate
    assert wait_for(lambda: probe.sim.get("estop") is True and probe.sim.get("mode") == "damped", 20), probe.sim
