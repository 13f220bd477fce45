"""The shipped tiny grounder really grounds: frames rendered now by the MuJoCo sim (poses it never
saw in training), boxes through the product's parse -> finalize path, IoU against segmentation.

Thresholds sit below what the build measured (tests/data/tiny_grounder/go2vlm_grounder.json), with
a margin for a few unlucky frames; each test says which figure it guards.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from go2vlm.geometry.qwen import CoordSystem
from go2vlm.perception.vlm.prompts import detect_prompt
from go2vlm.vocabulary.answers import Box, finalize_boxes, parse_grounding
from testing_support.sim_dataset import (
    ALL_LABELS,
    Frame,
    FrameRenderer,
    answer_text,
    box_iou,
    match_boxes,
    sample_frames,
)
from testing_support.tiny_grounder import (
    EVAL_SEED_OFFSET,
    GROUNDER_MAX_PIXELS,
    META_FILE,
    RESIZED_HW,
    grounder_checkpoint,
    grounder_settings,
)

# Not the training stream (seed 0) nor the build's held-out streams (1000003, 2000006).
TEST_SEED = 4242
PER_LABEL = 5


@pytest.fixture(scope="module")
def scenes() -> dict[str, Any]:
    """Frames per label where it is visible, and frames where nothing at all is seen."""
    with FrameRenderer() as renderer:
        frames = list(sample_frames(renderer, 80, TEST_SEED))
    by_label = {lab: [f for f in frames if f.visible(lab)][:PER_LABEL] for lab in ALL_LABELS}
    for lab, fs in by_label.items():
        assert len(fs) == PER_LABEL, f"only {len(fs)} test frames show a {lab}"
    empty = [f for f in frames if not f.boxes and not f.ambiguous][:4]
    assert len(empty) == 4
    return {"by_label": by_label, "empty": empty}


def boxes_of(gen: Any, labels: list[str]) -> tuple[list[Box], bool]:
    parsed = parse_grounding(gen.text, labels=labels)
    counters: Counter[str] = Counter()
    boxes = finalize_boxes(
        parsed.boxes, coords=gen.coords, resized_hw=gen.resized_hw, original_hw=gen.original_hw, counters=counters
    )
    return boxes, parsed.found_json


def grounding_hits(backend: Any, scenes: dict[str, Any]) -> dict[str, list[float]]:
    """Per label, the worst IoU of the true boxes in each frame (all must be found for a hit)."""
    out: dict[str, list[float]] = {}
    for label, frames in scenes["by_label"].items():
        for frame in frames:
            gen = backend.generate(frame.rgb, detect_prompt([label]))
            assert gen.resized_hw == RESIZED_HW and gen.coords is CoordSystem.RESIZED_PIXELS
            boxes, found_json = boxes_of(gen, [label])
            assert found_json, gen.text
            ious = match_boxes(frame.boxes[label], [b.box for b in boxes if b.label == label])
            out.setdefault(label, []).append(min(ious))
    return out


def assert_grounds(ious: dict[str, list[float]]) -> None:
    hits = {label: sum(v >= 0.5 for v in values) for label, values in ious.items()}
    total = sum(hits.values())
    # The build measured IoU>=0.5 on 39 % of held-out frames with one label per prompt (red ball 50 %,
    # green box 36 %, blue cylinder 22 %; go2vlm_grounder.json) and 5/15 on these frames. 3 of 15 (20 %)
    # leaves room for renderer/CPU differences, while a model that does not localise scores 0 (untrained: 0/15).
    assert total >= 3, f"IoU>=0.5 on {total}/15: {ious}"
    # and it is not one label carrying the rest: every label's boxes overlap the truth somewhere
    assert all(max(values) > 0.3 for values in ious.values()), ious


# --------------------------------------------------------------------------------- no model
def test_answer_round_trips_through_the_product_parser() -> None:
    """The training answer, parsed and finalised as the node does, lands back on the true boxes."""
    frame = Frame(
        world="x",
        pose=(0.0, 0.0, 0.0),
        rgb=np.zeros((480, 640, 3), np.uint8),
        boxes={
            "red ball": [(100.0, 200.0, 180.0, 260.0), (600.0, 0.0, 640.0, 40.0)],
            "blue cylinder": [(0.0, 0.0, 50.0, 480.0)],
        },
    )
    text = answer_text(frame, ("blue cylinder", "red ball", "green box"), RESIZED_HW)
    assert text.startswith('[{"bbox_2d": [0, 0, 18, 168], "label": "blue cylinder"}')
    parsed = parse_grounding(text, labels=list(ALL_LABELS))
    assert not parsed.counters and [b.label for b in parsed.boxes] == ["blue cylinder", "red ball", "red ball"]
    counters: Counter[str] = Counter()
    boxes = finalize_boxes(
        parsed.boxes,
        coords=CoordSystem.RESIZED_PIXELS,
        resized_hw=RESIZED_HW,
        original_hw=(480, 640),
        counters=counters,
    )
    for label, truth in frame.boxes.items():
        ious = match_boxes(truth, [b.box for b in boxes if b.label == label])
        assert min(ious) > 0.9, (label, ious)
    assert answer_text(frame, ("green box",), RESIZED_HW) == "[]"


def test_iou_and_matching() -> None:
    assert box_iou((0, 0, 10, 10), (0, 0, 10, 10)) == 1.0
    assert box_iou((0, 0, 10, 10), (5, 0, 15, 10)) == pytest.approx(1 / 3)
    assert box_iou((0, 0, 1, 1), (2, 2, 3, 3)) == 0.0
    # one predicted box cannot count for two true boxes
    assert match_boxes([(0, 0, 10, 10), (1, 0, 11, 10)], [(0, 0, 10, 10)]) == [1.0, 0.0]


def test_sim_frames_have_segmentation_boxes() -> None:
    """Ground truth comes from the segmentation render: boxes tight around the object's pixels."""
    with FrameRenderer(worlds=("vision_test",)) as renderer:
        renderer.pose("vision_test", 0.0, 0.0, 0.0)  # the red sphere 2 m straight ahead
        frame = renderer.render("vision_test")
    (box,) = frame.boxes["red ball"]
    assert abs((box[0] + box[2]) / 2 - 320) < 4 and 100 < box[2] - box[0] < 300
    red = (frame.rgb[:, :, 0] > 150) & (frame.rgb[:, :, 1] < 80) & (frame.rgb[:, :, 2] < 80)
    ys, xs = np.nonzero(red)
    assert (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1) == pytest.approx(box, abs=3)
    assert not frame.visible("green box") and not frame.visible("blue cylinder")


