"""What the robot base (robots/base.py) gives every robot end, checked on both of ours, the sim and the
go2 driver (no robot on the network), in process over real DDS: one posture vocabulary, checked the
same way; the e-stop first, refusing postures and naming who latched it; /cmd_vel clamped to the
robot profile's ceilings, a bad one refused by stopping; and the same status fields."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest
from busutil import Recorder, wait_for

from go2vlm.bus import QOS_LATCHED, Node, running
from go2vlm.bus.topics import EMERGENCY_STOP, GO2_COMMAND
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.robots.base import RobotEnd
from go2vlm.robots.go2 import protocol
from go2vlm.robots.go2.driver_node import Go2DriverNode
from go2vlm.robots.go2_sim import sim_node
from go2vlm.robots.go2_sim.sim_node import SimNode

ENDS = {
    "sim": {"mode": "kinematic", "world": "empty", "camera": False, "world_camera": False, "lidar": False},
    "go2": {"camera_rate_hz": 0.0, "lidar": False, "rpc_timeout_s": 0.2},
}


def test_one_posture_vocabulary() -> None:
    """The Go2's words (robots/go2/protocol.py) are the vocabulary of both robot ends and of `go2vlm go2`;
    the sim carries out every one of them, rise and hello included."""
    from go2vlm.cli.go2 import POSTURES as CLI_POSTURES

    assert tuple(SimNode.postures) == tuple(Go2DriverNode.postures) == protocol.POSTURES == CLI_POSTURES
    assert set(sim_node.POSTURES) == set(protocol.POSTURES)
    assert SimNode.estop_postures == Go2DriverNode.estop_postures == protocol.ESTOP_ALLOWED
    assert SimNode.posture_topic == Go2DriverNode.posture_topic == GO2_COMMAND
    assert issubclass(SimNode, RobotEnd) and issubclass(Go2DriverNode, RobotEnd)


class _Probe(Node):
    name = "robot_base_probe"


@pytest.fixture(params=sorted(ENDS))
def end(request: pytest.FixtureRequest) -> Iterator[tuple[RobotEnd, _Probe, Recorder]]:
    node = make_node(request.param, params=ENDS[request.param])
    assert isinstance(node, RobotEnd)
    probe = _Probe()
    status = Recorder()
    node.status_topic.subscription(probe, lambda m: status(json.loads(m.data)))
    with running(node, probe):
        yield node, probe, status


def _last(status: Recorder) -> dict:
    msgs = status.msgs()
    return msgs[-1] if msgs else {}


def _result(status: Recorder, word: str) -> str | None:
    last = _last(status).get("last_command") or {}
    return last.get("result") if last.get("name") == word else None


def test_the_shared_robot_end(end: tuple[RobotEnd, _Probe, Recorder]) -> None:
    node, probe, status = end
    # /cmd_vel: clamped to the robot profile's ceilings; a non-finite one is refused by stopping.
    c = node.profile.ceilings
    node._on_cmd_vel(Twist(linear=Vector3(9.0, -5.0, 0.0), angular=Vector3(0.0, 0.0, 20.0)))
    assert node.command() == (c.vx_forward, -c.vy, c.vyaw)
    node._on_cmd_vel(Twist(linear=Vector3(float("nan"), 0.0, 0.0)))
    assert node.command() == (0.0, 0.0, 0.0) and node.counters.get("bad_cmd_vel") == 1
    node._on_cmd_vel(Twist(linear=Vector3(0.3, 0.0, 0.0)))
    assert node.command() == (0.3, 0.0, 0.0)

    # Postures: one vocabulary, checked the same way; the same status fields.
    command = GO2_COMMAND.publisher(probe)
    estop = EMERGENCY_STOP.publisher(probe, qos=QOS_LATCHED)
    assert wait_for(lambda: command.matched > 0 and estop.matched > 0 and len(status) > 0, 20)
    for key in ("estop", "estop_why", "commander", "last_command"):
        assert key in _last(status), _last(status)
    command.publish(String(data="fly"))
    assert wait_for(lambda: _result(status, "fly") == "unknown command", 10), _last(status)
    assert node.counters.get("bad_command") == 1

    # The e-stop: the command is zero, the status names who latched it, postures that stand or move
    # the robot are refused, the stops are not.
    estop.publish(Bool(data=True))
    assert wait_for(lambda: _last(status).get("estop") is True, 10), _last(status)
    assert node.command() == (0.0, 0.0, 0.0)
    assert "robot_base_probe" in _last(status)["estop_why"], "the status names who latched it"
    for word in ("stand", "rise", "hello"):
        command.publish(String(data=f" {word.upper()} "))
        assert wait_for(lambda w=word: _result(status, w) == "refused: emergency stop latched", 10), _last(status)
    assert node.counters.get("refused_command") == 3
    command.publish(String(data="stop"))  # allowed while latched
    assert wait_for(lambda: _result(status, "stop") is not None, 10), _last(status)
    assert _result(status, "stop") != "refused: emergency stop latched"
