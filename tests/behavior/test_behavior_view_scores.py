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
from go2vlm.behavior.view_scores import SCORES, ViewAnswerRejected, parse_view_answer


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
    vlm.values.observe(*robot, math.pi, math.radians(73), 1.0, cm)  # looking west: likely
    vlm.values.observe(*robot, 0.0, math.radians(73), 0.0, cm)  # east: unlikely
    vlm.step(*robot, 0.0, 1.1)
    assert vlm.frontier is not None and vlm.frontier.centroid[0] < 8.0


def corridor_with_a_door() -> Costmap:
    """A known corridor 12 x 2 m along x (walls at y = 0 and 2), open (unknown) at its east end, and a
    door 1 m wide at x 5-6 in its north wall onto unknown space; its west end walled."""
    g = np.full((120, 280), -1, np.int8)  # 14 x 6 m at 0.05 m, origin (0, 0)
    g[0:40, 0:240] = 0
    g[0, 0:240] = g[39, 0:240] = 100
    g[0:40, 0] = 100
    g[39, 100:120] = 0  # the door
    return Costmap(g, 0.05, (0.0, 0.0), 1.0)


def test_a_view_scored_likely_keeps_its_frontier_once_the_robot_walks_on() -> None:
    """From the doorway the model says the way north, through the door, is likely; the robot then
    walks 3.5 m east, nearer the corridor's open end, which no view has scored. The door's
    frontier keeps its value where it is on the map: exploration still chooses it. (A score kept by
    the heading it was given at, read back along the bearing from where the robot stands now, lost
    the door as soon as the robot walked past it.)"""
    cm = corridor_with_a_door()
    vlm = Explorer(ExploreParams(frontier_choice="vlm"))
    vlm.set_map(cm)
    view = math.radians(73)
    vlm.values.observe(5.5, 1.0, math.pi / 2, view, 1.0, cm)  # north through the door: likely
    vlm.step(9.0, 1.0, 0.0, 1.1)
    assert vlm.frontier is not None, vlm.reason
    fx, fy = vlm.frontier.centroid
    assert 4.5 < fx < 7.0 and fy > 1.5, vlm.frontier.centroid  # the door's, not the corridor's end (x = 12)
    near = Explorer(ExploreParams(frontier_choice="nearest"))
    near.set_map(cm)
    near.step(9.0, 1.0, 0.0, 1.1)
    assert near.frontier is not None and near.frontier.centroid[0] > 10.0  # nearest: the corridor's end