def test_shipped_checkpoint_files_and_figures(grounder_ckpt: Path) -> None:
    config = json.loads((grounder_ckpt / "config.json").read_text())
    assert config["model_type"] == "qwen2_5_vl"
    proc = json.loads((grounder_ckpt / "processor_config.json").read_text())
    assert proc["image_processor"]["size"]["longest_edge"] == GROUNDER_MAX_PIXELS
    assert (grounder_ckpt / "model.safetensors").stat().st_size < 11_000_000
    meta = json.loads((grounder_ckpt / META_FILE).read_text())
    assert "train_tiny_grounder.py" in meta["command"] and meta["seed"] == 0
    assert meta["evaluation"]["seed"] == meta["seed"] + EVAL_SEED_OFFSET
    assert meta["evaluation"]["single"]["overall"]["iou50_rate"] >= 0.3  # measured 0.39


def test_missing_checkpoint_is_a_clear_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("GO2VLM_GROUNDER", str(tmp_path))
    with pytest.raises(FileNotFoundError, match="train_tiny_grounder"):
        grounder_checkpoint()


# --------------------------------------------------------------------------------- the model
@pytest.fixture(scope="module")
def hf_backend(grounder_ckpt: Path):  # noqa: ANN201
    from go2vlm.perception.vlm.hf_backend import TransformersBackend

    backend = TransformersBackend(grounder_settings(grounder_ckpt))
    backend.load()
    yield backend
    backend.close()


@pytest.mark.slow
def test_grounds_sim_objects_transformers_backend(hf_backend: Any, scenes: dict[str, Any]) -> None:
    assert_grounds(grounding_hits(hf_backend, scenes))


@pytest.mark.slow
def test_no_object_no_box(hf_backend: Any, scenes: dict[str, Any]) -> None:
    """Frames with none of the objects: `[]`, or at least no box of the asked label."""
    wrong = []
    for frame in scenes["empty"]:
        for labels in ([lab] for lab in ALL_LABELS):
            gen = hf_backend.generate(frame.rgb, detect_prompt(labels))
            boxes, found_json = boxes_of(gen, labels)
            assert found_json, gen.text
            if boxes:
                wrong.append((frame.pose, labels, gen.text))
    # The build measured 1.8 % false positives on held-out frames without the object: 1 of 12 is slack.
    assert len(wrong) <= 1, wrong


@pytest.mark.slow
def test_grounds_sim_objects_through_transformers_serve(
    grounder_ckpt: Path, grounder_server: str, scenes: dict[str, Any]
) -> None:
    """The same through the openai backend and a real OpenAI-compatible server on loopback: the client
    resizes to the model's 168x224 and JPEG-encodes, the server's processor leaves the size alone."""
    from go2vlm.perception.vlm.openai_backend import OpenAIBackend

    backend = OpenAIBackend(grounder_settings(grounder_ckpt, "openai", base_url=grounder_server))
    backend.load()
    try:
        assert_grounds(grounding_hits(backend, scenes))
    finally:
        backend.close()
