"""Issue 14's obstacle-aware approach, end to end: "go to the blue cylinder" in the `obstacles` world
with crate_2 straight between the robot and the cylinder is reached with zero collisions, through the
real graph (sim with its ray-cast lidar -> /scan, the oracle's boxes -> target_tracker -> commander
with its local planner -> safety gate with its collision guard -> sim), run by `go2vlm eval`."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import pytest
from busutil import GO2VLM, env

from go2vlm.apps.episodes.outputs import read_jsonl

pytestmark = pytest.mark.slow

# The robot at (-0.6, -3.5) facing the cylinder at (-2, 0): the straight line runs through crate_2
# at (-1.2, -2.0), a 0.6 x 0.4 m box.
YAW = math.atan2(3.5, -1.4)
SUITE = f"""
name: crate_between
description: a crate straight between the robot and the blue cylinder
episodes: 1
seed: 0
defaults:
  mode: kinematic
  duration_s: 50
tasks:
  - world: obstacles
    goal: go to the blue cylinder
    spawn: {{x: -0.6, y: -3.5, yaw: {YAW:.4f}, min_clearance_m: 0.1}}  # the red ball starts near
"""


def test_go_to_round_a_crate_without_touching_it(tmp_path: Path) -> None:
    suite = tmp_path / "crate.yaml"
    suite.write_text(SUITE)
    out = tmp_path / "run"
    args = ["--suite", str(suite), "--perception", "oracle", "--fast", "--no-progress", "--out", str(out)]
    proc = subprocess.run(
        [*GO2VLM, "eval", *args],
        capture_output=True, text=True, timeout=600, env=env(),
    )  # fmt: skip
    assert proc.returncode == 0, f"eval failed ({proc.returncode}):\n{proc.stdout[-2000:]}\n{proc.stderr[-4000:]}"
    (line,) = read_jsonl(out / "results.jsonl")
    m = line["metrics"]
    detail = json.dumps({k: m.get(k) for k in ("success", "final_state", "collisions", "min_clearance_m")})
    assert m["success"] and m["final_state"] == "reached", detail
    # The straight line would have met the crate (the guard would have stopped it short, not reached).
    assert m["collisions"] == 0 and m["min_clearance_m"] > 0.1, detail
