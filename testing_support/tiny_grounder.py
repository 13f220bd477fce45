"""A tiny Qwen2.5-VL that really grounds "red ball", "green box" and "blue cylinder" in our sim.

:mod:`.tiny_qwen` makes checkpoints that say one fixed text. This one is trained, offline on a
CPU, on head-camera frames of the vision_test, follow_ball and obstacles worlds
(:mod:`.sim_dataset`), with the prompts the product sends (``detect_prompt`` with one label, or
all three) and Qwen2.5-VL's own answer format, boxes in pixels of the resized image. Its
held-out figures and the exact build command are in ``go2vlm_grounder.json`` next to the weights.

The same build on the ``household`` dataset (``--dataset household``: the household world's
categories and the referring suite's phrases, one label per prompt or a few) makes the household
grounder, ``tests/data/tiny_grounder_household``.

The shipped checkpoint lives in ``tests/data/tiny_grounder`` (:func:`grounder_checkpoint`).
It sees every frame at :data:`GROUNDER_MAX_PIXELS` (168x224 for a 4:3 frame, 48 visual tokens):
its processor config says so, and :func:`grounder_settings` sets the node's ``max_pixels`` to it
(the node's default would give the model 391 tokens it was never trained on).

Build (about an hour on 2 CPU cores)::

    python scripts/train_tiny_grounder.py --seed 0 --frames 6000 --steps 3000 --out tests/data/tiny_grounder
"""

from __future__ import annotations

import itertools
import json
import math
import os
import random
import sys
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from testing_support.sim_dataset import (
    CAMERA_HW,
    PRIMITIVES,
    SPECS,
    Frame,
    FrameRenderer,
    GroundingSpec,
    answer_text,
    match_boxes,
    openai_view,
    processor_view,
    sample_frames,
)

__all__ = [
    "EVAL_SEED_OFFSET",
    "GROUNDER_MAX_PIXELS",
    "GROUNDER_MIN_PIXELS",
    "META_FILE",
    "RESIZED_HW",
    "GroundingData",
    "build_untrained_grounder",
    "eval_labels",
    "evaluate",
    "grounder_checkpoint",
    "grounder_spec",
    "household_grounder_checkpoint",
    "grounder_node_params",
    "grounder_settings",
    "label_sets",
    "render_dataset",
    "score_answer",
    "train_grounder",
    "weights_bytes",
]

GROUNDER_MAX_PIXELS = 168 * 224
GROUNDER_MIN_PIXELS = 56 * 56
RESIZED_HW = (168, 224)  # what a 480x640 frame becomes at GROUNDER_MAX_PIXELS
META_FILE = "go2vlm_grounder.json"
# Held-out frames come from seed + this: another random stream than any training seed nearby.
EVAL_SEED_OFFSET = 1_000_003
_SHIPPED = Path(__file__).resolve().parents[1] / "tests" / "data" / "tiny_grounder"
_SHIPPED_HOUSEHOLD = _SHIPPED.with_name("tiny_grounder_household")


def grounder_checkpoint() -> Path:
    """The shipped, trained checkpoint directory (``$GO2VLM_GROUNDER`` overrides it)."""
    return _checked(_SHIPPED, "GO2VLM_GROUNDER")


def household_grounder_checkpoint() -> Path:
    """The shipped household grounder (``$GO2VLM_HOUSEHOLD_GROUNDER`` overrides it)."""
    return _checked(_SHIPPED_HOUSEHOLD, "GO2VLM_HOUSEHOLD_GROUNDER")


def grounder_spec(path: str | os.PathLike[str]) -> GroundingSpec:
    """The dataset a checkpoint was trained on (``go2vlm_grounder.json``; older ones: the primitives)."""
    meta = Path(path) / META_FILE
    name = json.loads(meta.read_text()).get("dataset", PRIMITIVES.name) if meta.is_file() else PRIMITIVES.name
    return SPECS[name]


