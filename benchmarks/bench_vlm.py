#!/usr/bin/env python3
"""Benchmark the VLM perception path: where a frame's time goes, what image size costs, and how
old the answers are when the camera is faster than the model.

Sections (``--sections``, default all):

* ``latency``   per-frame breakdown (preprocess, prefill, decode, postprocess) for each
                ``--quantization`` (e.g. ``none,nf4``), with load time and peak GPU memory.
* ``sizes``     visual tokens and latency vs camera image size and ``max_pixels``.
* ``freshness`` result age vs camera rate, over the real bus: the seed article's design
                (inference inside the image callback, queue depth 10) against the vlm node's
                (newest frame wins, a worker thread). The camera is simulated at ``--camera-hz``.

Runs on the tiny Qwen2.5-VL checkpoint (built offline, ~15 s the first time) by default:

    python benchmarks/bench_vlm.py --out bench_tiny.json

A real checkpoint or the real 3B shapes with random weights on a GPU (fp16 vs nf4, fixed
number of generated tokens):

    python benchmarks/bench_vlm.py --model /path/to/Qwen2.5-VL-3B-Instruct --quantization none,nf4
    python benchmarks/bench_vlm.py --random-weights --arch 3b --device cuda --dtype fp16 \\
        --quantization none,nf4 --new-tokens 64 --out bench_3b.json
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import random
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

# Before torch: the node sets this too; the benchmark must measure the same allocator.
os.environ.setdefault("PYTORCH_CUDA_ALLOC_CONF", "expandable_segments:True")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: testing_support/ (dev-only)


# -- helpers -----------------------------------------------------------------------------------


def scene(h: int, w: int, seed: int = 0) -> np.ndarray:
    """An RGB test scene like the seed's: a green rectangle, a red disc, noise."""
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 40, (h, w, 3), dtype=np.uint8)
    img[int(h * 0.42) : int(h * 0.83), int(w * 0.16) : int(w * 0.47)] = (0, 255, 0)
    yy, xx = np.ogrid[:h, :w]
    r = min(h, w) * 0.17
    img[(yy - h * 0.31) ** 2 + (xx - w * 0.7) ** 2 <= r * r] = (255, 0, 0)
    return img


