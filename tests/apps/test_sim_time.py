"""The demos on sim time: the same seed at `--rtf 1` and at `--fast` gives the same outcome, and the
metrics agree within the tolerances below.

Why a tolerance and not equality: sim time does not wait for the nodes. The sim steps on while the
colour detector, the follower or commander and the gate work, and their work takes wall time; at
--fast (3-5x real time here) the same wall-time delay is 3-5x more sim time, and a busy host makes
timers skip periods. So the loop answers a few tens of milliseconds of sim time later at --fast and
the trajectories drift apart a little. What must not drift is what sim time guarantees: the same
frames (every camera frame is due and drawn in sim time), every timeout and rate in sim seconds,
hence the same outcome. Measured on the loaded 2-core reference machine: ball visible 99.5 % vs
99.0 %, mean |x| 0.132 vs 0.132, mean distance 1.71 vs 1.73 m, final distance 1.547 vs 1.549 m,
travelled 4.75 vs 4.72 m; go to: reached after 9.40 vs 9.66 s at 0.845 vs 0.831 m. The tolerances
are several times those differences and well inside what nodes on wall time did at --fast (before
sim time: the follow demo at 9x saw 74 camera frames instead of 201, and "go to" took 19.1 s of sim
time instead of 9.4, since every timer and timeout ran 9x slow in sim time).
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import pytest
from busutil import GO2VLM, env

# Slow: two whole demos each, one at real time.
pytestmark = pytest.mark.slow

SEED = ["--param", "sim.seed=7"]

# metric: (absolute tolerance, why)
FOLLOW_TOLERANCE: dict[str, float] = {
    "target_visible_fraction": 0.05,  # a frame or ten of 200 at the edge of the image
    "mean_abs_x_error": 0.05,  # in normalised image units (-1..1)
    # The follower answers a few processing delays late, which at --fast is more sim time the busier the
    # host is: on a loaded machine (a demo and two busy loops beside the suite) the fast run trailed
    # the ball by up to 0.3 m more on average and 0.55 m more at most. The distances say "it follows".
    "mean_distance_to_ball_m": 0.4,
    "min_distance_to_ball_m": 0.3,
    "max_distance_to_ball_m": 0.7,
    "final_distance_to_ball_m": 0.5,
    "robot_distance_travelled_m": 0.8,  # of ~4.7 m
    "mean_cmd_vx": 0.03,  # m/s
}
GOAL_TOLERANCE: dict[str, float] = {
    # Sim seconds, of ~9.5. At --rtf 1 too the sim does not wait for the detector and the commander, so
    # a loaded host delays them in sim time: on the CI host (the suite's other worker beside) rtf 1
    # took 10.23 s against 8.58 s fast, same course, 0.16 m more walked (58c4293). Nodes on wall time
    # at --fast took twice as long (19.1 s), which this still catches.
    "time_to_goal_s": 3.0,
    "final_distance_m": 0.1,  # the commander stops within 0.05 m of its 0.8 m stop distance
    "min_clearance_m": 0.1,
    "robot_distance_travelled_m": 0.3,  # of ~1.4 m
}


def _demo(out: Path, *args: str) -> dict[str, Any]:
    proc = subprocess.run(
        [*GO2VLM, "demo", "--out", str(out), "--no-progress", "--mode", "kinematic", *SEED, *args],
        capture_output=True, text=True, timeout=300, env=env(),
    )  # fmt: skip
    tail = f"{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    assert proc.returncode == 0, f"demo {args} failed ({proc.returncode}):\n{tail}"
    return json.loads((out / "metrics.json").read_text())


def _compare(a: dict[str, Any], b: dict[str, Any], tolerance: dict[str, float]) -> None:
    rows = [f"{k}: rtf1 {a[k]} fast {b[k]} (tolerance {tol})" for k, tol in tolerance.items()]
    print("\n".join(rows))
    bad = [row for row, (k, tol) in zip(rows, tolerance.items(), strict=True) if abs(a[k] - b[k]) > tol]
    assert not bad, "rtf 1 and fast disagree: " + "; ".join(bad)


def test_follow_demo_same_outcome_at_rtf_1_and_fast(tmp_path: Path) -> None:
    rt = _demo(tmp_path / "rtf1", "--duration", "20", "--rtf", "1", "--no-video")
    fast = _demo(tmp_path / "fast", "--duration", "20", "--fast", "--no-video")
    # Which run was faster is the host's business (docs/benchmarks.md has the figures), not the test's.
    assert fast["options"]["fast"] is True and rt["options"]["fast"] is False
    for m in (rt, fast):
        assert m["fell"] is False and m["duration_s"] >= 19.8
        assert m["target_visible_fraction"] >= 0.9 and m["max_distance_to_ball_m"] < 3.0, m
    # The camera runs at 10 Hz of sim time in both: at --fast the physics waits for each frame to be
    # drawn, at --rtf 1 a late render may drop some (up to 15 % on a very busy machine).
    assert fast["frames_dropped_by_renderer"] == 0 and fast["frames"] >= 195
    # 173 of 203 with a demo, two busy loops and another suite beside it
    assert 0.75 * fast["frames"] <= rt["frames"] <= fast["frames"] + 5
    _compare(rt, fast, FOLLOW_TOLERANCE)


def _course(states: list[str]) -> list[str]:
    """The states without brief losses: lost, and the repeat it leaves behind."""
    out: list[str] = []
    for s in states:
        if s != "lost" and (not out or out[-1] != s):
            out.append(s)
    return out


def test_goal_demo_same_outcome_at_rtf_1_and_fast(tmp_path: Path) -> None:
    goal = ["--goal", "go to the blue cylinder"]
    rt = _demo(tmp_path / "rtf1", *goal, "--rtf", "1")
    fast = _demo(tmp_path / "fast", *goal, "--fast")
    assert fast["options"]["fast"] is True and rt["options"]["fast"] is False
    for m in (rt, fast):
        assert m["goal_reached"] is True and m["final_state"] == "reached" and m["collisions"] == 0, m
    # A loaded host may lose the target for a moment at rtf 1 (a late frame): the same course otherwise.
    assert _course(rt["states"]) == _course(fast["states"]), (rt["states"], fast["states"])
    _compare(rt, fast, GOAL_TOLERANCE)