def _checked(shipped: Path, env_var: str) -> Path:
    path = Path(os.environ.get(env_var) or shipped)
    missing = [f for f in ("config.json", "model.safetensors", "tokenizer.json", META_FILE) if not (path / f).is_file()]
    if missing:
        raise FileNotFoundError(
            f"no tiny grounder checkpoint at {path} (missing {', '.join(missing)}). It ships in a source checkout "
            f"as tests/data/{shipped.name}; rebuild it with the command in docs/vlm.md "
            f"(python scripts/train_tiny_grounder.py ...) or point ${env_var} at a copy."
        )
    return path


def grounder_settings(path: str | os.PathLike[str], backend: str = "transformers", **overrides: Any) -> Any:
    """``BackendSettings`` for the grounder: CPU, its own pixel budget, room for a few boxes."""
    from go2vlm.perception.vlm.backend import BackendSettings

    settings = BackendSettings(
        model=str(path),
        backend=backend,
        device="cpu",
        max_pixels=GROUNDER_MAX_PIXELS,
        min_pixels=GROUNDER_MIN_PIXELS,
        max_new_tokens=160,
    )
    for key, value in overrides.items():
        setattr(settings, key, value)
    return settings


def grounder_node_params() -> dict[str, Any]:
    """The vlm node's parameters for the grounder (as `grounder_settings`), e.g. for an episode's `params["vlm"]`
    or `go2vlm demo -p vlm.NAME=VALUE`: CPU, the pixel budget of its own processor config (max_pixels=0:
    GROUNDER_MIN_PIXELS..GROUNDER_MAX_PIXELS), room for a few boxes, every frame it can."""
    return {"device": "cpu", "max_pixels": 0, "max_new_tokens": 160, "period_s": 0.0}


def label_sets(spec: GroundingSpec = PRIMITIVES) -> list[tuple[str, ...]]:
    """The label lists trained, known ahead: each label alone (goal, follow); for the primitives also all
    three, and the pairs and orders (a spec of many labels draws its few-label prompts as it goes)."""
    singles: list[tuple[str, ...]] = [(lab,) for lab in spec.labels]
    if not spec.all_labels_prompts:
        return singles
    every = spec.labels
    pairs = list(itertools.permutations(every, 2))
    triples = list(itertools.permutations(every, 3))
    return singles + [every] + pairs + [t for t in triples if t != every]


def _sample_labels(rng: random.Random, frame: Frame, spec: GroundingSpec = PRIMITIVES) -> tuple[str, ...]:
    labels = spec.labels
    r = rng.random()
    single = 0.55 if spec.all_labels_prompts else 0.8
    if r < single:
        seen = [lab for lab in labels if frame.visible(lab)]
        if seen and rng.random() < 0.7:
            return (rng.choice(seen),)
        return (rng.choice(labels),)
    if spec.all_labels_prompts and r < 0.85:
        return labels
    k = rng.choice((2, 3))
    return tuple(rng.sample(labels, k))


def eval_labels(frame: Frame, spec: GroundingSpec, rng: random.Random, negatives: int = 3) -> list[str]:
    """The labels asked about a held-out frame, one per prompt: every label for the primitives; for a spec
    of many labels, those the frame shows and a few it does not (`negatives`, drawn from `rng`)."""
    if spec.all_labels_prompts:
        return list(spec.labels)
    seen = [lab for lab in spec.labels if frame.visible(lab)]
    absent = [lab for lab in spec.labels if frame.negative(lab)]
    return seen + rng.sample(absent, min(negatives, len(absent)))


