"""`go2vlm demo --perception color|oracle|vlm` as a user runs it: a real process, the one command.
Option errors are one clear line and exit 2; the oracle runs the ball follow demo through the
tracker; the vlm variant with the shipped tiny grounder reports its answers, latency and tracking."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from busutil import GO2VLM, env
from testing.conftest import grounder_ckpt  # noqa: F401


def _demo(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*GO2VLM, "demo", "--no-progress", "--no-video", *args], capture_output=True, text=True,
                          timeout=timeout, env=env())  # fmt: skip


def test_bad_perception_options_are_one_line_errors() -> None:
    for args, words in (
        (["--perception", "vlm"], "--model"),
        (["--model", "x"], "--perception vlm"),
        (["--perception", "color", "--base-url", "http://127.0.0.1:1/v1"], "--perception vlm"),
        (["--perception", "oracle", "--robot", "go2"], "go2"),
        (["--perception", "nope"], "invalid choice"),
    ):
        proc = _demo(*args, timeout=60)
        assert proc.returncode == 2, (args, proc.stderr[-2000:])
        assert words in proc.stderr and "Traceback" not in proc.stderr, (args, proc.stderr)


@pytest.mark.slow
def test_oracle_follows_the_ball_through_the_tracker(tmp_path: Path) -> None:
    proc = _demo(
        "--perception", "oracle", "--mode", "kinematic", "--duration", "10", "--rtf", "2", "--out", str(tmp_path)
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "follow the red ball" in proc.stdout and "tracker:" in proc.stdout, proc.stdout
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["perception"] == "oracle" and m["world"] == "follow_ball" and m["kind"] == "follow"
    assert m["tracker"]["tracking_fraction"] > 0.5 and m["tracker"]["forward_unconfirmed"] == 0
    assert m["collisions"] == 0


@pytest.mark.slow
def test_vlm_demo_with_the_tiny_grounder_reports_what_the_vlm_did(tmp_path: Path, grounder_ckpt: Path) -> None:  # noqa: F811
    proc = _demo("--perception", "vlm", "--model", str(grounder_ckpt), "--goal", "go to the blue cylinder",
                 "--mode", "kinematic", "--rtf", "0.5", "--duration", "20", "--out", str(tmp_path),
                 "-p", "vlm.max_pixels=0", "-p", "vlm.device=cpu", "-p", "vlm.period_s=0")  # fmt: skip
    assert proc.returncode in (0, 1), proc.stderr[-3000:]  # reached or not: the tiny model is weak (docs/vlm.md)
    for line in ("perception:      vlm (transformers", "VLM latency:", "VLM answers:", "result age:", "tracker:"):
        assert line in proc.stdout, proc.stdout
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["vlm"]["inferences"] >= 1 and m["vlm"]["latency_ms_p50"] is not None
    assert m["grounding"]["answers"] >= 1 and m["grounding"]["scored"] == m["grounding"]["answers"]
    assert m["tracker"]["forward_unconfirmed"] == 0 and m["collisions"] == 0


@pytest.mark.slow
def test_a_model_that_cannot_load_is_a_clear_error_before_the_sim_runs(tmp_path: Path) -> None:
    pytest.importorskip("transformers")
    proc = _demo("--perception", "vlm", "--model", str(tmp_path / "no_such_model"), "--goal", "go to the red ball",
                 "--out", str(tmp_path / "run"), timeout=120)  # fmt: skip
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr[-2000:]  # a configuration error
    assert "no such directory, and not a hub id" in proc.stderr
    assert not (tmp_path / "run" / "metrics.json").exists()  # no episode ran: the model loads first
