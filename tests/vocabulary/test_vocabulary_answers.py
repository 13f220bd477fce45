"""Model output is untrusted: every malformed answer is sanitised or dropped and counted, never raised."""

from __future__ import annotations

import json
import math
from collections import Counter
from dataclasses import dataclass

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from go2vlm.geometry.qwen import CoordSystem
from go2vlm.vocabulary import answers as P
from go2vlm.vocabulary.answers import Box, answer_boxes, finalize_boxes, parse_grounding, sanitize_text

GOOD = '[{"bbox_2d": [10, 20, 30, 40], "label": "red ball"}]'


def boxes(text: str, **kw: object) -> tuple[list[Box], Counter[str]]:
    r = parse_grounding(text, **kw)  # type: ignore[arg-type]
    return r.boxes, r.counters


def test_bare_and_fenced() -> None:
    for text in (GOOD, f"```json\n{GOOD}\n```", f"Here you go:\n```\n{GOOD}\n```\nAnything else?"):
        got, c = boxes(text)
        assert got == [Box("red ball", (10.0, 20.0, 30.0, 40.0), None)], text
    got, c = boxes(f"The objects are {GOOD} as requested.")
    assert len(got) == 1 and c[P.C_JSON_REPAIRED] == 1


def test_truncated_json_keeps_complete_items() -> None:
    text = (
        '```json\n[{"bbox_2d": [1, 2, 3, 4], "label": "a"}, {"bbox_2d": [5, 6, 7, 8], "label": "b"}, {"bbox_2d": [9, '
    )
    got, c = boxes(text)
    assert [b.label for b in got] == ["a", "b"]
    assert c[P.C_JSON_REPAIRED] == 1


def test_no_json_and_non_list() -> None:
    got, c = boxes("I see a red ball on the left.")
    assert got == [] and c[P.C_NO_JSON] == 1
    got, c = boxes('{"bbox_2d": [1, 2, 3, 4], "label": "x"}')
    assert len(got) == 1 and c[P.C_NON_LIST] == 1
    got, c = boxes('{"objects": [{"bbox_2d": [1, 2, 3, 4], "label": "x"}]}')
    assert len(got) == 1
    for scalar in ("42", '"text"', "null", "true"):
        got, c = boxes(scalar)
        assert got == [] and (c[P.C_NON_LIST] == 1 or c[P.C_NO_JSON] == 1)
    got, c = boxes("[1, 2, [3]]")
    assert got == [] and c[P.C_ITEM_NOT_OBJECT] == 3


@pytest.mark.parametrize(
    "bbox, counter",
    [
        ("[NaN, 1, 2, 3]", P.C_NONFINITE),
        ("[Infinity, 1, 2, 3]", P.C_NONFINITE),
        ("[1e999, 1, 2, 3]", P.C_NONFINITE),
        ("[1e300, 1, 2, 3]", P.C_HUGE),
        ("[123456789012345678901234567890, 1, 2, 3]", P.C_HUGE),
        ("[1, 2, 3]", P.C_BAD_BBOX),
        ("[1, 2, 3, 4, 5]", P.C_BAD_BBOX),
        ('"1,2,3,4"', P.C_BAD_BBOX),
        ("[true, 1, 2, 3]", P.C_BAD_BBOX),
        ("[null, 1, 2, 3]", P.C_BAD_BBOX),
        ('[{"x": 1}, 1, 2, 3]', P.C_BAD_BBOX),
    ],
)
def test_bad_coordinates_dropped(bbox: str, counter: str) -> None:
    got, c = boxes(f'[{{"bbox_2d": {bbox}, "label": "x"}}]')
    assert got == [] and c[counter] >= 1


def test_numeric_strings_coerced_and_swapped_corners_fixed() -> None:
    got, c = boxes('[{"bbox_2d": ["30", "40", 10, 20], "label": "x"}]')
    assert got == [Box("x", (10.0, 20.0, 30.0, 40.0), None)]
    assert c[P.C_COERCED] == 2 and c[P.C_SWAPPED] == 1


def test_labels_filter_and_bad_labels() -> None:
    text = json.dumps(
        [
            {"bbox_2d": [1, 1, 5, 5], "label": "Red  Ball"},
            {"bbox_2d": [1, 1, 5, 5], "label": "cat"},
            {"bbox_2d": [1, 1, 5, 5], "label": "big dog"},
            {"bbox_2d": [1, 1, 5, 5]},
            {"bbox_2d": [1, 1, 5, 5], "label": ""},
            {"bbox_2d": [1, 1, 5, 5], "label": ["a"]},
        ]
    )
    got, c = boxes(text, labels=["red ball", "dog"])
    assert [b.label for b in got] == ["red ball", "dog"]  # requested spelling
    assert c[P.C_UNKNOWN_LABEL] == 1 and c[P.C_BAD_LABEL] == 3
    got, _ = boxes(text)  # no labels requested: keep every well-formed one
    assert len(got) == 3


def test_scores() -> None:
    text = json.dumps(
        [
            {"bbox_2d": [1, 1, 5, 5], "label": "a", "score": 0.7},
            {"bbox_2d": [1, 1, 5, 5], "label": "b", "confidence": 7},
            {"bbox_2d": [1, 1, 5, 5], "label": "c", "score": "high"},
        ]
    )
    got, c = boxes(text)
    assert [b.score for b in got] == [0.7, 1.0, None]
    assert c[P.C_SCORE_CLIPPED] == 1 and c[P.C_BAD_SCORE] == 1


