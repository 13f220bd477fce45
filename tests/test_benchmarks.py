"""No benchmark can rot: every `benchmarks/*.py` runs here at its smallest setting (the tiny model, a
frame or two, a second of bus time) as its own process, as a user would start it, and must write its
JSON. The figures are not checked (timings belong to docs/benchmarks.md, not to tests); that the
benchmark still imports, runs to the end and writes its results is.

A new benchmark needs a row in SMALLEST: the arguments of its quickest complete run, with `{json}`
where its output file goes (every benchmark takes `--json PATH`). Rows whose quickest run still
starts the sim or a graph of nodes for more than ~20 s are marked slow, with the reason; the README's
full test command runs them too.
Files in benchmarks/ whose name starts with `_` are helpers, not benchmarks.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH_DIR = ROOT / "benchmarks"


@dataclass(frozen=True)
class Smallest:
    args: tuple[str, ...]
    slow: str = ""  # why its smallest run is still long ("" = in the fast set)
    timeout_s: float = 300.0


# Per benchmark: its quickest complete run. Keep `{json}` (the output file the test checks).
SMALLEST: dict[str, Smallest] = {
    "bench_bus": Smallest(("--types", "ours", "--cases", "10", "--duration", "1", "--ser-n", "2", "--json", "{json}")),
    "bench_demo": Smallest(("--duration", "1", "--fast-duration", "1", "--no-video", "--json", "{json}")),
    "bench_guard": Smallest(("--trials", "1", "--json", "{json}"), slow="three 8 s drives of the sim at a wall"),
    "bench_houses": Smallest(("--seeds", "2", "--json", "{json}")),
    "bench_images": Smallest(("--sizes", "640x480", "--frames", "3", "--json", "{json}")),
    "bench_map": Smallest(("--sections", "walk,node", "--walk-m", "10", "--json", "{json}")),
    "bench_mcp": Smallest(
        ("--runs", "1", "--idle", "1", "--json", "{json}"),
        slow="starts the sim graph three times and drives one go-to goal",
        timeout_s=600.0,
    ),
    "bench_memory": Smallest(
        ("--hours", "0.002", "--episodes", "1", "--json", "{json}"), slow="two search episodes in the sim"
    ),
    "bench_odom_drift": Smallest(("--seeds", "2", "--json", "{json}")),
    "bench_params": Smallest(("--calls", "5", "--nodes", "1", "--json", "{json}")),
    "bench_pipeline": Smallest(("--frames", "20", "--flips", "2", "--period", "0.3", "--json", "{json}")),
    "bench_planner": Smallest(("--repeats", "1", "--json", "{json}")),
    "bench_record_view": Smallest(
        ("--duration", "1", "--camera-hz", "10", "--json", "{json}"),
        slow="three publisher/consumer process pairs, `go2vlm record` and `go2vlm view`",
    ),
    "bench_sim": Smallest(("--seconds", "0.2", "--frames", "2", "--json", "{json}")),
    "bench_vlm": Smallest(
        # the tiny Qwen2.5-VL checkpoint (built offline once, cached), every section
        ("--frames", "1", "--sizes", "240x320", "--max-pixels", "50176", "--size-frames", "1")
        + ("--duration", "1", "--new-tokens", "4", "--json", "{json}"),
    ),
    "bench_vlm_node": Smallest(
        # the stand-in model, the vlm node with a camera in this process (no sim), both designs
        ("--graph", "camera", "--duration", "1", "--frames", "1", "--tokens", "2", "--prefill-ms", "1")
        + ("--json", "{json}"),
    ),
    "bench_vlm_latency": Smallest(
        ("--latencies", "0.1", "--follow-s", "2", "--goto", "1", "--fast", "--json", "{json}"),
        slow="a follow and a go-to episode in the sim",
    ),
    "bench_webrtc": Smallest(("--seconds", "1", "--calls", "2", "--json", "{json}")),
    "bench_worlds": Smallest(("--worlds", "follow_ball", "--seconds", "0.5", "--json", "{json}")),
}


def _benchmarks() -> list[str]:
    return sorted(p.stem for p in BENCH_DIR.glob("*.py") if not p.name.startswith("_"))


def _param(name: str) -> object:
    row = SMALLEST.get(name)
    marks = [pytest.mark.slow] if row is not None and row.slow else []
    return pytest.param(name, marks=marks, id=name)


def test_every_row_names_a_benchmark() -> None:
    stale = sorted(set(SMALLEST) - set(_benchmarks()))
    assert not stale, f"SMALLEST in tests/test_benchmarks.py names benchmarks that are gone: {stale}"


@pytest.mark.parametrize("name", [_param(n) for n in _benchmarks()])
def test_benchmark_runs_at_its_smallest_setting(name: str, tmp_path: Path) -> None:
    row = SMALLEST.get(name)
    if row is None:
        pytest.fail(
            f"benchmarks/{name}.py has no smallest setting: add a row to SMALLEST in tests/test_benchmarks.py "
            "with the arguments of its quickest complete run (a frame or two, a second of bus time, the tiny "
            "model) and `--json {json}` (it must take --json PATH and write its results there); mark it "
            "slow=<why> if that run still takes more than ~20 s"
        )
    out = tmp_path / f"{name}.json"
    cmd = [sys.executable, str(BENCH_DIR / f"{name}.py"), *(a.replace("{json}", str(out)) for a in row.args)]
    env = dict(os.environ, PYTHONUNBUFFERED="1")  # conftest: this checkout's src/, a free DDS domain, loopback
    proc = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=row.timeout_s)
    tail = (proc.stdout[-3000:] + "\n--- stderr ---\n" + proc.stderr[-3000:]).strip()
    assert proc.returncode == 0, f"{' '.join(cmd)} exited {proc.returncode}:\n{tail}"
    assert out.is_file(), f"{name} ran but wrote no JSON to --json {out}:\n{tail}"
    data = json.loads(out.read_text())
    assert data, f"{name} wrote empty results"
