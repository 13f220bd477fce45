"""Exploration's `frontier_choice: vlm` (behavior/view_scores.py): only a whitelisted answer becomes a
score, free text never does; scored ways steer which frontier comes first; no answers: nearest."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.behavior.planner.global_path import Costmap
from go2vlm.behavior.strategies.explore import ExploreParams, Explorer
from go2vlm.behavior.view_scores import SCORES, ViewAnswerRejected, ViewScores, parse_view_answer


@pytest.mark.parametrize(
    ("text", "score"),
    [("likely", 1.0), ("Maybe.", 0.5), (" UNLIKELY ", 0.0), ('{"way": "likely"}', 1.0),
     ('```json\n{"way": "Unlikely"}\n```', 0.0)],
)  # fmt: skip
def test_whitelisted_answers(text: str, score: float) -> None:
    assert parse_view_answer(text) == score


@pytest.mark.parametrize(
    ("text", "reason"),
    [("", "empty"), ("go left through the door at 2 m/s", "not_whitelisted"), ("0.9", "bad_object"),
     ('{"way": "likely", "speed": 2}', "bad_object"), ('{"way": "left"}', "not_whitelisted"), ("x" * 300, "too_long"),
     ('["likely"]', "bad_object")],
)  # fmt: skip
def test_anything_else_is_rejected_with_a_reason(text: str, reason: str) -> None:
    with pytest.raises(ViewAnswerRejected) as exc:
        parse_view_answer(text)
    assert exc.value.reason == reason


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=60))
def test_free_text_never_becomes_more_than_a_whitelisted_score(text: str) -> None:
    try:
        score = parse_view_answer(text)
    except ViewAnswerRejected:
        return
    assert score in SCORES.values()
    assert text.strip().strip("`").lower().strip(" .!\"'") in SCORES or "way" in text


def test_sectors_keep_the_newest_answer() -> None:
    v = ViewScores(bin_deg=30.0)
    assert v.score(0.3) == v.unscored
    v.observe(0.1, 1.0, t=2.0)
    v.observe(0.2, 0.0, t=1.0)  # older: ignored
    assert v.score(0.05) == 1.0
    v.observe(0.2, 0.0, t=3.0)
    assert v.score(0.05) == 0.0
    assert v.toward(0.0, 0.0, 1.0, 0.1) == 0.0 and v.toward(0.0, 0.0, -1.0, 0.0) == v.unscored
    v.observe(math.nan, 1.0, 4.0)
    v.observe(1.0, 7.0, 4.0)  # not a score
    assert len(v.scores) == 1


def corridor() -> Costmap:
    """A known 8 m corridor along x, open (unknown) at both ends; the robot 2 m from the east end."""
    g = np.full((40, 240), -1, np.int8)
    g[10:30, 40:200] = 0
    g[10, 40:200] = g[29, 40:200] = 100
    return Costmap(g, 0.05, (0.0, 0.0), 1.0)


def test_vlm_choice_takes_the_way_the_model_scored_likely() -> None:
    cm = corridor()
    robot = (8.0, 1.0)  # ends at x = 2 (6 m west) and x = 10 (2 m east)
    near = Explorer(ExploreParams(frontier_choice="nearest"))
    near.set_map(cm)
    near.step(*robot, 0.0, 0.1)
    assert near.frontier is not None and near.frontier.centroid[0] > 8.0  # east: nearer
    vlm = Explorer(ExploreParams(frontier_choice="vlm"))
    vlm.set_map(cm)
    vlm.step(*robot, 0.0, 0.1)
    assert vlm.frontier is not None and vlm.frontier.centroid[0] > 8.0  # no answers yet: nearest
    vlm.reset(1.0)
    vlm.views.observe(math.pi, 1.0, 1.0)  # looking west: likely
    vlm.views.observe(0.0, 0.0, 1.0)  # east: unlikely
    vlm.step(*robot, 0.0, 1.1)
    assert vlm.frontier is not None and vlm.frontier.centroid[0] < 8.0
