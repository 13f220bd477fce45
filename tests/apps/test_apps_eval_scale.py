"""The eval at scale: the household world and its suites, the latency axis, and episodes on a Ray cluster.

Fast: the world, its assets and licences, what the suites resolve to, bad input (an object absent from
its world, a mesh that does not load, an unknown --latency, a cluster nobody answers) refused with one
line and exit 2 before any episode, the latency report. Slow: a local Ray cluster of two worker
processes gives the same outcomes as `--workers 2`; a task whose worker is killed is retried once, then
recorded as an error, and nothing is lost or duplicated; SIGTERM stops a Ray run as it stops workers."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from busutil import GO2VLM, env, wait_for

from go2vlm.apps.episodes.episode import Episode, graph_name, label_matches, node_overrides, target_body
from go2vlm.apps.episodes.outputs import append_jsonl, read_jsonl
from go2vlm.apps.episodes.report import write_report
from go2vlm.apps.episodes.suites import load_suite, world_bodies
from go2vlm.behavior.goals import parse_goal
from go2vlm.perception.answer_delay import AnswerDelay
from go2vlm.sim.worlds import WORLDS_DIR, build_world_xml

ASSETS = WORLDS_DIR.parent / "assets" / "household"


def _env() -> dict[str, str]:
    # The test's own loopback cluster: no token to hand round (recent Ray turns token auth on by default)
    return {**env(), "RAY_AUTH_MODE": "disabled"}


def _eval(out: Path, *args: str, timeout: float = 400) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*GO2VLM, "eval", "--out", str(out), "--no-progress", *args],
        capture_output=True, text=True, timeout=timeout, env=_env(),
    )  # fmt: skip


def _refused(proc: subprocess.CompletedProcess[str], out: Path, *words: str) -> None:
    """Exit 2, one line that says why, and no episode ran."""
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert len(lines) == 1 and lines[0].startswith("go2vlm eval: "), proc.stderr
    assert all(w in lines[0] for w in words), lines[0]
    assert not (out / "results.jsonl").exists()


# -- the world --------------------------------------------------------------------------------------


def test_household_world_has_real_objects_and_seeded_lighting() -> None:
    bodies = world_bodies("household")
    objects = {"teddy_bear", "duck", "soccer_ball", "tray", "cone", "toy_chest", "red_ball", "red_mug", "blue_mug",
               "red_lego_brick", "yellow_lego_brick", "box_1", "box_2", "box_3", "box_4"}  # fmt: skip
    assert objects <= set(bodies) and {"sofa", "coffee_table", "dining_table", "door"} <= set(bodies)
    assert len([b for b in bodies if b.startswith("red_")]) >= 3, "several objects of one colour"
    xml0, _ = build_world_xml("household", seed=0)
    assert xml0 == build_world_xml("household", seed=0)[0], "the same seed, the same light"
    assert xml0 != build_world_xml("household", seed=1)[0], "another seed, other light"
    assert build_world_xml("vision_test", seed=0)[0] == build_world_xml("vision_test", seed=1)[0], "no jitter asked"
    assert "<mesh" in xml0 and str(ASSETS.resolve()) in xml0


def test_household_assets_are_small_and_every_file_has_its_licence() -> None:
    files = sorted(p.name for p in ASSETS.iterdir() if p.name != "LICENSES.md")
    licences = (ASSETS / "LICENSES.md").read_text()
    assert files and all(f"`{name}`" in licences for name in files), files
    assert "zlib" in licences
    assert sum(p.stat().st_size for p in ASSETS.iterdir()) < 3 * 2**20


# -- goals, targets, suites -------------------------------------------------------------------------


def test_categories_and_referring_phrases_reach_the_model_whole() -> None:
    assert parse_goal("go to the teddy bear").target.label == "teddy bear"
    ref = parse_goal("go to the ball under the table").target
    assert (ref.label, ref.shape) == ("ball under the table", "ball")
    assert parse_goal("go to the red object nearest the door").target.color == "red"
    assert parse_goal("follow the red sphere").target.label == "red ball"  # colour-shape goals as before
    soccer = parse_goal("go to the soccer ball").target
    assert label_matches(soccer, "soccer_ball") and not label_matches(soccer, "red_ball")
    assert label_matches(parse_goal("go to the red ball").target, "red_sphere")
    names = list(world_bodies("household"))
    assert target_body("go to the red mug", names) == "red_mug"
    assert target_body("go to the ball under the table", names, "red_ball") == "red_ball"


def test_household_and_referring_suites() -> None:
    household, referring = load_suite("household"), load_suite("referring")
    assert household.episodes >= 60
    names = set(world_bodies("household"))
    for suite in (household, referring):
        for k in range(suite.episodes):
            ep = suite.episode(k, "oracle")
            assert target_body(ep.goal, sorted(names), ep.target) in names, ep
    ep = referring.episode(0, "oracle")
    assert ep.target == "red_ball" and graph_name(ep) == "episode_oracle_delay"
    delay = node_overrides(ep, 1.0, True)["answer_delay"]
    assert delay == {"latency_s": 0.0, "target_body": "red_ball", "target_label": "ball under the table"}
    way = node_overrides(ep, 1.0, True)["way_oracle"]  # frontier_choice vlm's answers: the body, half the view
    assert way["target_body"] == "red_ball" and 30.0 < way["half_view_deg"] < 40.0
    late = Episode.from_dict({**household.episode(0, "vlm").to_dict(), "answer_latency_s": 2.5})
    assert (
        graph_name(late) == "episode_vlm_delay" and node_overrides(late, 1.0, False)["answer_delay"]["latency_s"] == 2.5
    )
    goals = load_suite("goals").episode(0, "oracle")
    assert graph_name(goals) == "episode_oracle"  # no latency axis: the graph as before
    zero = Episode.from_dict({**goals.to_dict(), "answer_latency_s": 0.0})
    assert graph_name(zero) == "episode_oracle_delay", "every point of the axis, 0 too, runs one graph"
    with pytest.raises(ValueError, match="oracle and vlm"):
        Episode(world="household", goal="go to the duck", perception="color", answer_latency_s=1.0)


def test_answers_held_back_leave_on_the_clock() -> None:
    delay: AnswerDelay[str] = AnswerDelay(latency_s=2.0)
    assert delay.offer(10.0, "a") == []
    assert delay.due(11.9) == []
    assert delay.offer(11.0, "b") == []  # busy: a slower model would not have answered
    assert delay.due(12.0) == [(10.0, "a")]
    assert delay.counters == {"taken": 1, "skipped": 1, "answered": 1}


def test_the_report_draws_success_and_spl_against_latency(tmp_path: Path) -> None:
    for lat, wins in ((0.0, 4), (2.5, 3), (5.0, 1)):
        config = {"run_id": f"goals-oracle-{lat}", "suite": "goals", "perception": "oracle", "model": None,
                  "seed": 0, "fast": True, "rtf": None, "answer_latency_s": lat, "suite_file": "x",
                  "suite_sha256": "0" * 64, "git": {}, "machine": {}}  # fmt: skip
        for k in range(4):
            m = {"success": k < wins, "spl": 0.9 if k < wins else 0.0, "kind": "go_to", "time_to_goal_s": 10.0,
                 "collisions": 0, "fell": False, "wall_s": 5.0, "grounding": None, "vlm": None}  # fmt: skip
            append_jsonl(tmp_path / "results.jsonl", {"config": config, "index": k, "metrics": m})
    summary = write_report(tmp_path)
    rows = sorted(summary["groups"], key=lambda g: g["answer_latency_s"])
    assert [(g["answer_latency_s"], g["success"]) for g in rows] == [(0.0, 4), (2.5, 3), (5.0, 1)]
    assert (tmp_path / "success_spl_vs_added_latency.png").read_bytes()[:4] == b"\x89PNG"
    assert "| goals | oracle | - | 2.5 | 4 |" in (tmp_path / "report.md").read_text()


# -- bad input: one line, exit 2, before any episode --------------------------------------------------


def test_bad_input_is_refused_before_any_episode(tmp_path: Path) -> None:
    absent = tmp_path / "absent.yaml"
    absent.write_text("name: absent\ntasks:\n  - world: household\n    goal: go to the giraffe\n")
    _refused(_eval(tmp_path, "--suite", str(absent), "--perception", "oracle"), tmp_path, "giraffe", "household")
    wrong = tmp_path / "wrong_target.yaml"
    wrong.write_text("name: wrong\ntasks:\n  - world: household\n    goal: go to the ball under the table\n"
                     "    target: ball_under_the_sofa\n")  # fmt: skip
    _refused(_eval(tmp_path, "--suite", str(wrong), "--perception", "oracle"), tmp_path, "ball_under_the_sofa")
    # A world whose mesh does not load.
    (tmp_path / "broken.obj").write_text("v 0 0 0\nthis is no mesh\nf 1 7 9\n")
    world = tmp_path / "broken_world.xml"
    world.write_text(
        '<mujoco><compiler meshdir="."/><asset><mesh name="m" file="broken.obj"/></asset><worldbody>'
        '<geom type="plane" size="5 5 0.1"/><body name="vase" pos="2 0 0"><geom type="mesh" mesh="m"/></body>'
        "</worldbody></mujoco>"
    )
    broken = tmp_path / "broken.yaml"
    broken.write_text(f"name: broken\ntasks:\n  - world: {world}\n    goal: go to the vase\n")
    _refused(_eval(tmp_path, "--suite", str(broken), "--perception", "oracle"), tmp_path, "does not load")
    for latency, words in (("abc", ("'abc'", "--latency")), ("1,-2", ("-2", "0..60")), ("1,1", ("twice",))):
        proc = _eval(tmp_path, "--suite", "smoke", "--perception", "oracle", "--latency", latency, timeout=120)
        _refused(proc, tmp_path, *words)
    proc = _eval(tmp_path, "--suite", "smoke", "--perception", "color", "--latency", "0,1", timeout=120)
    _refused(proc, tmp_path, "--latency", "oracle and vlm")


def test_a_cluster_nobody_answers_is_a_clear_error(tmp_path: Path) -> None:
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.monotonic()
    proc = _eval(tmp_path, "--suite", "smoke", "--perception", "color", "--ray", f"127.0.0.1:{port}", timeout=120)
    _refused(proc, tmp_path, "cannot reach the Ray cluster", f"127.0.0.1:{port}")
    assert time.monotonic() - t0 < 60, "not a hang"


# -- a local Ray cluster of two worker processes -----------------------------------------------------


@pytest.fixture(scope="module")
def ray_cluster() -> Iterator[str]:
    """`ray start --head` with 2 CPUs (two worker processes at a time) on loopback; its address."""
    pytest.importorskip("ray")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    temp = tempfile.mkdtemp(prefix="rt-", dir="/tmp")  # short: Ray's socket paths must fit 107 bytes
    ray = Path(sys.executable).parent / "ray"
    cmd = [str(ray), "start", "--head", "--block", f"--port={port}", "--node-ip-address=127.0.0.1",
           "--num-cpus=2", "--include-dashboard=false", f"--temp-dir={temp}",
           f"--object-store-memory={128 * 2**20}"]  # fmt: skip
    head = subprocess.Popen(
        cmd, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    address = f"127.0.0.1:{port}"
    try:

        def up() -> bool:
            with socket.socket() as s:
                return s.connect_ex(("127.0.0.1", port)) == 0

        assert wait_for(up, timeout=120), "ray start --head did not come up"
        yield address
    finally:
        os.killpg(head.pid, signal.SIGTERM)  # the head and every process it started, nothing else
        try:
            head.wait(timeout=30)
        except subprocess.TimeoutExpired:
            pass
        try:
            os.killpg(head.pid, signal.SIGKILL)  # a raylet or GCS that outlived the head
        except ProcessLookupError:
            pass
        shutil.rmtree(temp, ignore_errors=True)


def _outcomes(out: Path) -> dict[int, tuple[str, bool, str]]:
    return {line["index"]: (line["episode"]["id"], line["metrics"]["success"], line["metrics"]["final_state"])
            for line in read_jsonl(out / "results.jsonl")}  # fmt: skip


@pytest.mark.slow
def test_ray_tasks_equal_two_workers(tmp_path: Path, ray_cluster: str) -> None:
    args = ["--suite", "smoke", "--perception", "color", "--fast", "--episodes", "3"]
    on_ray = _eval(tmp_path / "ray", *args, "--ray", ray_cluster)
    assert on_ray.returncode == 0, on_ray.stderr[-3000:]
    workers = _eval(tmp_path / "workers", *args, "--workers", "2")
    assert workers.returncode == 0, workers.stderr[-3000:]
    assert _outcomes(tmp_path / "ray") == _outcomes(tmp_path / "workers")
    assert sorted(_outcomes(tmp_path / "ray")) == [0, 1, 2]
    lines = read_jsonl(tmp_path / "ray" / "results.jsonl")
    assert {line["ray"] for line in lines} == {ray_cluster}
    assert lines[0]["config"]["run_id"] == read_jsonl(tmp_path / "workers" / "results.jsonl")[0]["config"]["run_id"]
    # Each Ray worker process on a DDS domain of its own.
    by_pid = {line["worker"]["pid"]: line["worker"]["domain"] for line in lines}
    assert len(set(by_pid.values())) == len(by_pid)
    summary = json.loads((tmp_path / "ray" / "summary.json").read_text())
    assert summary["groups"][0]["episodes"] == 3


def _task_pids() -> set[int]:
    ps = subprocess.run(["ps", "-eo", "pid=,args="], capture_output=True, text=True).stdout
    return {int(line.split()[0]) for line in ps.splitlines() if "ray::_episode_task" in line}


@pytest.mark.slow
def test_a_killed_task_is_retried_once_then_recorded_as_an_error(tmp_path: Path, ray_cluster: str) -> None:
    args = ["eval", "--no-progress", "--suite", "smoke", "--perception", "color", "--fast", "--ray", ray_cluster]
    for kills, out in ((1, tmp_path / "once"), (2, tmp_path / "twice")):
        proc = subprocess.Popen([*GO2VLM, *args, "--episodes", "1", "--out", str(out)], env=_env(),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
        killed: set[int] = set()
        try:
            for _ in range(kills):
                assert wait_for(lambda k=killed: bool(_task_pids() - k), timeout=180), "no task ran"
                pid = min(_task_pids() - killed)
                os.kill(pid, signal.SIGKILL)
                killed.add(pid)
            stdout, stderr = proc.communicate(timeout=300)
        finally:
            if proc.poll() is None:
                proc.kill()
        lines = read_jsonl(out / "results.jsonl")
        if kills == 1:  # retried: the episode's one result
            assert proc.returncode == 0, stderr[-3000:]
            assert [line["index"] for line in lines] == [0]
            assert not (out / "errors.jsonl").exists()
        else:  # the retry died too: an error, no result, and the run says so
            assert proc.returncode == 1, stderr[-3000:]
            assert lines == []
            errors = read_jsonl(out / "errors.jsonl")
            assert [e["index"] for e in errors] == [0] and "died" in errors[0]["error"]
            assert "smoke/000" in stderr and "0/1 episodes" in stdout


@pytest.mark.slow
def test_sigterm_stops_a_ray_run_as_it_stops_workers(tmp_path: Path, ray_cluster: str) -> None:
    """ray.init puts its own SIGTERM handler (sys.exit) in place of the eval's: the eval keeps its own, so
    a terminated Ray run keeps what finished, writes its report, exits 143, and --resume finishes it."""
    args = [*GO2VLM, "eval", "--no-progress", "--suite", "smoke", "--perception", "color", "--fast",
            "--episodes", "3", "--ray", ray_cluster, "--out", str(tmp_path)]  # fmt: skip
    proc = subprocess.Popen(args, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert wait_for(lambda: bool(_task_pids()), timeout=180), "no task ran"
        proc.send_signal(signal.SIGTERM)
        _, stderr = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, stderr[-3000:]
    assert "--resume" in stderr and (tmp_path / "summary.json").is_file()
    done = {line["index"] for line in read_jsonl(tmp_path / "results.jsonl")}
    assert len(done) < 3
    resumed = subprocess.run([*args, "--resume"], env=_env(), capture_output=True, text=True, timeout=400)
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert sorted(line["index"] for line in read_jsonl(tmp_path / "results.jsonl")) == [0, 1, 2]


@pytest.mark.slow
def test_household_oracle_and_color_on_a_local_ray(tmp_path: Path) -> None:
    """The issue's command, lean: two household episodes each for the oracle and the colour grounder as
    Ray tasks on a Ray this run starts; the report puts them side by side, and the gap shows."""
    listed = subprocess.run([*GO2VLM, "eval", "--list"], capture_output=True, text=True, timeout=120, env=_env())
    assert "household" in listed.stdout and "referring" in listed.stdout
    for variant in ("oracle", "color"):
        proc = _eval(tmp_path, "--suite", "household", "--perception", variant, "--fast", "--episodes", "2",
                     "--ray", "--workers", "2", timeout=900)  # fmt: skip
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert "Ray (local)" in proc.stdout
    groups = {g["perception"]: g for g in json.loads((tmp_path / "summary.json").read_text())["groups"]}
    assert groups["oracle"]["episodes"] == groups["color"]["episodes"] == 2
    assert groups["oracle"]["success"] >= 1, groups["oracle"]  # the teddy bear, by category
    assert groups["color"]["success"] == 0, "the colour grounder cannot read 'teddy bear'"
    report = (tmp_path / "report.md").read_text()
    assert "| household | oracle |" in report and "| household | color |" in report
    for line in read_jsonl(tmp_path / "results.jsonl"):
        assert line["ray"] == "local" and line["metrics"]["target_body"] == "teddy_bear"


def test_eval_frontier_sets_the_commanders_frontier_choice() -> None:
    from go2vlm.cli.eval import _with_frontier

    assert _with_frontier({}, None) == {}
    assert _with_frontier({"sim": {"seed": 1}}, "vlm") == {"sim": {"seed": 1}, "commander": {"frontier_choice": "vlm"}}
    assert _with_frontier({"commander": {"frontier_choice": "nearest"}}, "vlm")["commander"]["frontier_choice"] == (
        "nearest"
    )  # an explicit --param wins
