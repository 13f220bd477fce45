"""Build the tiny grounder: render frames, train on CPU, evaluate on held-out frames, write the checkpoint.

    python -m testing_support.train_grounder --seed 0 --frames 6000 --steps 3000 --out tests/data/tiny_grounder
    python -m testing_support.train_grounder --eval-only --out tests/data/tiny_grounder   # figures again
    python -m testing_support.train_grounder --dataset household ... --out tests/data/tiny_grounder_household

The checkpoint is written to a temporary sibling of ``--out`` and moved into place at the end,
with ``go2vlm_grounder.json``: the command, seed, library versions, training time and the
held-out figures (per label and overall) that docs/vlm.md quotes.
"""

from __future__ import annotations

import argparse
import json
import platform
import shlex
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from testing_support.sim_dataset import SPECS, GroundingSpec

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="train_tiny_grounder", description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--dataset", choices=sorted(SPECS), default="primitives", help="what it learns (testing/sim_dataset.py)"
    )
    p.add_argument("--seed", type=int, default=0, help="seeds weights, frames, batches (held-out: +1000003)")
    p.add_argument("--frames", type=int, default=6000, help="training frames rendered")
    p.add_argument("--steps", type=int, default=3000, help="optimiser steps")
    p.add_argument("--stop-after", type=int, default=None, help="end after this step (schedule still spans --steps)")
    p.add_argument("--max-minutes", type=float, default=None, help="training time budget; the stop is recorded")
    p.add_argument("--batch", type=int, default=16, help="examples per step")
    p.add_argument("--lr", type=float, default=1.5e-3, help="peak learning rate (AdamW, warm-up then cosine)")
    p.add_argument("--eval-frames", type=int, default=150, help="held-out frames for the final evaluation")
    p.add_argument("--probe-frames", type=int, default=24, help="held-out frames decoded during training")
    p.add_argument("--probe-every", type=int, default=500, help="steps between probes (0: none)")
    p.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    p.add_argument("--out", type=Path, required=True, help="checkpoint directory to write")
    p.add_argument("--eval-only", action="store_true", help="only evaluate the checkpoint in --out")
    return p


def _log(line: str) -> None:
    print(line, flush=True)


def _versions() -> dict[str, str]:
    import mujoco
    import tokenizers
    import torch
    import transformers

    return {
        "python": platform.python_version(),
        "torch": torch.__version__,
        "transformers": transformers.__version__,
        "tokenizers": tokenizers.__version__,
        "mujoco": mujoco.__version__,
    }


def _evaluate(ckpt: Path, frames: int, seed: int, spec: GroundingSpec) -> dict[str, Any]:
    from tqdm import tqdm

    from go2vlm.perception.vlm.hf_backend import TransformersBackend
    from testing_support.tiny_grounder import EVAL_SEED_OFFSET, evaluate, grounder_settings, render_dataset

    with tqdm(total=frames, desc="render held-out", unit="frame", file=sys.stderr) as bar:
        held_out = render_dataset(frames, seed + EVAL_SEED_OFFSET, progress=bar.update, keep_rgb=True, spec=spec)
    backend = TransformersBackend(grounder_settings(ckpt))
    backend.load()
    try:
        with tqdm(desc="evaluate", unit="answer", file=sys.stderr) as bar:
            t0 = time.monotonic()
            figures = evaluate(backend, held_out.frames, progress=bar.update, spec=spec, seed=seed)
            answers = sum(kind["answers"] for kind in figures.values())
            figures["seconds_per_answer"] = round((time.monotonic() - t0) / max(1, answers), 3)
    finally:
        backend.close()
    figures["frames"] = frames
    figures["seed"] = seed + EVAL_SEED_OFFSET
    figures["dataset"] = dict(held_out.stats)
    return figures