# ------------------------------------------------------------------------------------ checkpoint
def _tokenizer_corpus(seed: int, spec: GroundingSpec = PRIMITIVES) -> list[str]:
    """Chat scaffolding, every trained prompt and many answers: those strings become few tokens.

    Qwen's pre-tokenizer splits numbers into single digits, as in the real tokenizer, so each
    coordinate costs its digits plus ", "; the corpus makes the JSON around them cheap."""
    from go2vlm.perception.vlm.prompts import detect_prompt
    from testing_support.tiny_qwen import _TOKENIZER_CORPUS

    rng = random.Random(seed)
    texts = ["system\nYou are a helpful assistant.\nuser\nassistant\n"] * 8
    texts += [detect_prompt(labels) for labels in label_sets(spec)] * 4
    if not spec.all_labels_prompts:
        texts += [detect_prompt(rng.sample(spec.labels, rng.choice((2, 3)))) for _ in range(100)]
    texts += [detect_prompt(())] * 2
    for _ in range(300 if spec.all_labels_prompts else 600):
        items = []
        for _ in range(rng.randint(0, 3)):
            x1, y1 = rng.randint(0, 200), rng.randint(0, 150)
            box = [x1, y1, rng.randint(x1 + 1, 224), rng.randint(y1 + 1, 168)]
            items.append({"bbox_2d": box, "label": rng.choice(spec.labels)})
        texts.append(json.dumps(items))
    texts += ["0 1 2 3 4 5 6 7 8 9"] * 8
    return texts + list(_TOKENIZER_CORPUS)


def _grounder_config(vocab_size: int, special_ids: dict[str, int]) -> Any:
    """Text 4 x 192 (6 heads of 32), vision 4 x 96 with window attention and two full blocks:
    about 2.4M parameters, room to localise and small enough to ship."""
    from testing_support.tiny_qwen import _qwen_config

    hidden, heads = 192, 6
    text = {
        "vocab_size": vocab_size,
        "hidden_size": hidden,
        "intermediate_size": 448,
        "num_hidden_layers": 4,
        "num_attention_heads": heads,
        "num_key_value_heads": 2,
        "max_position_embeddings": 4096,
        "rms_norm_eps": 1e-6,
        # Where a visual token sits reaches the LLM only through M-RoPE. Qwen's [t, h, w] split gives w the
        # lowest frequencies: with 16 of them (head_dim 32) and theta 1e4 the 8 columns differ by < 0.03 rad,
        # and a tiny model never learnt x. So theta 100 and the split given twice, (t, h, w, t, h, w): the
        # rotary code cycles t/h/w over the chunks, so rows and columns get fast and slow frequencies alike.
        "rope_parameters": {"rope_type": "default", "rope_theta": 100.0, "mrope_section": [2, 3, 3, 2, 3, 3]},
        "bos_token_id": special_ids["<|endoftext|>"],
        "eos_token_id": special_ids["<|im_end|>"],
        "pad_token_id": special_ids["<|endoftext|>"],
        "use_sliding_window": False,
    }
    vision = {
        "depth": 4,
        "hidden_size": 96,
        "intermediate_size": 192,
        "num_heads": 3,
        "out_hidden_size": hidden,
        "patch_size": 14,
        "spatial_merge_size": 2,
        "temporal_patch_size": 2,
        "window_size": 112,
        "fullatt_block_indexes": [1, 3],
        "tokens_per_second": 2,
        "in_channels": 3,
    }
    config = _qwen_config(text, vision, special_ids, tie_word_embeddings=False)
    config.architectures = ["Qwen2_5_VLForConditionalGeneration"]
    return config


def build_untrained_grounder(
    out_dir: str | os.PathLike[str], *, seed: int = 0, spec: GroundingSpec = PRIMITIVES
) -> Path:
    """Write the random-init grounder (model, tokenizer, processor with its pixel budget) to ``out_dir``."""
    import torch
    from transformers import Qwen2_5_VLForConditionalGeneration

    from testing_support.tiny_qwen import QWEN_SPECIAL_TOKENS, _train_tokenizer, save_checkpoint

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tokenizer = _train_tokenizer(spec.vocab_size, _tokenizer_corpus(seed, spec))
    special_ids = {t: int(tokenizer.convert_tokens_to_ids(t)) for t in QWEN_SPECIAL_TOKENS}
    config = _grounder_config(len(tokenizer), special_ids)
    torch.manual_seed(seed)
    model = Qwen2_5_VLForConditionalGeneration._from_config(config, dtype=torch.float32)
    save_checkpoint(model, tokenizer, special_ids, GROUNDER_MIN_PIXELS, GROUNDER_MAX_PIXELS, out)
    return out


