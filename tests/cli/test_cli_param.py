"""`go2vlm param` end to end: the follow article's pipeline (`go2vlm launch follow_test_pattern`) in
one process, `go2vlm param` in others, /cmd_vel watched here. Tuning the follower's gain changes
/cmd_vel; refused changes say why and change nothing; the safety gate's limits go down live and
never up."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from busutil import GO2VLM, Procs, Recorder, env, wait_for

from go2vlm.bus import Node, build_node_config, load_params_file, running
from go2vlm.msgs.geometry_msgs import Twist

# The test pattern's red circle is at x = (450 - 320) / 320 = 0.40625 of the half width: with the
# follower's kp_angular 0.8, angular.z = -0.325 (follow_test_pattern.yaml); with 0.4, -0.1625.
X = 0.40625


def cli(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*GO2VLM, "param", *args], capture_output=True, text=True, timeout=timeout, env=env())


def settles(rec: Recorder, wz: float) -> bool:
    msgs = rec.msgs()
    return bool(msgs) and abs(msgs[-1].angular.z - wz) < 1e-9


@pytest.fixture
def pipeline(procs: Procs) -> Recorder:
    procs.start("launch", "follow_test_pattern")
    rec = Recorder()
    watcher = Node(node_name="param_test_watch", parameter_services=False)
    watcher.create_subscription(Twist, "/cmd_vel", rec)
    with running(watcher):
        assert wait_for(lambda: settles(rec, -0.8 * X), 60), f"/cmd_vel never settled: {rec.msgs()[-1:]}"
        yield rec


def test_tune_the_follower_and_the_gate_live(pipeline: Recorder, tmp_path: Path) -> None:
    rec = pipeline
    out = cli("set", "follower", "kp_angular", "0.4")
    assert (out.returncode, out.stdout.strip()) == (0, "Set parameter kp_angular successful"), out.stderr
    assert wait_for(lambda: settles(rec, -0.4 * X), 20), f"/cmd_vel is {rec.msgs()[-1].angular.z}"

    out = cli("get", "follower", "kp_angular")
    assert (out.returncode, out.stdout.strip()) == (0, "Double value is: 0.4")
    out = cli("list", "follower")
    assert out.returncode == 0 and "  kp_angular" in out.stdout.splitlines() and "  use_sim_time" in out.stdout
    out = cli("describe", "follower", "kp_angular", "rate_hz")
    assert out.returncode == 0
    assert "Parameter name: kp_angular\n  Type: double\n" in out.stdout
    kp, rate = out.stdout.split("Parameter name: rate_hz")
    assert "Read only: false" in kp and "Max value: 20.0" in kp and "Read only: true" in rate

    # Refused: out of range, wrong type, read-only. One line each, the node's reason, nothing changes.
    for args, reason in [
        (("kp_angular", "50"), "parameter 'kp_angular': 50.0 is above the maximum 20.0"),
        (("kp_angular", "fast"), "'kp_angular' is a double, setting it to a string is not allowed"),
        (("rate_hz", "5"), "parameter 'rate_hz' is read-only"),
    ]:
        out = cli("set", "follower", *args)
        assert out.returncode == 2, out
        assert out.stderr.count("\n") == 1 and reason in out.stderr and "Traceback" not in out.stderr
    assert cli("get", "follower", "kp_angular").stdout.strip() == "Double value is: 0.4"
    assert settles(rec, -0.4 * X)

    # The gate: lowering max_vyaw clamps /cmd_vel at once; raising is refused, under the ceiling or above it.
    out = cli("set", "safety", "max_vyaw", "0.1")
    assert out.returncode == 0, out.stderr
    assert wait_for(lambda: settles(rec, -0.1), 20), f"/cmd_vel is {rec.msgs()[-1].angular.z}"
    n = len(rec)
    out = cli("set", "safety", "max_vyaw", "0.5")
    assert out.returncode == 2 and "loosening a safety limit at runtime is refused (max_vyaw 0.1 -> 0.5)" in out.stderr
    out = cli("set", "safety", "max_vyaw", "5")
    assert out.returncode == 2 and "above the maximum 4.0" in out.stderr
    assert wait_for(lambda: len(rec) > n + 10 and settles(rec, -0.1), 20), f"/cmd_vel is {rec.msgs()[-1].angular.z}"
    assert all(abs(m.angular.z) <= 0.1 + 1e-9 for m in rec.msgs()[n:]), "a refused raise changed nothing"

    # dump is a params file that --params-file takes.
    out = cli("dump", "follower")
    assert out.returncode == 0 and out.stdout.startswith("/follower:\n  ros__parameters:\n")
    path = tmp_path / "follower.yaml"
    path.write_text(out.stdout)
    from go2vlm.behavior.follower_node import FollowerConfig

    config, base = build_node_config(FollowerConfig, load_params_file(path, "follower"), node="follower")
    assert (config.kp_angular, config.rate_hz, base.use_sim_time) == (0.4, 20.0, False)


def test_no_such_node_or_parameter(pipeline: Recorder) -> None:
    out = cli("get", "nobody", "kp_angular", "--timeout", "1")
    assert out.returncode == 1 and out.stderr.count("\n") == 1
    assert "service /nobody/get_parameters is not available" in out.stderr
    out = cli("get", "follower", "kp_nope")
    assert out.returncode == 2 and "node /follower does not declare parameter(s) 'kp_nope'" in out.stderr
    out = cli("set", "follower", "kp_angular")
    assert out.returncode == 2 and "expected NAME VALUE pairs" in out.stderr
