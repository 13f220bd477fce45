"""The sim as a robot end that holds a stop, as real processes over real DDS:
- it honours /emergency_stop by itself (no gate running): Damp, no /cmd_vel, /go2/command only as
  the e-stop allows, until the exact release; then /cmd_vel moves it only after passing zero;
- one commander: with the gate driving, a foreign /cmd_vel writer (a `topic pub` process at 200 Hz
  asking for 2 m/s) stops the robot, and /sim/status and /safety/status name it (GUID, participant,
  node); a second gate makes both gates refuse, and the robot stays put."""

from __future__ import annotations

import json
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from busutil import Procs, Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Endpoint, Node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.std_msgs import Bool, String

SIM = ["run", "sim", *("--param", "mode=kinematic", "--param", "camera=false", "--param", "world_camera=false")]


# Slow: the sim runs as a process in every test (as in the other sim node tests).
pytestmark = pytest.mark.slow


class Probe(Node):
    name = "stop_holds_probe"

    def __init__(self) -> None:
        super().__init__()
        self.odom, self.sim, self.gates = Recorder(), Recorder(), Recorder()
        self.create_subscription(Odometry, "/odom", self.odom, QOS_DEFAULT)
        self.create_subscription(String, "/sim/status", lambda m: self.sim(json.loads(m.data)), QOS_LATCHED)
        self.create_subscription(String, "/safety/status", self._gate, QOS_LATCHED, with_sender=True)
        self.teleop = self.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)
        self.estop = self.create_publisher(Bool, "/emergency_stop", QOS_LATCHED)
        self.release = self.create_publisher(String, "/emergency_stop/release", QOS_DEFAULT)
        self.command = self.create_publisher(String, "/go2/command", QOS_DEFAULT)
        self.latest_gate: dict[str, dict[str, Any]] = {}
        self.speed = 0.0
        self._stop = threading.Event()
        self._teleop = threading.Thread(target=self._run_teleop, daemon=True)

    def _gate(self, msg: String, sender: Endpoint | None) -> None:
        self.latest_gate[sender.guid if sender else "?"] = json.loads(msg.data)

    def _run_teleop(self) -> None:
        while not self._stop.wait(0.05):
            self.teleop.publish(Twist(linear=Vector3(x=self.speed)))

    def start(self) -> Probe:
        super().start()
        self._teleop.start()
        return self

    def close(self) -> None:
        self._stop.set()

    def x(self) -> float:
        return self.odom.msgs()[-1].pose.pose.position.x

    def status(self) -> dict[str, Any]:
        items = self.sim.msgs()
        return items[-1] if items else {}

    def moved_while(self, seconds: float) -> float:
        x0 = self.x()
        time.sleep(seconds)
        return abs(self.x() - x0)


@pytest.fixture
def probe() -> Iterator[Probe]:
    p = Probe().start()
    try:
        yield p
    finally:
        p.shutdown()


def test_the_sim_latches_the_estop_by_itself(procs: Procs, probe: Probe) -> None:
    procs.start(*SIM)
    assert wait_for(lambda: len(probe.odom) > 5 and probe.status().get("mode") == "standing", 40)
    probe.estop.publish(Bool(data=True))  # no gate runs: the sim hears it itself
    assert wait_for(lambda: probe.status().get("estop") is True and probe.status()["mode"] == "damped", 10)
    probe.command.publish(String(data="stand"))
    probe.command.publish(String(data="recover"))
    assert wait_for(lambda: probe.status()["counters"].get("refused_command", 0) >= 2, 10), probe.status()
    assert probe.status()["mode"] == "damped" and probe.status()["last_command"]["result"].startswith("refused")
    probe.estop.publish(Bool(data=False))  # false does not release
    probe.release.publish(String(data="RELEASE "))  # neither does a padded token
    time.sleep(1.0)
    assert probe.status()["estop"] is True
    probe.release.publish(String(data="RELEASE"))
    assert wait_for(lambda: probe.status()["estop"] is False, 10)
    assert probe.status()["mode"] == "damped", "released, the robot stays down until told to stand"
    probe.command.publish(String(data="recover"))
    assert wait_for(lambda: probe.status()["mode"] == "standing", 20)
    assert probe.status()["commander"]["need_zero"] is True


def test_one_commander_per_robot(procs: Procs, probe: Probe, tmp_path: Path) -> None:
    procs.start(*SIM)
    gate1 = procs.start("run", "safety", "--param", f"estop_state_file={tmp_path / 'g1.json'}")
    assert wait_for(lambda: len(probe.odom) > 5 and probe.status().get("commander", {}).get("ok"), 40)
    probe.speed = 0.3
    assert wait_for(lambda: probe.moved_while(0.5) > 0.05, 10), "the gate drives the sim"

    # A foreign writer: the robot stops, and both ends name it.
    rogue = procs.start(
        "topic", "pub", "/cmd_vel", "geometry_msgs/msg/Twist", "{linear: {x: 2.0}}", "--rate", "200",
        stdout=subprocess.DEVNULL,
    )  # fmt: skip
    assert wait_for(lambda: probe.status().get("commander", {}).get("reported"), 15)
    assert probe.moved_while(1.0) < 0.01, "a foreign /cmd_vel writer stops the robot"
    foreign = probe.status()["commander"]["foreign"]
    assert len(foreign) == 1 and foreign[0]["node"] == "/go2vlm_topic_pub"
    assert foreign[0]["guid"] and foreign[0]["participant"]
    assert "not a safety gate" in probe.status()["commander"]["reason"]
    assert wait_for(lambda: any(s["commander"]["foreign"] for s in probe.latest_gate.values()), 10)
    gate_view = next(iter(probe.latest_gate.values()))
    assert gate_view["commander"]["foreign"][0]["guid"] == foreign[0]["guid"]
    assert "not a safety gate" in gate_view["last_zero_reason"]
    assert probe.status()["counters"].get("cmd_vel_refused", 0) > 0

    # It goes: the gate drives again, starting from zero.
    procs.stop(rogue)
    assert wait_for(lambda: probe.status()["commander"]["ok"], 20)
    assert wait_for(lambda: probe.moved_while(0.5) > 0.05, 10), "driving resumes once the foreign writer left"

    # A second gate: both refuse to drive, and the robot stays put.
    gate2 = procs.start("run", "safety", "--name", "safety2", "--param", f"estop_state_file={tmp_path / 'g2.json'}")
    assert wait_for(lambda: len(probe.status()["commander"]["gates"]) == 2, 20)
    assert probe.moved_while(1.0) < 0.01
    assert "2 safety gates" in probe.status()["commander"]["reason"]
    assert wait_for(
        lambda: (
            len(probe.latest_gate) == 2
            and all("2 safety gates" in s["last_zero_reason"] for s in probe.latest_gate.values())
        ),
        10,
    ), probe.latest_gate
    procs.stop(gate2)
    assert wait_for(lambda: probe.status()["commander"]["ok"], 20)
    assert wait_for(lambda: probe.moved_while(0.5) > 0.05, 10)
    procs.stop(gate1)