def _print_table(figures: dict[str, Any]) -> None:
    _log(f"held-out evaluation: {figures['frames']} frames (seed {figures['seed']})")
    for kind, title in (("single", "one label per prompt"), ("all_three", "all three labels in one prompt")):
        if kind not in figures:
            continue
        res = figures[kind]
        _log(f"  {title}: {res['answers']} answers, JSON parse failures {res['parse_fail_rate']:.1%}")
        _log(f"    {'label':<34} {'visible':>7} {'IoU>=0.5':>9} {'mean IoU':>9} {'negatives':>9} {'false pos':>9}")
        rows = [*res["labels"].items(), ("overall", res["overall"])]
        for label, s in rows:
            rate = "-" if s["iou50_rate"] is None else f"{s['iou50_rate']:.1%}"
            miou = "-" if s["mean_iou"] is None else f"{s['mean_iou']:.3f}"
            fp = "-" if s["false_positive_rate"] is None else f"{s['false_positive_rate']:.1%}"
            _log(f"    {label:<34} {s['visible_frames']:>7} {rate:>9} {miou:>9} {s['negative_frames']:>9} {fp:>9}")


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    import torch

    torch.set_num_threads(args.threads)
    out: Path = args.out
    given = list(sys.argv[1:] if argv is None else argv)
    command = "python scripts/train_tiny_grounder.py " + shlex.join(given)
    if args.eval_only:
        from testing_support.tiny_grounder import META_FILE, grounder_spec

        meta = _read_meta(out / META_FILE)
        figures = _evaluate(out, args.eval_frames, meta.get("seed", args.seed), grounder_spec(out))
        _print_table(figures)
        meta["evaluation"] = figures
        (out / META_FILE).write_text(json.dumps(meta, indent=1) + "\n")
        return 0

    from tqdm import tqdm

    from testing_support.sim_dataset import MIN_BOX_SIDE_PX
    from testing_support.tiny_grounder import (
        EVAL_SEED_OFFSET,
        GROUNDER_MAX_PIXELS,
        META_FILE,
        RESIZED_HW,
        build_untrained_grounder,
        describe_stats,
        render_dataset,
        train_grounder,
        weights_bytes,
    )

    work = out.parent / f".{out.name}.building"
    shutil.rmtree(work, ignore_errors=True)
    t_start = time.monotonic()
    spec = SPECS[args.dataset]
    build_untrained_grounder(work, seed=args.seed, spec=spec)
    with tqdm(total=args.frames, desc="render", unit="frame", file=sys.stderr) as bar:
        data = render_dataset(args.frames, args.seed, progress=bar.update, spec=spec)
    _log(f"training frames: {describe_stats(data.stats)}")
    probe = None
    if args.probe_every and args.probe_frames:
        # probe frames come from the held-out stream too (a different slice than the final evaluation's)
        probe = render_dataset(args.probe_frames, args.seed + 2 * EVAL_SEED_OFFSET, spec=spec)
    render_min = (time.monotonic() - t_start) / 60
    trained = train_grounder(
        work,
        data,
        steps=args.steps,
        batch_size=args.batch,
        lr=args.lr,
        seed=args.seed,
        probe=probe,
        probe_every=args.probe_every,
        log=_log,
        stop_after=args.stop_after,
        max_minutes=args.max_minutes,
        spec=spec,
    )
    if trained["steps_done"] < args.steps and args.stop_after is None:
        # the run that happened, repeatable on any machine: same schedule, same stop, no clock
        if "--max-minutes" in given:
            i = given.index("--max-minutes")
            del given[i : i + 2]
        given += ["--stop-after", str(trained["steps_done"])]
        command = "python scripts/train_tiny_grounder.py " + shlex.join(given)
    figures = _evaluate(work, args.eval_frames, args.seed, spec)
    _print_table(figures)
    many = f"{len(spec.labels)} labels of {', '.join(spec.worlds)}"
    what = " / ".join(spec.labels) if len(spec.labels) <= 3 else many
    meta = {
        "what": f"tiny Qwen2.5-VL grounding {what} in go2vlm's MuJoCo worlds",
        "dataset": spec.name,
        "labels": {label: list(spec.label_bodies[label]) for label in spec.labels},
        "command": command,
        "seed": args.seed,
        "args": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
        "max_pixels": GROUNDER_MAX_PIXELS,
        "resized_hw": list(RESIZED_HW),
        "min_box_side_px": MIN_BOX_SIDE_PX,
        "training_frames": dict(data.stats),
        "render_minutes": round(render_min, 1),
        "train_minutes": trained["minutes"],
        "steps_done": trained["steps_done"],
        "train_history": trained["history"],
        "weights_bytes": weights_bytes(work),
        "versions": _versions(),
        "evaluation": figures,
    }
    (work / META_FILE).write_text(json.dumps(meta, indent=1) + "\n")
    if out.exists():
        shutil.rmtree(out)
    work.rename(out)
    _log(
        f"wrote {out}: {meta['weights_bytes'] / 1e6:.1f} MB of weights, "
        f"{meta['train_minutes']} min training, {(time.monotonic() - t_start) / 60:.1f} min in all"
    )
    return 0


def _read_meta(path: Path) -> dict[str, Any]:
    return json.loads(path.read_text()) if path.is_file() else {}


if __name__ == "__main__":
    sys.exit(main())
