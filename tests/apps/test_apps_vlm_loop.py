"""The VLM drives the robot, in the sim, with real processes' worth of real parts: the shipped tiny
Qwen2.5-VL grounder (tests/data/tiny_grounder, trained on our sim's renders) in the vlm node, the
target_tracker, the commander, the safety gate and the MuJoCo sim, over real DDS, through the episode
runner behind `go2vlm demo --perception vlm`. Both backends: local (transformers, in this process)
and openai (a real `transformers serve` on loopback).

Episodes: tests/data/vlm_loop_suite.yaml, "go to the blue cylinder" from spawns drawn (seeded) 2-3 m
in front of it, facing it within 20 degrees. The local test runs episode 0, the served one episode 1:
the first two draws, not picked. Sim at half real time, so a busy CI machine's CPU model still answers
a few times per sim second (what this tests is the loop, not the model's speed; docs/benchmarks.md has
what latency does).

Asserted from the sim's ground truth: reached (within 1 m of the cylinder's surface) before the
timeout, zero collisions, and no forward motion unless the tracker had confirmed the target in the
1.5 s before (the commander's lost timeout + the gate's ramp)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("mujoco")

from testing.conftest import grounder_ckpt, grounder_server  # noqa: E402, F401

from go2vlm.apps.episodes import RunOptions, run_episode  # noqa: E402
from go2vlm.apps.episodes.episode import vlm_node_params  # noqa: E402
from go2vlm.apps.episodes.suites import load_suite  # noqa: E402
from go2vlm.bus import ShutdownRequested  # noqa: E402

pytestmark = pytest.mark.slow

SUITE = Path(__file__).resolve().parents[1] / "data" / "vlm_loop_suite.yaml"
RTF = 0.5


def run_vlm_episode(k: int, model: str, base_url: str | None = None) -> dict[str, Any]:
    from testing_support.tiny_grounder import grounder_node_params

    ep = load_suite(str(SUITE)).episode(k, "vlm")
    params = vlm_node_params("vlm", model, base_url, {"vlm": grounder_node_params()})
    ep = dataclasses.replace(ep, params=params)
    return run_episode(ep, RunOptions(rtf=RTF, video=False), ShutdownRequested()).metrics


def assert_reached_safely(m: dict[str, Any]) -> None:
    brief = {k: m[k] for k in ("states", "final_state", "final_distance_m", "collisions", "tracker", "vlm", "spawn")}
    assert m["success"] and m["final_state"] == "reached", brief
    assert m["final_distance_m"] <= 1.0 and m["collisions"] == 0 and not m["fell"], brief
    tr = m["tracker"]
    assert tr["forward_cmds"] > 0 and tr["forward_unconfirmed"] == 0, brief  # moved only toward a confirmed target
    assert tr["tracking_frames"] > 0 and tr["carried_fraction"] > 0.5, brief  # the tracker carried it between answers
    g = m["grounding"]
    assert g["answers"] >= 3 and g["hits"] >= 1, brief  # the model really grounded it (scored against ground truth)
    assert m["vlm"]["inferences"] >= 3 and m["vlm"]["latency_ms_p50"] is not None


def test_go_to_the_blue_cylinder_grounded_by_the_local_tiny_vlm(grounder_ckpt: Path) -> None:  # noqa: F811
    m = run_vlm_episode(0, str(grounder_ckpt))
    assert m["vlm"]["backend"] == "transformers"
    assert_reached_safely(m)


def test_go_to_the_blue_cylinder_grounded_by_a_served_tiny_vlm(grounder_ckpt: Path, grounder_server: str) -> None:  # noqa: F811
    m = run_vlm_episode(1, str(grounder_ckpt), grounder_server)  # transformers serve names the model by its path
    assert m["vlm"]["backend"] == "openai"
    assert_reached_safely(m)
