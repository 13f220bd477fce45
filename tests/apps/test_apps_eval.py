"""`go2vlm eval` as a real process: the smoke suite for the color and oracle variants (what CI runs),
in two worker processes on DDS domains of their own; an interrupted run resumes without redoing
finished episodes; the vlm variant with the shipped tiny grounder behind a real `transformers serve`."""

from __future__ import annotations

import json
import signal
import subprocess
from pathlib import Path
from typing import Any

import pytest
from busutil import GO2VLM, Procs, env, wait_for

# The shipped tiny grounder and `transformers serve` in front of it (started once per session).
from testing.conftest import grounder_ckpt, grounder_server  # noqa: F401

from go2vlm.apps.episodes.outputs import read_jsonl

pytestmark = pytest.mark.slow

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _eval(out: Path, *args: str, timeout: float = 400) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*GO2VLM, "eval", "--out", str(out), "--no-progress", *args],
        capture_output=True, text=True, timeout=timeout, env=env(),
    )  # fmt: skip


def _ok(proc: subprocess.CompletedProcess[str]) -> None:
    assert proc.returncode == 0, f"eval failed ({proc.returncode}):\n{proc.stdout[-2000:]}\n{proc.stderr[-4000:]}"


def test_smoke_suite_for_color_and_oracle(tmp_path: Path) -> None:
    """CI's eval: both variants succeed on the smoke suite; every result carries its configuration."""
    for variant in ("color", "oracle"):
        plots = ("--plots",) if variant == "oracle" else ()  # run folders without a video
        proc = _eval(tmp_path, "--suite", "smoke", "--perception", variant, "--fast", "--workers", "2", *plots)
        _ok(proc)
        assert "success" in proc.stdout and "results.jsonl" in proc.stdout
    lines = read_jsonl(tmp_path / "results.jsonl")
    assert len(lines) == 8
    summary = json.loads((tmp_path / "summary.json").read_text())
    groups = {g["perception"]: g for g in summary["groups"]}
    assert set(groups) == {"color", "oracle"}
    for g in groups.values():
        assert g["episodes"] == 4 and g["success"] >= 3, g  # a loaded host may cost one; the oracle never fails twice
        lo, hi = g["success_rate_ci95"]
        assert lo <= g["success_rate"] <= hi
        assert g["fell"] == 0 and g["spl_mean"] is not None
    # The oracle's grounding is the ground truth: every scored answer is a hit.
    assert groups["oracle"]["grounding_precision_iou50"] == 1.0 and groups["oracle"]["grounding_recall_iou50"] == 1.0
    assert groups["color"]["grounding_precision_iou50"] is None  # the grounder's boxes are internal
    for line in lines:
        cfg = line["config"]
        assert cfg["suite"] == "smoke" and "tasks:" in cfg["suite_text"] and cfg["fast"] is True
        assert cfg["versions"]["mujoco"] and cfg["machine"]["cores"] and "commit" in cfg["git"]
        m = line["metrics"]
        assert {"success", "spl", "time_to_goal_s", "path_length_m", "collisions", "min_clearance_m", "fell"} <= set(m)
        assert m["target_in_view_fraction"] is not None
    # Two workers, each on a DDS domain of its own.
    domains = {(line["config"]["perception"], line["worker"]["pid"]): line["worker"]["domain"] for line in lines}
    assert len(set(domains.values())) >= 2
    for name in ("success_by_variant.png", "iou_hist.png", "success_vs_latency.png"):
        assert (tmp_path / name).read_bytes()[:8] == PNG_MAGIC
    folders = sorted((tmp_path / "episodes").iterdir())
    assert len(folders) == 4 and all((f / "plot.png").read_bytes()[:8] == PNG_MAGIC for f in folders)
    assert not any((f / "video.mp4").exists() for f in folders)
    reasons = json.loads((folders[0] / "series.json").read_text())["reasons"]
    assert reasons and all(len(r) == 3 and isinstance(r[2], str) for r in reasons)  # [t, state, reason]
    report = (tmp_path / "report.md").read_text()
    assert "| smoke | color |" in report and "| smoke | oracle |" in report
    # The same run again is refused: nothing is overwritten.
    again = _eval(tmp_path, "--suite", "smoke", "--perception", "color", "--fast")
    assert again.returncode == 2 and "--resume" in again.stderr


