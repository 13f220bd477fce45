"""Every packaged launch file loads, names only real nodes, builds every node's parameters, opens with a
header comment that says what it runs, and keeps the safety rules: one safety gate wherever something
can move, a closed loop in the sim on the sim's clock. The VLM launch files are checked against
what they promise (the VLM article's world and camera; the served model on the real Go2)."""

from __future__ import annotations

import pytest

from go2vlm.bus import build_config
from go2vlm.cli.args import node_params
from go2vlm.launch.launcher import LaunchError, available, check_entries, load_launch, resolve, with_overrides
from go2vlm.robot_profile import DEFAULT_ROBOT, profile
from go2vlm.safety.gate_node import SafetyGateConfig, limits_of

ROBOTS = ("sim", "go2")
BEHAVIOURS = ("follower", "commander")


def _by_kind(name: str) -> dict[str, dict]:
    _, entries = load_launch(name)
    return {e.kind: e.params for e in entries}


@pytest.mark.parametrize("name", available())
def test_every_packaged_launch_file_loads_and_checks(name: str) -> None:
    path, entries = load_launch(name)
    if name.startswith("episode_"):  # the episode runner sets the model (--model) of its graphs' vlm node
        entries = with_overrides(entries, {e.name: {"model": "m"} for e in entries if e.kind == "vlm"})
    check_entries(entries)  # every node's parameters build (imports the node classes, no model loads)
    header = path.read_text().splitlines()
    assert header and header[0].startswith("# "), f"{name}: opens with a comment that says what it runs"
    kinds = [e.kind for e in entries]
    if any(k in BEHAVIOURS for k in kinds):  # something can move: exactly one gate
        assert kinds.count("safety") == 1, name
    assert all(kinds.count(k) <= 1 for k in ROBOTS), name  # one robot of each kind (follow_go2_sim: both)
    if "sim" in kinds and "safety" in kinds:  # a closed loop in the sim runs on the sim's clock
        assert all(e.params.get("use_sim_time") is True for e in entries), name
    if "safety" in kinds:  # the gate names the robot it commands: the go2 driver's where there is one
        gate = next(e.params for e in entries if e.kind == "safety")
        robot = "go2" if "go2" in kinds else "sim"
        assert gate.get("robot", DEFAULT_ROBOT) == robot, f"{name}: the gate commands {robot}"
        assert "health_topic" not in gate, f"{name}: the health topic is the robot profile's ({robot})"


def test_the_gate_reads_the_robot_profile() -> None:
    """The robot's facts reach the gate through its profile: ceilings, health topic, footprint."""
    for robot, health in (("sim", "/lowstate"), ("go2", "/go2/lowstate")):
        cfg = build_config(SafetyGateConfig, {"robot": robot})
        assert cfg.health_input == health == profile(robot).health_topic
        assert limits_of(cfg).ceiling == profile(robot).ceilings
    go2 = {e.kind: e for e in with_overrides(load_launch("goal_go2")[1], {})}
    cfg = build_config(SafetyGateConfig, go2["safety"].params)
    assert cfg.health_input == "/go2/lowstate"  # the drift this test is here for: goal_go2 without it


def test_vlm_sim_is_the_vlm_articles_system() -> None:
    nodes = _by_kind("vlm_sim")
    assert set(nodes) == {"sim", "vlm"}  # nothing moves: no behaviour, no gate
    sim, vlm = nodes["sim"], nodes["vlm"]
    assert sim["world"] == "vision_test" and sim["world_camera"] is True  # article section 6.1
    assert (sim["world_camera_width"], sim["world_camera_height"], sim["world_camera_rate_hz"]) == (640, 480, 10.0)
    assert vlm["image_topic"] == "/world_camera/image_raw" and vlm["mode"] == "detect"
    assert vlm["model"] == "Qwen/Qwen2.5-VL-3B-Instruct" and vlm["max_new_tokens"] == 256  # article section 3.2
    assert set(vlm["labels"]) == {"red ball", "green box", "blue cylinder"}


def test_goal_launch_files_ground_the_goal_with_the_vlm() -> None:
    for name, robot in (("goal_sim", "sim"), ("goal_go2", "go2")):
        nodes = _by_kind(name)
        assert robot in nodes and nodes["vlm"]["mode"] == "detect", name
        assert nodes["target_tracker"]["grounding"] == "vlm", name
    assert _by_kind("goal_sim")["commander"]["goal"] == "go to the blue cylinder"
    go2 = _by_kind("goal_go2")
    assert go2["vlm"]["backend"] == "openai" and go2["vlm"]["base_url"].startswith("http")  # served off-board
    assert go2["go2"]["stand_on_start"] is False
    assert go2["safety"]["max_vx_forward"] <= 0.4


def test_command_line_params_override_a_launch_file() -> None:
    _, entries = load_launch("goal_go2")
    entries = with_overrides(
        entries, node_params(["vlm.base_url=http://10.0.0.5:8000/v1", "commander.goal=go to the red ball"])
    )
    check_entries(entries)
    by = {e.kind: e.params for e in entries}
    assert by["vlm"]["base_url"] == "http://10.0.0.5:8000/v1" and by["commander"]["goal"] == "go to the red ball"
    with pytest.raises(LaunchError, match="no node named"):
        with_overrides(entries, node_params(["nope.x=1"]))
    assert resolve("goal_sim").name == "goal_sim.yaml"