def test_limits() -> None:
    many = json.dumps([{"bbox_2d": [1, 1, 5, 5], "label": "a"}] * 500)
    got, c = boxes(many)
    assert len(got) == P.MAX_ITEMS and c[P.C_TOO_MANY] == 500 - P.MAX_ITEMS
    got, c = boxes(GOOD + " " * (P.MAX_CHARS + 10))
    assert len(got) == 1 and c[P.C_TEXT_TOO_LONG] == 1
    for evil in ("[" * 100_000, "{" * 100_000, '[{"a":' * 20_000, "1" * 10_000, "\x00\ud800"):
        parse_grounding(evil)  # bounded, no exception
    assert parse_grounding(None).counters[P.C_NO_JSON] == 1  # type: ignore[arg-type]


def test_sanitize_text() -> None:
    c: Counter[str] = Counter()
    assert sanitize_text("ok\x1b[31mred\u202e", 100, c) == "ok[31mred"
    assert c[P.C_CONTROL_CHARS] == 1
    assert len(sanitize_text("x" * 100, 10, c)) == 10


def test_finalize_clips_and_drops() -> None:
    c: Counter[str] = Counter()
    raw = [
        Box("in", (10, 10, 20, 20)),
        Box("partly", (-50, -50, 20, 20)),
        Box("outside", (500, 500, 600, 600)),
        Box("flat", (10, 10, 10, 20)),
    ]
    got = finalize_boxes(
        raw, coords=CoordSystem.RESIZED_PIXELS, resized_hw=(100, 100), original_hw=(200, 400), counters=c
    )
    assert [b.label for b in got] == ["in", "partly"]
    assert got[0].box == (40.0, 20.0, 80.0, 40.0)
    assert got[1].box == (0.0, 0.0, 80.0, 40.0)
    assert c[P.C_CLIPPED] == 2 and c[P.C_DEGENERATE] == 2


# -- fuzzing -------------------------------------------------------------------------------------

json_leaf = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=20),
)
json_value = st.recursive(
    json_leaf,
    lambda inner: st.lists(inner, max_size=6) | st.dictionaries(st.text(max_size=10), inner, max_size=6),
    max_leaves=30,
)
item = st.fixed_dictionaries(
    {"bbox_2d": st.lists(json_leaf, min_size=0, max_size=6), "label": json_leaf},
    optional={"score": json_leaf, "confidence": json_leaf},
)


def _check(result: P.ParseResult, labels: list[str] | None) -> None:
    assert all(k in P.COUNTERS for k in result.counters), result.counters
    for b in result.boxes:
        assert isinstance(b.label, str) and b.label
        x1, y1, x2, y2 = b.box
        assert all(math.isfinite(v) and abs(v) <= P.MAX_ABS_COORD for v in b.box)
        assert x1 <= x2 and y1 <= y2
        assert b.score is None or 0.0 <= b.score <= 1.0
        if labels:
            assert b.label in labels
    c: Counter[str] = Counter()
    out = finalize_boxes(
        result.boxes, coords=CoordSystem.RESIZED_PIXELS, resized_hw=(84, 112), original_hw=(480, 640), counters=c
    )
    for b in out:
        x1, y1, x2, y2 = b.box
        assert 0 <= x1 < x2 <= 640 and 0 <= y1 < y2 <= 480


FUZZ = settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FUZZ
@given(st.text(max_size=400))
def test_fuzz_any_text(text: str) -> None:
    _check(parse_grounding(text), None)


@FUZZ
@given(json_value, st.sampled_from(["", "```json\n", "Sure: "]), st.integers(0, 400))
def test_fuzz_any_json(value: object, prefix: str, cut: int) -> None:
    text = prefix + json.dumps(value, allow_nan=True)
    _check(parse_grounding(text), None)
    _check(parse_grounding(text[:cut]), None)  # truncated anywhere


@FUZZ
@given(st.lists(item, max_size=8), st.lists(st.sampled_from(["a", "b", "red ball"]), max_size=2), st.integers(0, 600))
def test_fuzz_grounding_shaped(items: list[dict], labels: list[str], cut: int) -> None:
    text = "```json\n" + json.dumps(items, allow_nan=True) + "\n```"
    _check(parse_grounding(text, labels=labels), labels)
    _check(parse_grounding(text[:cut], labels=labels), labels)


@dataclass(frozen=True)
class _Gen:
    text: str
    coords: CoordSystem = CoordSystem.RESIZED_PIXELS
    resized_hw: tuple[int, int] = (240, 320)
    original_hw: tuple[int, int] = (480, 640)


def test_answer_boxes_is_parse_then_rescale() -> None:
    """The one answer -> boxes path: boxes in the original image's pixels, counters where asked."""
    gen = _Gen('[{"bbox_2d": [10, 20, 400, 60], "label": "red ball"}, {"bbox_2d": [1, 1, 2], "label": "x"}]')
    counters: Counter[str] = Counter()
    parsed, boxes = answer_boxes(gen, ["red ball"], counters)
    assert parsed.found_json and [b.label for b in boxes] == ["red ball"]
    assert boxes[0].box == (20.0, 40.0, 640.0, 120.0)  # x2 800 clipped to the 640 px image
    assert counters[P.C_CLIPPED] == 1 and counters[P.C_UNKNOWN_LABEL] == 1
    assert answer_boxes(_Gen("no boxes here"))[1] == []