def test_interrupted_eval_resumes_without_redoing_episodes(tmp_path: Path) -> None:
    procs = Procs()
    args = ["eval", "--out", str(tmp_path), "--no-progress", "--suite", "smoke", "--perception", "color"]
    args += ["--episodes", "8", "--fast"]
    proc = procs.start(*args)
    try:
        assert wait_for(lambda: len(read_jsonl(tmp_path / "results.jsonl")) >= 1, timeout=180), proc.stdout
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=120)
    finally:
        procs.stop_all()
    assert proc.returncode == 130, out[-3000:]
    first = (tmp_path / "results.jsonl").read_text()
    done = [line["index"] for line in read_jsonl(tmp_path / "results.jsonl")]
    assert 1 <= len(done) < 8 and "--resume" in out
    assert json.loads((tmp_path / "summary.json").read_text())["groups"][0]["episodes"] == len(done)
    resumed = _eval(tmp_path, *args[4:], "--resume")
    _ok(resumed)
    text = (tmp_path / "results.jsonl").read_text()
    assert text.startswith(first), "finished results are kept as they were"
    indexes = [line["index"] for line in read_jsonl(tmp_path / "results.jsonl")]
    assert sorted(indexes) == list(range(8)), "each episode exactly once"
    assert f"{8 - len(done)} now" in resumed.stdout


def test_bad_eval_options_are_clear_errors(tmp_path: Path) -> None:
    for args, words in (
        (["--suite", "nope", "--perception", "color"], "not found"),
        (["--suite", "smoke", "--perception", "vlm"], "--model"),
        (["--suite", "smoke", "--perception", "color", "--model", "x"], "--perception vlm"),
        (["--suite", "smoke", "--perception", "color", "--param", "commander.no_such=1"], "no_such"),
        (["--suite", "smoke", "--perception", "color", "--param", "vlm.model=x"], "no node named 'vlm'"),
        (["--suite", "smoke", "--perception", "color", "--workers", "2", "--domain", "150"], "--domain"),
    ):
        proc = _eval(tmp_path, *args, timeout=120)
        assert proc.returncode == 2, (args, proc.stderr[-2000:])
        assert words in proc.stderr and "Traceback" not in proc.stderr


def test_vlm_variant_scores_every_answer(tmp_path: Path, grounder_ckpt: Path, grounder_server: str) -> None:  # noqa: F811
    """Two smoke episodes with the tiny sim-trained Qwen2.5-VL behind a real `transformers serve`: every
    answer is scored against the ground truth of its frame, and the latency and tracking are recorded."""
    from testing_support.tiny_grounder import grounder_node_params

    params = [a for k, v in grounder_node_params().items() for a in ("--param", f"vlm.{k}={v}")]
    proc = _eval(tmp_path, "--suite", "smoke", "--perception", "vlm", "--episodes", "2", "--base-url", grounder_server,
                 "--model", str(grounder_ckpt), *params)  # fmt: skip
    _ok(proc)
    lines = read_jsonl(tmp_path / "results.jsonl")
    assert len(lines) == 2 and {line["config"]["perception"] for line in lines} == {"vlm"}
    for line in lines:
        m: dict[str, Any] = line["metrics"]
        g = m["grounding"]
        assert g["answers"] >= 1 and g["scored"] == g["answers"], g  # every answer against its frame's truth
        assert g["hits"] + g["misses"] + g["wrong_object"] + g["false_positives"] <= g["answers"]
        assert m["vlm"]["backend"] == "openai" and m["vlm"]["latency_ms_p50"] is not None
        assert m["tracker"]["frames"] > 0 and m["tracker"]["forward_unconfirmed"] == 0
        assert m["collisions"] == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert any(g["perception"] == "vlm" for g in summary["groups"])
