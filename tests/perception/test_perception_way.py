"""Which way to the object on the bus (perception/way.py): the /vlm/way envelope round-trips and
anything else is rejected with a reason; the oracle says `likely` exactly when the object lies within
the view's half angle of the heading; an answer placed at the heading the pose history had at its
frame's stamp scores the frontiers that way, not those the robot faces when the answer arrives."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from go2vlm.behavior.view_scores import parse_view_answer
from go2vlm.perception.way import WayMessageRejected, oracle_way, parse_way_message, way_message
from go2vlm.world.poses import PoseHistory
from go2vlm.world.value_map import ValueMap

finite = st.floats(-50, 50, allow_nan=False)
angle = st.floats(-math.pi, math.pi, allow_nan=False)


@given(st.floats(1e-3, 1e9, allow_nan=False), st.text(max_size=40), st.text(max_size=200))
def test_the_envelope_round_trips(stamp: float, obj: str, answer: str) -> None:
    assert parse_way_message(way_message(stamp, obj, answer)) == (stamp, obj, answer)


@pytest.mark.parametrize(
    ("text", "reason"),
    [("likely", "way_not_json"), ("[1, 2]", "way_bad_envelope"),
     ('{"stamp": 1, "answer": "likely"}', "way_bad_envelope"),
     ('{"stamp": 1, "object": "duck", "answer": "likely", "turn": 30}', "way_bad_envelope"),
     ('{"stamp": -1, "object": "duck", "answer": "likely"}', "way_bad_stamp"),
     ('{"stamp": true, "object": "duck", "answer": "likely"}', "way_bad_stamp"),
     ('{"stamp": "now", "object": "duck", "answer": "likely"}', "way_bad_stamp"),
     ('{"stamp": 1, "object": "duck", "answer": 1.0}', "way_bad_envelope"), ("x" * 5000, "way_too_long")],
)  # fmt: skip
def test_anything_else_is_rejected_with_a_reason(text: str, reason: str) -> None:
    with pytest.raises(WayMessageRejected) as err:
        parse_way_message(text)
    assert err.value.reason == reason


@given(finite, finite, angle, st.floats(0.5, 20), angle, st.floats(0.05, 3.1))
def test_the_oracle_says_likely_within_the_view(x: float, y: float, yaw: float, r: float, off: float,
                                               half: float) -> None:  # fmt: skip
    tx, ty = x + r * math.cos(yaw + off), y + r * math.sin(yaw + off)
    word = oracle_way(x, y, yaw, tx, ty, half)
    assert parse_view_answer(word) in (0.0, 1.0)  # always a whitelisted word
    if abs(abs(off) - half) > 1e-6:
        assert word == ("likely" if abs(off) < half else "unlikely")


@given(angle, st.floats(0.2, 1.0), st.floats(0.0, 2.0))
def test_an_answer_is_placed_at_its_frames_heading(yaw0: float, rate: float, when: float) -> None:
    """The robot turns at `rate`; an answer about the frame at `when` arrives at the end of the turn:
    its score lies on the value map ahead of the frame's heading, not where the robot faces now."""
    hist = PoseHistory()
    for k in range(61):
        hist.add(k * 0.05, 0.0, 0.0, yaw0 + rate * k * 0.05)
    values = ValueMap()
    at = hist.at(when)
    values.observe(at.x, at.y, at.yaw, math.radians(73), parse_view_answer("likely"), None)
    assert values.at(3 * math.cos(at.yaw), 3 * math.sin(at.yaw)) == 1.0
    end = hist.at(3.0).yaw
    if abs(math.remainder(end - at.yaw, 2 * math.pi)) > math.radians(73) / 2 + 0.3:
        assert values.at(3 * math.cos(end), 3 * math.sin(end)) == values.unscored  # not where it faces now
