"""The e-stop belongs to the robot, and the apps say so: `go2vlm demo` and `go2vlm eval` refuse to start
on a latched robot (exit 2, one line: since when, who latched it, the release command) before the sim
starts, whether the latch is a gate's latch file or a `go2vlm estop` holding it on the domain;
`go2vlm estop --release` releases a stored latch that no gate keeps; and a latch during a run is in
metrics.json and the summary, whose result then says the robot was stopped. Real processes, real DDS."""

from __future__ import annotations

import json
import os
import subprocess
import threading
import time
from pathlib import Path

import pytest
from busutil import GO2VLM, Procs, Recorder, env, wait_for

from go2vlm.apps.episodes.demo import goal_summary
from go2vlm.apps.episodes.latch import estop_metrics
from go2vlm.apps.episodes.runner import EpisodeResult
from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node, running
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.safety.estop import LatchFile, latch_path

DOMAIN = int(os.environ["ROS_DOMAIN_ID"])  # the session's own domain (tests/conftest.py)


def _one_line(out: subprocess.CompletedProcess[str], verb: str) -> str:
    assert "Traceback" not in out.stderr + out.stdout, out.stderr
    lines = [line for line in out.stderr.splitlines() if line.startswith(f"go2vlm {verb}")]
    assert len(lines) == 1, out.stderr
    return lines[0]


def _run(*args: str) -> tuple[subprocess.CompletedProcess[str], float]:
    t0 = time.monotonic()
    out = subprocess.run([*GO2VLM, *args], capture_output=True, text=True, timeout=120, env=env())
    return out, time.monotonic() - t0


def test_demo_refuses_a_robot_its_latch_file_holds_then_the_release_frees_it(tmp_path: Path) -> None:
    store = LatchFile(latch_path("sim", DOMAIN))  # what a gate killed while latched leaves behind
    store.save(True, "safety", since=time.time() - 60, why="health: tilt 52 deg")
    out, took = _run("demo", "--out", str(tmp_path / "run"), "--no-progress", "--no-video")
    print(f"refused in {took:.1f} s")
    assert out.returncode == 2, out.stderr
    line = _one_line(out, "demo")
    assert "latched for robot 'sim'" in line and f"domain {DOMAIN}" in line and "since 20" in line
    assert "by safety" in line and "health: tilt 52 deg" in line and "`go2vlm estop --release`" in line
    assert not (tmp_path / "run").exists(), "refused before anything started or was written"
    assert "[sim]" not in out.stderr, "the sim never started"

    rel = subprocess.run([*GO2VLM, "estop", "--release", "--wait", "0.5", "--timeout", "1"], capture_output=True,
                         text=True, timeout=60, env=env())  # fmt: skip
    assert rel.returncode == 0, rel.stderr
    assert "released the stored latch of robot 'sim'" in rel.stdout
    state = store.read()
    assert state is not None and state.engaged is False


def test_demo_refuses_while_an_estop_holder_holds_the_domain(procs: Procs, tmp_path: Path) -> None:
    holder = procs.start("estop", stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(holder.stdout or []), daemon=True).start()
    assert wait_for(lambda: any("HOLDING" in line for line in lines), 15), lines
    out, took = _run("demo", "--robot", "go2", "--out", str(tmp_path / "run"), "--no-progress", "--no-video")
    print(f"refused in {took:.1f} s")
    assert out.returncode == 2, out.stderr
    line = _one_line(out, "demo")
    assert "latched for robot 'go2'" in line and "go2vlm_estop" in line and "held on /emergency_stop" in line
    assert "`go2vlm estop --release`" in line
    assert not (tmp_path / "run").exists()


def test_eval_refuses_a_latched_robot_on_its_domain(tmp_path: Path) -> None:
    LatchFile(latch_path("sim", DOMAIN)).save(True, "gate_b", why="/emergency_stop from /teleop")
    args = ["eval", "--suite", "smoke", "--perception", "color", "--fast", "--no-progress"]
    out, _ = _run(*args, "--domain", str(DOMAIN), "--out", str(tmp_path / "ev"))
    assert out.returncode == 2, out.stderr
    line = _one_line(out, "eval")
    assert "latched for robot 'sim'" in line and "by gate_b" in line and "`go2vlm estop --release`" in line
    assert not (tmp_path / "ev").exists(), "refused before any worker started or anything was written"


