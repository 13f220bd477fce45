"""Does the vlm node starve its model? Inference time and result age with the camera and the sim
running, against inference alone, for a launch-bound model.

    .venv/bin/python benchmarks/bench_vlm_node.py --duration 60 --json runs/vlm_node.json
    .venv/bin/python benchmarks/bench_vlm_node.py --cases alone,process --graph episode_vlm
    .venv/bin/python benchmarks/bench_vlm_node.py --graph camera --backend transformers \
        --model ~/.cache/go2vlm/random-3b-tall-vall --param dtype=bf16 --param max_new_tokens=32   # a GPU

The model is the `standin` backend (perception/vlm/standin_backend.py): no weights, the timing of the
real 3B's eager decode on an H100 (39.3 tokens/s, 32 new tokens, an 80 ms prefill: 0.89 s a frame),
each token pure-Python work that holds the interpreter, as a launch-bound decode loop does. Cases:

- alone    the backend's generate() in this process, nothing else running (--frames frames);
- inproc   a packaged launch graph (--graph, default goal_sim: the sim with its head camera at 10 Hz,
           640x480, the vlm node in detect mode, tracker, object memory, commander, follower, gate)
           built in this process as `go2vlm launch` and the episode runner build it, with the vlm
           node's inference in the node's own process (inference_process=off: the design before);
- process  the same graph with inference_process=on (the default for transformers and standin): the
           model in a process of its own, the newest frame handed over in shared memory.

`--graph camera` is the vlm node alone with a camera in this process (640x480 bgr8 at 10 Hz, no
sim: no MuJoCo needed). `--backend transformers --model DIR` measures a real model instead of the
stand-in (`--param k=v` sets the vlm node's parameters, e.g. dtype, quantization, compile).

Per case: inference time (the backend's own wall time per frame, p50/p90) and, for the graphs, the
result age (the node's result_age_ms: now minus the source frame's stamp, in sim time, and in wall
time through the sim's achieved real-time factor). Targets (issue 33): inference within 10 % of
alone, age at most 1.2x inference. Wall-clock figures: quote the load average printed with them.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import yaml

os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 230)))
os.environ.setdefault("GO2VLM_IFACE", "lo")


def stats(xs: list[float]) -> dict[str, float]:
    if not xs:
        return {"n": 0}
    v = sorted(xs)
    return {
        "p50": v[len(v) // 2],
        "p90": v[min(len(v) - 1, round(0.9 * (len(v) - 1)))],
        "mean": statistics.fmean(v),
        "n": len(v),
    }


def case_alone(vlm_params: dict[str, Any], frames: int) -> dict[str, Any]:
    """The backend's generate() in this process, nothing else running."""
    import numpy as np

    from go2vlm.bus import build_config
    from go2vlm.perception.vlm.factory import make_backend
    from go2vlm.perception.vlm.prompts import detect_prompt
    from go2vlm.perception.vlm.vlm_node import VlmConfig

    cfg = build_config(VlmConfig, {**vlm_params, "inference_process": "off"}, node="vlm")
    b = make_backend(cfg.backend_settings())
    b.load()
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 256, (480, 640, 3), dtype=np.uint8)
    prompt = detect_prompt(())
    b.generate(frame, prompt)
    times = [b.generate(frame, prompt).timings_ms["total"] for _ in range(frames)]
    b.close()
    return {"case": "alone", "inference_ms": stats(times)}


class _Camera:
    """A 640x480 bgr8 camera at 10 Hz in this process (the `camera` graph: no sim)."""

    def __init__(self) -> None:
        import threading

        import numpy as np

        from go2vlm.bus import Node
        from go2vlm.bus.topics import CAMERA_IMAGE

        self.node = Node(node_name="bench_camera")
        self.pub = CAMERA_IMAGE.publisher(self.node)
        rng = np.random.default_rng(1)
        self.frames = [rng.integers(0, 256, (480, 640, 3), dtype=np.uint8) for _ in range(4)]
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        from go2vlm.msgs.image import numpy_to_image

        i, next_t = 0, time.monotonic()
        while not self.stop.is_set():
            self.pub.publish(numpy_to_image(self.frames[i % 4], "bgr8", header=self.node.header("camera")))
            i += 1
            next_t += 0.1
            self.stop.wait(max(0.0, next_t - time.monotonic()))

    def start(self) -> None:
        self.node.start()
        self.thread.start()

    def shutdown(self) -> None:
        self.stop.set()
        self.thread.join(5)
        self.node.shutdown()


