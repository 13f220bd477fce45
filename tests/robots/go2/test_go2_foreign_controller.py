"""The go2 driver watches rt/api/sport/request for a foreign controller, as real processes over real
DDS (the sim's Unitree bridge plays the Go2): with the default policy (damp) a raw request from
another client latches the driver's e-stop and damps the robot until the deliberate release; with
foreign_sport=report it is only reported. Either way /go2/status names the writer."""

from __future__ import annotations

import json
import subprocess
import time

from busutil import GO2VLM, Procs, Recorder, env, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_UNITREE_WRITER, Node, running
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.unitree import Request
from go2vlm.robots.go2 import protocol as p

SIM = [
    "run", "sim",
    *("--param", "unitree=true", "--param", "mode=kinematic", "--param", "world=vision_test"),
    *("--param", "camera=false", "--param", "world_camera=false"),
    *("--remap", "/cmd_vel:=/sim/cmd_vel", "--remap", "/odom:=/sim/odom", "--remap", "/tf:=/sim/tf"),
    *("--remap", "/imu:=/sim/imu"),
]  # fmt: skip
# rpc_timeout_s: unitree_sdk2's 1 s is a network timeout; the sim's answer to `go2 hello` took longer
# on a host at load 34 (as test_go2_sim_bridge.py saw for StandUp).
DRIVER = ["run", "go2", "--param", "camera_rate_hz=0", "--param", "rpc_timeout_s=5"]


class Foreign(Node):
    name = "foreign_client"

    def __init__(self) -> None:
        super().__init__()
        self.status = Recorder()
        self.create_subscription(String, "/go2/status", lambda m: self.status(json.loads(m.data)), QOS_LATCHED)
        self.command = self.create_publisher(String, "/go2/command", QOS_DEFAULT)
        self.release = self.create_publisher(String, "/emergency_stop/release", QOS_DEFAULT)
        self.raw = self.create_publisher(Request, p.request_topic(p.SPORT_SERVICE), QOS_UNITREE_WRITER)

    def last(self) -> dict:
        items = self.status.msgs()
        return items[-1] if items else {}


def test_a_foreign_sport_controller_damps_or_is_reported(procs: Procs) -> None:
    foreign = Foreign()
    with running(foreign):
        procs.start(*SIM)
        driver = procs.start(*DRIVER)
        assert wait_for(lambda: foreign.last().get("connected") and foreign.last().get("mode") == "balance_stand", 60)
        guid = str(foreign.raw.guid)

        # Our own CLI goes through the driver, so it is not foreign.
        hello = subprocess.run([*GO2VLM, "go2", "hello"], capture_output=True, text=True, timeout=60, env=env())
        assert hello.returncode == 0 and "through the go2 driver" in hello.stdout, hello.stdout + hello.stderr
        assert foreign.last()["foreign_sport"]["requests"] == 0 and foreign.last()["estop"] is False

        foreign.raw.publish(p.build_request(p.BALANCE_STAND))
        assert wait_for(lambda: foreign.last()["foreign_sport"]["requests"] >= 1, 10)
        st = foreign.last()
        assert st["foreign_sport"]["policy"] == "damp"
        assert st["foreign_sport"]["writers"][guid]["node"] == "/foreign_client"
        assert st["foreign_sport"]["writers"][guid]["last_api"] == "BalanceStand"
        assert wait_for(lambda: foreign.last()["estop"] is True and foreign.last()["mode"] == "damping", 10)
        # Latched like an e-stop: a stand is refused until the deliberate release.
        foreign.command.publish(String(data="stand"))
        assert wait_for(lambda: (foreign.last().get("last_command") or {}).get("name") == "stand", 10)
        assert foreign.last()["last_command"]["result"].startswith("refused")
        foreign.release.publish(String(data="RELEASE"))
        assert wait_for(lambda: foreign.last()["estop"] is False, 10)

        # Policy "report": counted and named, nothing latched.
        procs.stop(driver)
        n = len(foreign.status)
        procs.start(*DRIVER, "--param", "foreign_sport=report")
        assert wait_for(lambda: len(foreign.status) > n and foreign.last().get("connected"), 30)
        foreign.raw.publish(p.build_request(p.HELLO))
        assert wait_for(lambda: foreign.last()["foreign_sport"]["requests"] >= 1, 10)
        time.sleep(1.5)
        assert foreign.last()["estop"] is False and foreign.last()["foreign_sport"]["policy"] == "report"