# ------------------------------------------------------------------------------------ data
@dataclass
class GroundingData:
    """Rendered frames kept small: the image the model sees (168x224) and the ground truth."""

    views: np.ndarray  # (N, 168, 224, 3) uint8
    frames: list[Frame]  # ground truth; their rgb is dropped to save memory
    stats: Counter[str] = field(default_factory=Counter)


def render_dataset(
    n: int,
    seed: int,
    *,
    progress: Callable[[int], None] | None = None,
    keep_rgb: bool = False,
    spec: GroundingSpec = PRIMITIVES,
) -> GroundingData:
    """``n`` frames from :func:`sample_frames`, each reduced to 168x224 as one of the two backends
    would (the transformers processor's resize, or the openai backend's resize + JPEG)."""
    rng = np.random.default_rng(seed + 17)
    views = np.empty((n, *RESIZED_HW, 3), dtype=np.uint8)
    frames: list[Frame] = []
    stats: Counter[str] = Counter()
    with FrameRenderer(spec=spec) as renderer:
        for i, frame in enumerate(sample_frames(renderer, n, seed)):
            view = openai_view if rng.random() < 0.4 else processor_view
            views[i] = view(frame.rgb, RESIZED_HW)
            stats[frame.world] += 1
            stats[f"objects={sum(len(b) for b in frame.boxes.values())}"] += 1
            for label in spec.labels:
                stats[label] += frame.visible(label)
            if not keep_rgb:
                frame.rgb = np.empty((0, 0, 3), dtype=np.uint8)
            frames.append(frame)
            if progress is not None:
                progress(1)
    return GroundingData(views=views, frames=frames, stats=stats)


def _chat_text(processor: Any, prompt: str) -> str:
    """The user turn exactly as the transformers backend builds it: one image, then the prompt."""
    messages = [{"role": "user", "content": [{"type": "image"}, {"type": "text", "text": prompt}]}]
    return str(processor.apply_chat_template(messages, tokenize=False, add_generation_prompt=True))


def _flip(frame: Frame) -> Frame:
    w = frame.camera_hw[1]
    boxes = {lab: [(w - b[2], b[1], w - b[0], b[3]) for b in bs] for lab, bs in frame.boxes.items()}
    return Frame(frame.world, frame.pose, frame.rgb, boxes, set(frame.ambiguous), frame.camera_hw)