def stats(values: list[float]) -> dict[str, float]:
    if not values:
        return {}
    v = sorted(values)
    return {
        "mean": statistics.fmean(v),
        "p50": v[len(v) // 2],
        "p90": v[min(len(v) - 1, int(round(0.9 * (len(v) - 1))))],
        "max": v[-1],
        "n": float(len(v)),
    }


def table(rows: list[dict[str, Any]], cols: list[tuple[str, str]]) -> str:
    def fmt(x: Any) -> str:
        if isinstance(x, float):
            return f"{x:.1f}" if abs(x) < 1e5 else f"{x:.3g}"
        return "" if x is None else str(x)

    cells = [[fmt(r.get(k)) for k, _ in cols] for r in rows]
    widths = [max(len(h), *(len(c[i]) for c in cells)) if cells else len(h) for i, (_, h) in enumerate(cols)]
    line = "  ".join(h.rjust(w) for (_, h), w in zip(cols, widths, strict=True))
    out = [line, "-" * len(line)]
    out += ["  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)) for row in cells]
    return "\n".join(out)


def cuda_available() -> bool:
    try:
        import torch

        return torch.cuda.is_available()
    except ImportError:
        return False


def gpu_mem() -> dict[str, float]:
    if not cuda_available():
        return {}
    import torch

    return {
        "allocated_gib": torch.cuda.memory_allocated() / 2**30,
        "peak_allocated_gib": torch.cuda.max_memory_allocated() / 2**30,
        "peak_reserved_gib": torch.cuda.max_memory_reserved() / 2**30,
    }


def reset_peak() -> None:
    if cuda_available():
        import torch

        torch.cuda.reset_peak_memory_stats()


def free_memory() -> None:
    gc.collect()
    if cuda_available():
        import torch

        torch.cuda.empty_cache()


# -- model -------------------------------------------------------------------------------------


def resolve_model(args: argparse.Namespace) -> str:
    from testing_support import tiny_qwen as tiny

    if args.model:
        return args.model
    if args.random_weights:
        if args.arch == "tiny":
            return str(tiny.cached_tiny_checkpoint(answer=None, steps=0))
        tag = f"random-{args.arch}-t{args.text_layers or 'all'}-v{args.vision_layers or 'all'}"
        root = Path(os.environ.get("GO2VLM_CACHE") or Path.home() / ".cache" / "go2vlm")
        out = root / tag
        if not (out / "config.json").is_file():
            print(f"building random-weight {args.arch} checkpoint in {out} ...", file=sys.stderr)
            device = "cuda" if cuda_available() else "cpu"
            tiny.save_untrained_checkpoint(
                out,
                arch=args.arch,
                text_layers=args.text_layers,
                vision_layers=args.vision_layers,
                device=device,
                dtype="float16" if device == "cuda" else "bfloat16",
            )
        return str(out)
    return str(tiny.cached_tiny_checkpoint())


def make_backend(args: argparse.Namespace, model: str, quantization: str) -> Any:
    from go2vlm.perception.vlm.backend import BackendSettings
    from go2vlm.perception.vlm.factory import make_backend

    s = BackendSettings(
        model=model,
        backend="transformers",
        dtype=args.dtype,
        device=args.device,
        quantization=quantization,
        compile=args.compile,
        process="off",  # the backend itself, in this process: its own time, and sizes can change its settings
        max_pixels=args.latency_max_pixels,
        max_new_tokens=args.new_tokens or 96,
        min_new_tokens=args.new_tokens or 0,
    )
    return make_backend(s)


def postprocess(gen: Any) -> tuple[float, int]:
    """What the node does after generate(): parse, rescale, build the message. Returns (ms, boxes)."""
    from go2vlm.vocabulary.answers import answer_boxes

    try:  # the message types need cyclonedds; a bare GPU box may lack it (latency/sizes still run)
        from go2vlm.msgs.std_msgs import Header
        from go2vlm.perception.vlm.vlm_node import detections_msg
    except ImportError:
        detections_msg = None  # type: ignore[assignment]

    t0 = time.perf_counter()
    _, boxes = answer_boxes(gen)
    if detections_msg is not None:
        detections_msg(boxes, Header())
    return (time.perf_counter() - t0) * 1e3, len(boxes)


# -- sections ----------------------------------------------------------------------------------


def bench_latency(args: argparse.Namespace, backend: Any, quant: str, load_s: float) -> dict[str, Any]:
    h, w = args.latency_size
    img = scene(h, w)
    backend.generate(img, args.prompt)  # warm-up (kernels, allocator)
    reset_peak()
    per: dict[str, list[float]] = {k: [] for k in ("preprocess", "prefill", "decode", "postprocess", "total")}
    gen = None
    for i in range(args.frames):
        gen = backend.generate(scene(h, w, seed=i), args.prompt)
        post_ms, _ = postprocess(gen)
        for k in ("preprocess", "prefill", "decode"):
            per[k].append(gen.timings_ms[k])
        per["postprocess"].append(post_ms)
        per["total"].append(gen.timings_ms["total"] + post_ms)
    assert gen is not None
    mem = gpu_mem()
    decode_tps = gen.new_tokens / (statistics.fmean(per["decode"]) / 1e3) if per["decode"] and gen.new_tokens else 0
    return {
        "quantization": quant,
        "compiled": bool(getattr(backend, "compiled", False)),
        "load_report": dict(getattr(backend, "load_report", {})),
        "backend": backend.description,
        "image": f"{h}x{w}",
        "resized": f"{gen.resized_hw[0]}x{gen.resized_hw[1]}",
        "visual_tokens": gen.visual_tokens,
        "prompt_tokens": gen.prompt_tokens,
        "new_tokens": gen.new_tokens,
        "load_s": load_s,
        "ms": {k: stats(v) for k, v in per.items()},
        "decode_tok_s": decode_tps,
        "gpu": mem,
        "answer": gen.text[:200],
    }


def bench_sizes(args: argparse.Namespace, backend: Any) -> list[dict[str, Any]]:
    rows = []
    saved = (backend.settings.max_pixels, backend.settings.max_new_tokens, backend.settings.min_new_tokens)
    # Few generated tokens: this section is about the image side (vision tower + prefill).
    backend.settings.max_new_tokens = backend.settings.min_new_tokens = args.sizes_new_tokens
    try:
        for h, w in args.sizes:
            for mp in args.max_pixels:
                backend.settings.max_pixels = mp
                img = scene(h, w)
                backend.generate(img, args.prompt)  # warm-up for this shape
                reset_peak()
                runs = [backend.generate(scene(h, w, seed=i), args.prompt) for i in range(args.size_frames)]
                g = runs[-1]
                rows.append(
                    {
                        "image": f"{h}x{w}",
                        "max_pixels": mp,
                        "resized": f"{g.resized_hw[0]}x{g.resized_hw[1]}",
                        "visual_tokens": g.visual_tokens,
                        "preprocess_ms": statistics.median(r.timings_ms["preprocess"] for r in runs),
                        "prefill_ms": statistics.median(r.timings_ms["prefill"] for r in runs),
                        "total_ms": statistics.median(r.timings_ms["total"] for r in runs),
                        "peak_gib": gpu_mem().get("peak_allocated_gib"),
                    }
                )
                print(f"  sizes: {rows[-1]}", file=sys.stderr)
    finally:
        backend.settings.max_pixels, backend.settings.max_new_tokens, backend.settings.min_new_tokens = saved
    return rows


class _Preloaded:
    """Lend an already loaded backend to a node without letting the node load or close it.

    ``extra_ms`` pads every inference with a sleep, to replay a bigger model's latency (the seed
    measured 2-3 s per frame for the 3B on an RTX 5060) while the tiny model does the real work.
    """

    def __init__(self, inner: Any, extra_ms: float = 0.0) -> None:
        self.inner = inner
        self.extra_ms = extra_ms
        self.name = inner.name
        self.description = inner.description

    def load(self) -> None:
        pass

    def generate(self, rgb: np.ndarray, prompt: str) -> Any:
        gen = self.inner.generate(rgb, prompt)
        if self.extra_ms > 0:
            time.sleep(self.extra_ms / 1e3)
            gen.timings_ms["decode"] += self.extra_ms
            gen.timings_ms["total"] += self.extra_ms
        return gen

    def close(self) -> None:
        pass


def bench_freshness(args: argparse.Namespace, inner: Any, hz: float, extra_ms: float) -> list[dict[str, Any]]:
    from go2vlm.bus import QOS_DEFAULT, QOS_SENSOR, Node, QosProfile, build_config
    from go2vlm.msgs.builtin_interfaces import Time
    from go2vlm.msgs.image import numpy_to_image
    from go2vlm.msgs.sensor_msgs import Image
    from go2vlm.msgs.std_msgs import Header
    from go2vlm.msgs.vision_msgs import Detection2DArray
    from go2vlm.perception.vlm.vlm_node import VlmConfig, VlmNode, detections_msg, image_to_rgb
    from go2vlm.vocabulary.answers import answer_boxes

    backend = _Preloaded(inner, extra_ms)
    h, w = args.latency_size
    frames = [scene(h, w, seed=i)[:, :, ::-1].copy() for i in range(8)]  # bgr8 like a camera driver

    class SeedStyleNode(Node):
        """The seed article's node: inference inside the image callback, subscription depth 10."""

        name = "vlm_seed_style"

        def __init__(self, topic: str, out: str, depth: int) -> None:
            super().__init__(node_name="vlm_seed_style")
            self.pub = self.create_publisher(Detection2DArray, out, QOS_DEFAULT)
            # rclpy's create_subscription(Image, topic, cb, 10): reliable, keep-last 10
            self.create_subscription(Image, topic, self.on_image, QosProfile(reliable=True, depth=depth))
            self.processed = 0

        def on_image(self, msg: Image) -> None:
            if self._stop.is_set():  # shut down: do not work through the rest of the queue
                return
            gen = backend.generate(image_to_rgb(msg), args.prompt)
            _, boxes = answer_boxes(gen)
            self.pub.publish(detections_msg(boxes, msg.header))
            self.processed += 1

    results = []
    for design in ("seed_callback_queue10", "vlm_node_newest_wins"):
        tag = f"{design}_{int(hz * 10)}_{int(extra_ms)}"
        cam_topic, out_topic = f"/bench/{tag}/image_raw", f"/bench/{tag}/detections"
        harness = Node(node_name="bench_harness")
        # The seed's camera publisher used depth 10 reliable; the node subscribes with sensor QoS.
        cam_qos = QOS_DEFAULT if design.startswith("seed") else QOS_SENSOR
        cam = harness.create_publisher(Image, cam_topic, cam_qos)
        ages: list[float] = []
        stamps: list[float] = []

        def on_result(msg: Detection2DArray, ages: list[float] = ages, stamps: list[float] = stamps) -> None:
            src = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            ages.append((time.time() - src) * 1e3)
            stamps.append(src)

        harness.create_subscription(Detection2DArray, out_topic, on_result, QOS_DEFAULT)
        if design.startswith("seed"):
            node: Any = SeedStyleNode(cam_topic, out_topic, args.queue_depth)
        else:
            cfg = build_config(
                VlmConfig,
                {"model": "bench", "mode": "detect", "image_topic": cam_topic, "period_s": 0.0},
                node="vlm",
            )
            node = VlmNode(cfg, backend=backend, remap={"/vlm/detections": out_topic})
        harness.start()
        node.start()
        time.sleep(1.0)  # discovery
        published = 0
        t_end = time.monotonic() + args.duration
        next_t = time.monotonic()
        while time.monotonic() < t_end:
            img = numpy_to_image(frames[published % len(frames)], "bgr8", Header(stamp=Time.from_sec(time.time())))
            cam.publish(img)
            published += 1
            next_t += 1.0 / hz
            time.sleep(max(0.0, next_t - time.monotonic()))
        node.shutdown()
        if node._thread is not None:  # the seed node may still be inside a callback
            node._thread.join(30)
        time.sleep(0.3)
        harness.shutdown()
        steady = ages[len(ages) // 2 :]  # second half: after the seed's queue has filled
        if design.startswith("seed"):
            processed, dropped = node.processed, published - node.processed
        else:
            processed, dropped = node.slot.taken, node.slot.dropped
        row = {
            "design": design,
            "camera_hz": hz,
            "extra_latency_ms": extra_ms,
            "duration_s": args.duration,
            "frames_published": published,
            "results": len(ages),
            "frames_processed": processed,
            "frames_dropped_or_unprocessed": dropped,
            "age_ms": stats(ages),
            "steady_age_ms": stats(steady),
            "last_age_ms": ages[-1] if ages else None,
        }
        results.append(row)
        print(
            f"  freshness: {design} @ {hz} Hz: {len(ages)} results, age p50 {row['age_ms'].get('p50')}", file=sys.stderr
        )
    return results


# -- main --------------------------------------------------------------------------------------


def parse_size(text: str) -> tuple[int, int]:
    h, _, w = text.lower().partition("x")
    return int(h), int(w)


def main(argv: list[str] | None = None) -> int:
    from go2vlm.geometry.qwen import DEFAULT_MAX_PIXELS
    from go2vlm.perception.vlm.prompts import detect_prompt

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", default="", help="checkpoint dir or hub id (default: the tiny test checkpoint)")
    p.add_argument("--random-weights", action="store_true", help="random init with --arch's shapes")
    p.add_argument("--arch", default="tiny", choices=("tiny", "3b", "7b"))
    p.add_argument("--text-layers", type=int, default=None, help="random weights: fewer LLM layers (smoke runs)")
    p.add_argument("--vision-layers", type=int, default=None, help="random weights: fewer vision blocks")
    p.add_argument("--device", default="auto")
    p.add_argument("--dtype", default="auto", choices=("auto", "fp16", "bf16", "fp32"))
    p.add_argument("--quantization", default="none", help="comma list of none,nf4,int8 (compared in turn)")
    p.add_argument(
        "--compile",
        default="auto",
        choices=("auto", "on", "off"),
        help="static cache + compiled decode (auto: CUDA 16-bit)",
    )
    p.add_argument("--new-tokens", type=int, default=0, help="generate exactly N tokens (0: up to 96, stop at eos)")
    p.add_argument("--prompt", default=None, help="default: the detect-mode grounding prompt")
    p.add_argument("--sections", default="latency,sizes,freshness")
    p.add_argument("--frames", type=int, default=10, help="latency: frames per configuration")
    p.add_argument("--latency-size", type=parse_size, default=(480, 640), help="HxW camera frame")
    p.add_argument("--latency-max-pixels", type=int, default=DEFAULT_MAX_PIXELS)
    p.add_argument("--sizes", default="240x320,480x640,720x1280,1080x1920")
    p.add_argument("--max-pixels", default="50176,200704,401408,1003520", help="comma list (64..1280 tokens)")
    p.add_argument("--size-frames", type=int, default=3)
    p.add_argument("--sizes-new-tokens", type=int, default=4)
    p.add_argument("--camera-hz", default="10", help="comma list of simulated camera rates")
    p.add_argument("--duration", type=float, default=20.0, help="freshness: seconds per design and rate")
    p.add_argument(
        "--extra-latency-ms",
        default="0",
        help="freshness: comma list of per-inference padding to replay a bigger model (seed: 2500 for the 3B)",
    )
    p.add_argument("--queue-depth", type=int, default=10, help="seed design's subscription depth")
    p.add_argument(
        "--domain", type=int, default=None, help="DDS domain (default: $ROS_DOMAIN_ID, else a random private one)"
    )
    p.add_argument("--out", "--json", dest="out", default=None, help="write all results as JSON here")
    args = p.parse_args(argv)
    args.sizes = [parse_size(s) for s in args.sizes.split(",") if s]
    args.max_pixels = [int(x) for x in args.max_pixels.split(",") if x]
    args.prompt = args.prompt or detect_prompt(())
    sections = set(args.sections.split(","))
    # A private domain on loopback: never talk to a robot while benchmarking.
    if args.domain is not None:
        os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 200)))
    os.environ.setdefault("GO2VLM_IFACE", "lo")

    model = resolve_model(args)
    report: dict[str, Any] = {
        "model": model,
        "random_weights": args.random_weights,
        "arch": args.arch,
        "host": {
            "machine": platform.machine(),
            "python": platform.python_version(),
            "cpus": os.cpu_count(),
            # other work on the machine skews CPU timings: keep the load next to the figures
            "loadavg_start": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        },
        "latency": [],
        "sizes": [],
        "freshness": [],
    }
    try:
        import torch
        import transformers

        report["host"].update(torch=torch.__version__, transformers=transformers.__version__)
        if torch.cuda.is_available():
            report["host"]["gpu"] = torch.cuda.get_device_name(0)
        else:
            report["host"]["torch_threads"] = torch.get_num_threads()
    except ImportError:
        pass

    for i, quant in enumerate(q for q in args.quantization.split(",") if q):
        free_memory()
        reset_peak()
        t0 = time.perf_counter()
        backend = make_backend(args, model, quant)
        backend.load()
        load_s = time.perf_counter() - t0
        weights = gpu_mem()
        print(f"loaded {backend.description} in {load_s:.1f} s {weights}", file=sys.stderr)
        if "latency" in sections:
            row = bench_latency(args, backend, quant, load_s)
            row["gpu_after_load"] = weights
            report["latency"].append(row)
        if i == 0 and "sizes" in sections:
            report["sizes"] = bench_sizes(args, backend)
        if i == 0 and "freshness" in sections:
            for extra in (float(x) for x in args.extra_latency_ms.split(",") if x):
                for hz in (float(x) for x in args.camera_hz.split(",") if x):
                    report["freshness"] += bench_freshness(args, backend, hz, extra)
        backend.close()
        del backend
        free_memory()

    if hasattr(os, "getloadavg"):
        report["host"]["loadavg_end"] = os.getloadavg()[0]
    print_report(report)
    if args.out:
        Path(args.out).write_text(json.dumps(report, indent=1, ensure_ascii=False))
        print(f"\nwrote {args.out}")
    return 0