def test_eval_workers_leave_latched_domains_out() -> None:
    from go2vlm.apps.episodes.evaluate import EVAL_DOMAINS, EvalOptions, _episodes, _latched
    from go2vlm.apps.episodes.suites import load_suite

    suite = load_suite("smoke")
    opts = EvalOptions(suite="smoke", perception="color", out=Path("unused"), fast=True)
    episodes = _episodes(suite, opts, suite.seed, {})
    d = EVAL_DOMAINS[0] + 7
    assert d not in _latched(episodes, opts)
    LatchFile(latch_path("sim", d)).save(True, "safety", why="test")
    assert _latched(episodes, opts) == (d,)


def test_estop_metrics_and_a_goal_summary_that_says_stopped() -> None:
    events = [(9.0, False, ""), (12.0, True, "/emergency_stop from /go2vlm_estop"), (20.0, False, ""),
              (25.0, True, "health: tilt")]  # fmt: skip
    m = estop_metrics(events, t0=10.0, t_end=40.0)
    assert m["latched"] and m["latched_at_end"] and m["latched_s"] == 23.0
    assert m["latches"][0] == {"at_s": 2.0, "why": "/emergency_stop from /go2vlm_estop", "for_s": 8.0, "released": True}
    assert m["latches"][1]["at_s"] == 15.0 and m["latches"][1]["released"] is False
    assert estop_metrics([(5.0, True, "restored")], 10.0, 12.0)["latches"][0]["at_s"] == 0.0  # latched from the start
    assert estop_metrics([], 0.0, 1.0) == {"latched": False, "latched_s": 0.0, "latched_at_end": False, "latches": []}

    from go2vlm.apps.episodes.episode import Episode

    ep = Episode(world="vision_test", goal="go to the blue cylinder")
    metrics = {
        "goal": ep.goal, "goal_reached": False, "kind": "go_to", "world": ep.world, "mode": "dynamic",
        "sim_s": 30.0, "wall_s": 31.0, "final_state": "not_found", "final_reason": "no blue cylinder in view",
        "states": ["searching", "not_found"], "target_body": "blue_cylinder", "time_to_goal_s": None,
        "final_distance_m": 4.0, "collisions": 0, "min_clearance_m": 1.0, "spl": 0.0, "path_length_m": 0.0,
        "perception": "color", "estop": m, "stopped": True, "result": "stopped",
    }  # fmt: skip
    text = goal_summary(EpisodeResult(ep, metrics, {}))
    first, second = text.splitlines()[:2]
    assert ": STOPPED" in first and "NOT reached" not in first
    assert "STOPPED by the e-stop at 2.0 s for 23.0 s, 2 latches" in second
    assert "final state:     stopped: the e-stop held the robot" in text


class _Estop(Node):
    name = "latch_during_run"


@pytest.mark.slow  # a demo at real time
def test_a_latch_during_a_run_is_in_metrics_and_the_summary(procs: Procs, tmp_path: Path) -> None:
    """The e-stop latches 1 s into a demo and is released 2 s later: metrics.json and the summary say
    when, for how long and why, and the demo exits 1 (stopped)."""
    probe = _Estop()
    clock = Recorder()
    probe.create_subscription(Clock, "/clock", clock, QOS_DEFAULT)
    estop = probe.create_publisher(Bool, "/emergency_stop", QOS_LATCHED)
    release = probe.create_publisher(String, "/emergency_stop/release", QOS_DEFAULT)

    def sim_t() -> float:
        msgs = clock.msgs()
        return msgs[-1].clock.to_sec() if msgs else -1.0

    args = ["demo", "--out", str(tmp_path), "--no-progress", "--no-video", "--mode", "kinematic", "--duration", "6"]
    with running(probe):
        proc = procs.start(*args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        assert wait_for(lambda: sim_t() >= 1.0, 120), "the demo's sim did not start"
        estop.publish(Bool(data=True))
        assert wait_for(lambda: sim_t() >= 3.0, 60)
        release.publish(String(data="RELEASE"))
        estop.close()  # no latched `true` left for the gate to hear again
        out, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err[-3000:]
    m = json.loads((tmp_path / "metrics.json").read_text())
    e = m["estop"]
    assert m["stopped"] is True and e["latched"] is True and len(e["latches"]) == 1, e
    latch = e["latches"][0]
    assert 0.5 <= latch["at_s"] <= 3.0 and 0.5 <= latch["for_s"] <= 4.0 and latch["released"] is True, latch
    assert "latch_during_run" in latch["why"], latch
    assert "STOPPED by the e-stop at" in out and "latch_during_run" in out, out
    assert "go2vlm demo: STOPPED by the e-stop" in err, err[-2000:]