class _Batcher:
    """Builds training batches: cached prompt ids, the answer's ids, loss on the answer only."""

    def __init__(self, processor: Any, data: GroundingData, seed: int, spec: GroundingSpec = PRIMITIVES) -> None:
        self.processor = processor
        self.data = data
        self.spec = spec
        self.rng = random.Random(seed)
        tok = processor.tokenizer
        self.pad_id = int(tok.convert_tokens_to_ids("<|endoftext|>"))
        self.end_id = int(tok.convert_tokens_to_ids("<|im_end|>"))
        self.image_id = int(tok.convert_tokens_to_ids("<|image_pad|>"))
        self._prompt_ids: dict[tuple[str, ...], list[int]] = {}

    def prompt_ids(self, labels: tuple[str, ...]) -> list[int]:
        """The prompt's ids with the image's visual tokens in place (computed once per label list)."""
        if labels not in self._prompt_ids:
            from go2vlm.perception.vlm.prompts import detect_prompt

            n_visual = (RESIZED_HW[0] // 28) * (RESIZED_HW[1] // 28)
            text = _chat_text(self.processor, detect_prompt(labels))
            text = text.replace("<|image_pad|>", "<|image_pad|>" * n_visual)
            self._prompt_ids[labels] = self.processor.tokenizer(text, add_special_tokens=False)["input_ids"]
        return self._prompt_ids[labels]

    def example(self, index: int, labels: tuple[str, ...], flip: bool) -> tuple[np.ndarray, list[int], list[int]]:
        frame = self.data.frames[index]
        view = self.data.views[index]
        if flip:  # a mirrored scene is as valid as the scene: twice the poses for free
            frame, view = _flip(frame), view[:, ::-1]
        answer = answer_text(frame, labels, RESIZED_HW)
        answer_ids = self.processor.tokenizer(answer, add_special_tokens=False)["input_ids"] + [self.end_id]
        return np.ascontiguousarray(view), self.prompt_ids(labels), answer_ids

    def batch(self, size: int) -> dict[str, Any]:
        import torch

        rows: list[tuple[np.ndarray, list[int], list[int]]] = []
        while len(rows) < size:
            i = self.rng.randrange(len(self.data.frames))
            labels = _sample_labels(self.rng, self.data.frames[i], self.spec)
            if any(lab in self.data.frames[i].ambiguous for lab in labels) and len(labels) == 1:
                continue  # a speck: no right answer to teach
            rows.append(self.example(i, labels, self.rng.random() < 0.5))
        length = max(len(p) + len(a) for _, p, a in rows)
        ids = torch.full((size, length), self.pad_id, dtype=torch.long)
        labels_t = torch.full((size, length), -100, dtype=torch.long)
        mask = torch.zeros((size, length), dtype=torch.long)
        for r, (_, p, a) in enumerate(rows):
            n = len(p) + len(a)
            ids[r, :n] = torch.tensor(p + a)
            labels_t[r, len(p) : n] = torch.tensor(a)
            mask[r, :n] = 1
        images = self.processor.image_processor(
            [v for v, _, _ in rows],
            return_tensors="pt",
            size={"shortest_edge": GROUNDER_MIN_PIXELS, "longest_edge": GROUNDER_MAX_PIXELS},
        )
        return {
            "input_ids": ids,
            "attention_mask": mask,
            "labels": labels_t,
            "pixel_values": images["pixel_values"],
            "image_grid_thw": images["image_grid_thw"],
            "mm_token_type_ids": (ids == self.image_id).long(),
        }


# ------------------------------------------------------------------------------------ training
def train_grounder(
    ckpt_dir: str | os.PathLike[str],
    data: GroundingData,
    *,
    steps: int,
    batch_size: int = 16,
    lr: float = 1.5e-3,
    seed: int = 0,
    probe: GroundingData | None = None,
    probe_every: int = 0,
    log: Callable[[str], None] = print,
    show_bar: bool = True,
    stop_after: int | None = None,
    max_minutes: float | None = None,
    spec: GroundingSpec = PRIMITIVES,
) -> dict[str, Any]:
    """Train the checkpoint in ``ckpt_dir`` in place (AdamW, warm-up then cosine, loss on answers).

    ``probe``: a few held-out frames decoded greedily every ``probe_every`` steps (single-label
    prompts, boxes compared in resized pixels) so a long run shows whether it is localising.

    The schedule always spans ``steps``; ``stop_after`` ends the run early at that step, and
    ``max_minutes`` does so at the first multiple of 100 steps past the budget (a shared 2-core
    machine's speed varies 3x). The result's ``steps_done`` is what to pass as ``stop_after`` to
    repeat the run."""
    import torch
    from transformers import AutoProcessor, Qwen2_5_VLForConditionalGeneration

    ckpt = Path(ckpt_dir)
    torch.manual_seed(seed)
    processor = AutoProcessor.from_pretrained(ckpt)
    model = Qwen2_5_VLForConditionalGeneration.from_pretrained(ckpt, dtype=torch.float32)
    model.train()
    batcher = _Batcher(processor, data, seed, spec)
    decay = [p for n, p in model.named_parameters() if p.ndim >= 2 and "embed" not in n]
    no_decay = [p for n, p in model.named_parameters() if not (p.ndim >= 2 and "embed" not in n)]
    optim = torch.optim.AdamW(
        [{"params": decay, "weight_decay": 0.01}, {"params": no_decay, "weight_decay": 0.0}], lr=lr, betas=(0.9, 0.98)
    )
    warm = max(1, steps // 20)

    def lr_at(step: int) -> float:
        if step < warm:
            return lr * (step + 1) / warm
        t = (step - warm) / max(1, steps - warm)
        return lr * (0.05 + 0.95 * 0.5 * (1.0 + math.cos(math.pi * t)))

    bar = None
    if show_bar:
        from tqdm import tqdm

        bar = tqdm(total=steps, desc="train", unit="step", dynamic_ncols=True, file=sys.stderr)
    history: list[dict[str, float]] = []
    t0 = time.monotonic()
    ema = None
    last = steps if stop_after is None else min(steps, stop_after)
    for step in range(last):
        for group in optim.param_groups:
            group["lr"] = lr_at(step)
        batch = batcher.batch(batch_size)
        loss = model(**batch).loss
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        optim.step()
        optim.zero_grad(set_to_none=True)
        value = float(loss.detach())
        ema = value if ema is None else 0.98 * ema + 0.02 * value
        if bar is not None:
            bar.update(1)
            bar.set_postfix(loss=f"{ema:.3f}", lr=f"{lr_at(step):.1e}")
        done = step + 1
        out_of_time = max_minutes is not None and (time.monotonic() - t0) / 60 > max_minutes and done % 100 == 0
        if done % 100 == 0 or done == last:
            entry = {"step": done, "loss": round(ema, 4), "minutes": round((time.monotonic() - t0) / 60, 2)}
            if probe is not None and probe_every and (done % probe_every == 0 or done == last or out_of_time):
                model.eval()
                entry.update(_probe(model, processor, probe, spec))
                model.train()
            history.append(entry)
            log(json.dumps(entry))
        if out_of_time:
            last = done
            log(f"time budget of {max_minutes} min spent: stopping after step {done} of {steps}")
            break
    if bar is not None:
        bar.close()
    model.eval()
    model.save_pretrained(ckpt)
    return {
        "steps": steps,
        "steps_done": last,
        "minutes": round((time.monotonic() - t0) / 60, 1),
        "history": history,
    }


def _probe(model: Any, processor: Any, probe: GroundingData, spec: GroundingSpec = PRIMITIVES) -> dict[str, float]:
    """Greedy single-label answers on the probe frames: IoU>=0.5 rate and parse failures (resized pixels)."""
    import torch
    from PIL import Image

    from go2vlm.perception.vlm.prompts import detect_prompt
    from go2vlm.vocabulary.answers import parse_grounding

    hits = visible = fails = asked = 0
    rng = random.Random(0)
    with torch.inference_mode():
        for frame, view in zip(probe.frames, probe.views, strict=True):
            for label in eval_labels(frame, spec, rng, negatives=1):
                if label in frame.ambiguous:
                    continue
                text = _chat_text(processor, detect_prompt([label]))
                enc = processor(
                    text=[text],
                    images=[Image.fromarray(view)],
                    return_tensors="pt",
                    size={"shortest_edge": GROUNDER_MIN_PIXELS, "longest_edge": GROUNDER_MAX_PIXELS},
                )
                out = model.generate(**enc, max_new_tokens=100, do_sample=False)
                answer = processor.tokenizer.decode(out[0, enc["input_ids"].shape[1] :], skip_special_tokens=True)
                parsed = parse_grounding(answer, labels=[label])
                asked += 1
                fails += not parsed.found_json
                if frame.visible(label):
                    visible += 1
                    truth = [_resized_box(b) for b in frame.boxes[label]]
                    ious = match_boxes(truth, [b.box for b in parsed.boxes])
                    hits += all(iou >= 0.5 for iou in ious)
    return {"probe_hit": round(hits / max(1, visible), 3), "probe_parse_fail": round(fails / max(1, asked), 3)}


def _resized_box(box: Sequence[float]) -> tuple[float, float, float, float]:
    sy, sx = RESIZED_HW[0] / CAMERA_HW[0], RESIZED_HW[1] / CAMERA_HW[1]
    return (box[0] * sx, box[1] * sy, box[2] * sx, box[3] * sy)


# ------------------------------------------------------------------------------------ evaluation
@dataclass
class _Tally:
    visible: int = 0
    hits: int = 0
    ious: list[float] = field(default_factory=list)
    negatives: int = 0
    false_pos: int = 0
    extra_boxes: int = 0

    def add(self, other: _Tally) -> None:
        self.visible += other.visible
        self.hits += other.hits
        self.ious += other.ious
        self.negatives += other.negatives
        self.false_pos += other.false_pos
        self.extra_boxes += other.extra_boxes

    def summary(self) -> dict[str, Any]:
        return {
            "visible_frames": self.visible,
            "iou50_rate": round(self.hits / self.visible, 3) if self.visible else None,
            "mean_iou": round(float(np.mean(self.ious)), 3) if self.ious else None,
            "negative_frames": self.negatives,
            "false_positive_rate": round(self.false_pos / self.negatives, 3) if self.negatives else None,
            "extra_boxes": self.extra_boxes,
        }


def score_answer(frame: Frame, label: str, boxes: Sequence[Any]) -> _Tally:
    """One frame and one label: did the answer's boxes (camera pixels) match the ground truth?

    Visible: a hit when every true box has a distinct answer box with IoU >= 0.5. Negative (not
    seen at all): any box is a false positive. A speck (see sim_dataset) counts neither way."""
    tally = _Tally()
    pred = [b.box for b in boxes if b.label == label]
    if frame.visible(label):
        ious = match_boxes(frame.boxes[label], pred)
        tally.visible = 1
        tally.hits = int(all(iou >= 0.5 for iou in ious))
        tally.ious = ious
        tally.extra_boxes = max(0, len(pred) - sum(iou > 0 for iou in ious))
    elif frame.negative(label):
        tally.negatives = 1
        tally.false_pos = int(bool(pred))
    return tally


def evaluate(
    backend: Any,
    frames: Sequence[Frame],
    *,
    progress: Callable[[int], None] | None = None,
    spec: GroundingSpec = PRIMITIVES,
    seed: int = 0,
) -> dict[str, Any]:
    """Held-out figures through a loaded backend (the product's generate -> parse -> finalize path).

    Prompt kinds per frame: each label alone (as the goal and the follower ask; for a spec of many
    labels, those in view and three that are not, drawn from `seed`) and, for the primitives, all
    three in one prompt. Per label and overall: IoU>=0.5 rate on frames where it is visible, mean IoU,
    false-positive rate on frames without it, answers whose JSON did not parse."""
    from go2vlm.perception.vlm.prompts import detect_prompt
    from go2vlm.vocabulary.answers import answer_boxes

    rng = random.Random(seed)
    asked: dict[int, list[tuple[str, ...]]] = {
        id(frame): [(lab,) for lab in eval_labels(frame, spec, rng)] for frame in frames
    }
    kinds: list[tuple[str, Callable[[Frame], list[tuple[str, ...]]]]] = [("single", lambda f: asked[id(f)])]
    if spec.all_labels_prompts:
        kinds.append(("all_three", lambda f: [spec.labels]))
    results: dict[str, Any] = {}
    for kind, prompts_of in kinds:
        per_label = {lab: _Tally() for lab in spec.labels}
        answers = parse_fail = repaired = 0
        for frame in frames:
            for labels in prompts_of(frame):
                gen = backend.generate(frame.rgb, detect_prompt(labels))
                parsed, boxes = answer_boxes(gen, labels)
                answers += 1
                parse_fail += not parsed.found_json
                repaired += parsed.counters["parse.json_repaired"] > 0
                for label in labels:
                    per_label[label].add(score_answer(frame, label, boxes))
                if progress is not None:
                    progress(1)
        overall = _Tally()
        for tally in per_label.values():
            overall.add(tally)
        results[kind] = {
            "labels": {lab: t.summary() for lab, t in per_label.items()},
            "overall": overall.summary(),
            "answers": answers,
            "parse_fail_rate": round(parse_fail / max(1, answers), 4),
            "json_repaired_rate": round(repaired / max(1, answers), 4),
        }
    return results


def weights_bytes(ckpt: str | os.PathLike[str]) -> int:
    return sum(p.stat().st_size for p in Path(ckpt).glob("*.safetensors"))


def describe_stats(stats: Counter[str]) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(stats.items()))