def print_report(report: dict[str, Any]) -> None:
    print(f"\nmodel: {report['model']}  host: {report['host']}")
    if report["latency"]:
        rows = []
        for r in report["latency"]:
            ms = r["ms"]
            rows.append(
                {
                    "q": r["quantization"],
                    "img": r["image"],
                    "vt": r["visual_tokens"],
                    "new": r["new_tokens"],
                    "load": r["load_s"],
                    "pre": ms["preprocess"]["p50"],
                    "prefill": ms["prefill"]["p50"],
                    "decode": ms["decode"]["p50"],
                    "post": ms["postprocess"]["p50"],
                    "total": ms["total"]["p50"],
                    "tok_s": r["decode_tok_s"],
                    "wts_gib": r.get("gpu_after_load", {}).get("allocated_gib"),
                    "peak_gib": r["gpu"].get("peak_allocated_gib"),
                }
            )
        print("\nper-frame latency, ms (p50 over frames)")
        print(
            table(
                rows,
                [
                    ("q", "quant"),
                    ("img", "image"),
                    ("vt", "vis.tok"),
                    ("new", "new.tok"),
                    ("load", "load s"),
                    ("pre", "preproc"),
                    ("prefill", "prefill"),
                    ("decode", "decode"),
                    ("post", "postproc"),
                    ("total", "total"),
                    ("tok_s", "dec tok/s"),
                    ("wts_gib", "weights GiB"),
                    ("peak_gib", "peak GiB"),
                ],
            )
        )
    if report["sizes"]:
        print("\nvisual tokens and latency vs image size and max_pixels")
        print(
            table(
                report["sizes"],
                [
                    ("image", "image"),
                    ("max_pixels", "max_pixels"),
                    ("resized", "resized"),
                    ("visual_tokens", "vis.tok"),
                    ("preprocess_ms", "preproc ms"),
                    ("prefill_ms", "prefill ms"),
                    ("total_ms", "total ms"),
                    ("peak_gib", "peak GiB"),
                ],
            )
        )
    if report["freshness"]:
        rows = []
        for r in report["freshness"]:
            rows.append(
                {
                    "design": r["design"],
                    "hz": r["camera_hz"],
                    "extra": r["extra_latency_ms"],
                    "pub": r["frames_published"],
                    "res": r["results"],
                    "drop": r["frames_dropped_or_unprocessed"],
                    "p50": r["age_ms"].get("p50"),
                    "steady": r["steady_age_ms"].get("mean"),
                    "max": r["age_ms"].get("max"),
                }
            )
        print("\nresult age (now - source frame stamp), ms")
        print(
            table(
                rows,
                [
                    ("design", "design"),
                    ("hz", "camera Hz"),
                    ("extra", "+latency ms"),
                    ("pub", "frames"),
                    ("res", "results"),
                    ("drop", "dropped"),
                    ("p50", "age p50"),
                    ("steady", "age 2nd half"),
                    ("max", "age max"),
                ],
            )
        )


if __name__ == "__main__":
    sys.exit(main())
