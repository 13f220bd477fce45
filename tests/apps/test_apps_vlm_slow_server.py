"""`go2vlm demo --goal "go to the blue cylinder" --perception vlm` through a real OpenAI-compatible
server on loopback that answers 5 s after each request (the shipped tiny grounder behind `transformers
serve`, behind a proxy that holds every request 5 s: testing_support.serve.delaying_proxy), from the
demo's own spawn, where the cylinder is behind the robot. Every answer is 5+ s old when it comes, so
the search stops and looks, the object memory places the answers at the pose of their frames, and the
commander walks to the remembered cylinder and stops on an answer about a frame taken there.

Asserted from the sim's ground truth: reached (within 1 m of the cylinder's surface), no collision,
answers at least 5 s old, no forward command that neither the tracker nor the memory confirmed, and
the memory's blue cylinder within 0.3 m of the real one (also through `go2vlm objects --file`)."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import pytest

pytest.importorskip("mujoco")

from busutil import GO2VLM, env  # noqa: E402
from testing.conftest import grounder_ckpt, grounder_server  # noqa: E402, F401

from testing_support.serve import delaying_proxy  # noqa: E402

pytestmark = pytest.mark.slow

DELAY_S = 5.0


def test_go_to_through_a_server_that_answers_5_s_late(
    grounder_ckpt: Path,  # noqa: F811
    grounder_server: str,  # noqa: F811
    tmp_path: Path,
) -> None:
    from testing_support.tiny_grounder import grounder_node_params

    out = tmp_path / "run"
    params = [f"vlm.{k}={v}" for k, v in {**grounder_node_params(), "timeout_s": 60}.items()]
    with delaying_proxy(grounder_server, DELAY_S) as url:
        cmd = [*GO2VLM, "demo", "--goal", "go to the blue cylinder", "--perception", "vlm",
               "--model", str(grounder_ckpt), "--base-url", url, "--mode", "kinematic", "--rtf", "1",
               "--duration", "300", "--no-video", "--no-progress", "--out", str(out),
               *[a for p in params for a in ("-p", p)]]  # fmt: skip
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1500, env=env())
    assert (out / "metrics.json").exists(), proc.stderr[-3000:]
    m = json.loads((out / "metrics.json").read_text())
    brief = {k: m.get(k) for k in ("states", "final_state", "final_reason", "final_distance_m", "collisions",
                                   "tracker", "grounding", "memory", "time_to_goal_s")}  # fmt: skip
    assert proc.returncode == 0, (proc.stdout[-3000:], brief)
    assert m["success"] and m["final_state"] == "reached" and m["final_distance_m"] <= 1.0, brief
    assert m["collisions"] == 0 and not m["fell"], brief
    assert m["grounding"]["result_age_s_mean"] >= DELAY_S, brief  # every answer came 5+ s after its frame
    assert m["tracker"]["forward_cmds"] > 0 and m["tracker"]["forward_unconfirmed"] == 0, brief
    cyl = max((o for o in m["memory"]["objects"] if o["label"] == "blue cylinder"), key=lambda o: o["confidence"])
    assert cyl["error_m"] <= 0.3, brief  # the one "where is" names
    assert "remembered:" in proc.stdout and "blue cylinder" in proc.stdout
    # A newcomer asks where the blue cylinder is, after the demo.
    ask = subprocess.run([*GO2VLM, "objects", "--file", str(out / "objects.json"), "--where", "blue cylinder"],
                         capture_output=True, text=True, timeout=60, env=env())  # fmt: skip
    assert ask.returncode == 0 and ask.stdout.startswith("blue cylinder at ("), ask
    x, y = (float(v) for v in ask.stdout.split("(", 1)[1].split(")", 1)[0].split(","))
    assert math.hypot(x + 2.0, y) <= 0.3, ask.stdout  # the blue cylinder stands at (-2, 0)