def case_graph(
    graph: str, vlm_params: dict[str, Any], process: str, duration_s: float, ready_timeout_s: float
) -> dict[str, Any]:
    from go2vlm.launch.launcher import load_launch, make_nodes, with_overrides
    from go2vlm.launch.registry import make_node
    from go2vlm.perception.vlm.vlm_node import VlmNode

    params = {**vlm_params, "inference_process": process, "period_s": 0.0}
    nodes: list[Any]
    if graph == "camera":
        nodes = [make_node("vlm", params={**params, "mode": "detect"}), _Camera()]
    else:
        _, entries = load_launch(graph)
        vlm_name = next(e.name for e in entries if e.kind == "vlm")
        nodes = make_nodes(with_overrides(entries, {vlm_name: params}))
    vlm = next(n for n in nodes if isinstance(n, VlmNode))
    try:
        vlm.start()  # the model first, as the episode runner starts it
        deadline = time.monotonic() + ready_timeout_s
        while vlm.state == "loading" and time.monotonic() < deadline:
            time.sleep(0.05)
        if vlm.state != "ready":
            raise RuntimeError(f"the vlm node is {vlm.state}: {vlm.last_error}")
        for n in nodes:
            if n is not vlm:
                n.start()
        deadline = time.monotonic() + ready_timeout_s
        while vlm.inferences < 2 and time.monotonic() < deadline:  # the sim up, frames flowing
            time.sleep(0.05)
        if vlm.inferences < 2:
            raise RuntimeError("no answers from the vlm node: no camera frames?")
        lat, age = [], []
        seen = vlm.inferences
        wall0, sim0 = time.monotonic(), vlm.now()
        while time.monotonic() - wall0 < duration_s:
            time.sleep(0.02)
            with vlm._stats:
                n, total, age_ms = vlm.inferences, vlm.last_latency_ms.get("total"), vlm.last_result_age_ms
            if n != seen and total is not None and age_ms is not None:
                seen = n
                lat.append(total)
                age.append(age_ms)
        rtf = (vlm.now() - sim0) / max(time.monotonic() - wall0, 1e-9)
        status = vlm.status()
    finally:
        for n in reversed(nodes):
            n.shutdown()
    age_sim = stats(age)
    return {
        "case": "process" if process == "on" else "inproc",
        "graph": graph,
        "inference_process": process,
        "inference_ms": stats(lat),
        "result_age_sim_ms": age_sim,
        "sim_rtf": rtf,
        "result_age_wall_ms_p50": age_sim.get("p50", 0.0) / rtf if rtf > 0 else None,
        "frames_received": status["frames_received"],
        "frames_dropped": status["frames_dropped"],
        "inferences": status["inferences"],
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default="alone,inproc,process")
    ap.add_argument("--graph", default="goal_sim", help="a packaged launch graph with a vlm node, or camera")
    ap.add_argument("--backend", default="standin", choices=("standin", "transformers"))
    ap.add_argument("--model", default="", help="transformers: the checkpoint (standin: from --tok-s ...)")
    ap.add_argument("--param", action="append", default=[], help="k=v: a vlm node parameter (repeatable)")
    ap.add_argument("--duration", type=float, default=30.0, help="wall seconds measured per graph case")
    ap.add_argument("--frames", type=int, default=20, help="alone: frames")
    ap.add_argument("--tok-s", type=float, default=39.3)
    ap.add_argument("--tokens", type=int, default=32)
    ap.add_argument("--prefill-ms", type=float, default=80.0)
    ap.add_argument("--ready-timeout", type=float, default=120.0, help="wall seconds for the graph to answer")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    spec = f"tok_s={args.tok_s},tokens={args.tokens},prefill_ms={args.prefill_ms}"
    vlm_params: dict[str, Any] = {"backend": args.backend, "model": args.model or spec, "mode": "detect"}
    for kv in args.param:
        key, _, value = kv.partition("=")
        vlm_params[key] = yaml.safe_load(value)
    out: dict[str, Any] = {
        "host": {"machine": platform.machine(), "cpus": os.cpu_count(), "python": platform.python_version()},
        "vlm": vlm_params,
        "loadavg_start": os.getloadavg()[0],
        "cases": [],
    }
    for case in (c.strip() for c in args.cases.split(",") if c.strip()):
        if case == "alone":
            row = case_alone(vlm_params, args.frames)
        elif case in ("inproc", "process"):
            process = "on" if case == "process" else "off"
            row = case_graph(args.graph, vlm_params, process, args.duration, args.ready_timeout)
        else:
            ap.error(f"unknown case {case!r}")
        row["loadavg"] = os.getloadavg()[0]
        out["cases"].append(row)
        print(json.dumps(row), flush=True)
    alone = next((r for r in out["cases"] if r["case"] == "alone"), None)
    if alone and alone["inference_ms"].get("p50"):
        base = alone["inference_ms"]["p50"]
        for r in out["cases"]:
            if r["case"] != "alone" and r["inference_ms"].get("p50"):
                r["inference_vs_alone"] = r["inference_ms"]["p50"] / base
                r["age_vs_inference"] = r["result_age_wall_ms_p50"] / r["inference_ms"]["p50"]
                print(
                    f"{r['case']:8s} inference p50 {r['inference_ms']['p50']:.0f} ms = {r['inference_vs_alone']:.2f}x "
                    f"alone ({base:.0f} ms); result age p50 {r['result_age_wall_ms_p50']:.0f} ms wall "
                    f"= {r['age_vs_inference']:.2f}x inference (sim rtf {r['sim_rtf']:.2f})",
                    flush=True,
                )
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
