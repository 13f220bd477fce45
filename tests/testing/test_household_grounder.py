"""The household grounding dataset and the tiny grounder trained on it (tests/data/tiny_grounder_household).

Fast: the dataset speaks the suites' language (every goal the household and referring suites give the
vlm node is a label, naming the task's own target), its labels name bodies of the world, frames carry
segmentation boxes and the world's per-episode lighting. Slow: the shipped checkpoint loads through the
product's loading code and grounds household objects in frames rendered now (poses it never saw).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from go2vlm.apps.episodes.suites import load_suite, world_bodies
from go2vlm.behavior.goals import parse_goal
from testing_support.sim_dataset import HOUSEHOLD, PRIMITIVES, FrameRenderer, sample_frames

TEST_SEED = 4243  # neither the build's training stream (0) nor its held-out ones (1000003, 2000006)


def test_every_goal_of_the_household_suites_is_a_label_naming_its_target() -> None:
    for name in ("household", "referring"):
        suite = load_suite(name)
        for task in suite.tasks:
            for goal in task.get("goals") or [task["goal"]]:
                label = parse_goal(goal).target.label  # what the commander asks the vlm node to ground
                assert label in HOUSEHOLD.labels, (name, goal)
                assert task["target"] in HOUSEHOLD.label_bodies[label], (name, goal, task["target"])


def test_labels_name_bodies_of_the_household_world() -> None:
    bodies = set(world_bodies("household"))
    assert set(HOUSEHOLD.bodies()) <= bodies
    assert len(HOUSEHOLD.label_bodies["box"]) == 4 and len(HOUSEHOLD.label_bodies["mug"]) == 2
    assert set(HOUSEHOLD.labels) == set(HOUSEHOLD.label_bodies) and not set(PRIMITIVES.labels) & {"teddy bear"}


def test_household_frames_have_boxes_rooms_and_lighting() -> None:
    with FrameRenderer(spec=HOUSEHOLD) as renderer:
        frames = list(sample_frames(renderer, 12, TEST_SEED))
        renderer.pose("household", -4.0, 1.5, 0.0)  # the living room, facing east: the coffee table ahead
        a = renderer.render("household")
        renderer.light("household", 1)
        b = renderer.render("household")
        renderer.light("household", 2)
        c = renderer.render("household")
    assert all(f.world == "household" and f.rgb.shape == (480, 640, 3) for f in frames)
    assert sum(bool(f.boxes) for f in frames) >= 6  # most frames are aimed at an object
    for f in frames:
        x, y, _ = f.pose
        assert -5.75 <= x <= 5.75 and -3.2 <= y <= 3.2 and not -0.3 < x < 0.3  # in a room, not in the wall
        for label, boxes in f.boxes.items():
            assert len(boxes) <= len(HOUSEHOLD.label_bodies[label])
            assert all(0 <= x1 < x2 <= 640 and 0 <= y1 < y2 <= 480 for x1, y1, x2, y2 in boxes)
    # a phrase labels its referent alone, a category every body of it
    with_ball = [f for f in frames if f.visible("red ball")]
    for f in with_ball:
        assert f.boxes["ball under the table"] == f.boxes["red ball"]
    assert a.boxes == b.boxes == c.boxes and "coffee table" in a.boxes  # lighting moves no box
    assert not np.array_equal(b.rgb, c.rgb)  # ... but changes the picture


# ------------------------------------------------------------------------------- the checkpoint
@pytest.fixture(scope="module")
def household_ckpt() -> Path:
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    from testing_support.tiny_grounder import household_grounder_checkpoint

    return household_grounder_checkpoint()


def test_shipped_household_checkpoint_files_and_figures(household_ckpt: Path) -> None:
    from testing_support.tiny_grounder import META_FILE, grounder_spec

    assert grounder_spec(household_ckpt) is HOUSEHOLD
    assert (household_ckpt / "model.safetensors").stat().st_size < 12_000_000
    meta = json.loads((household_ckpt / META_FILE).read_text())
    assert "--dataset household" in meta["command"] and meta["labels"]["second box from the left"] == ["box_3"]
