"""A memory file is read all or nothing (world/memory_file.py)."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.errors import ConfigError
from go2vlm.world.memory import MemoryObject
from go2vlm.world.memory_file import VERSION, MemoryFileError, dumps, loads

OBJ = MemoryObject("blue_cylinder_1", "blue cylinder", -2.0, 0.0, 0.75, (0.0025, 0.0, 0.0025), (0.6, 0.6, 1.5),
                   3.0, 12, 1, 2, 3.5, 40.25)  # fmt: skip


def test_round_trip() -> None:
    text = dumps([OBJ], "vision_test", "odom", 41.0)
    assert loads(text, "vision_test", "odom", 64) == [OBJ]


@pytest.mark.parametrize(
    ("mutate", "says"),
    [
        (lambda d: "{not json", "not JSON"),
        (lambda d: {**d, "format": "something"}, "format"),
        (lambda d: {**d, "version": VERSION + 1}, "newer go2vlm"),
        (lambda d: {**d, "world": "distractors"}, "world 'distractors'"),
        (lambda d: {**d, "frame_id": "map"}, "frame 'map'"),
        (lambda d: {**d, "objects": [d["objects"][0]] * 3}, "at most 2"),
        (lambda d: {**d, "objects": [d["objects"][0], d["objects"][0]]}, "share an id"),
        (lambda d: {**d, "objects": [d["objects"][0], {**d["objects"][0], "id": "b_2", "x": float("nan")}]}, "x = nan"),
        (lambda d: {**d, "objects": [d["objects"][0], {**d["objects"][0], "id": "b_2", "cov": [1, 2, 1]}]}, "covari"),
        (lambda d: {**d, "objects": [d["objects"][0], {**d["objects"][0], "id": "b_2", "label": ""}]}, "label"),
        (lambda d: {**d, "objects": [d["objects"][0], {**d["objects"][0], "id": "b_2", "seen": -1}]}, "seen"),
        (lambda d: {**d, "objects": "all of them"}, "not a list"),
        (lambda d: {**d, "objects": [d["objects"][0], {**d["objects"][0], "id": "ball_\u00b2"}]}, "id 'ball_"),
        (lambda d: {**d, "objects": [d["objects"][0], {**d["objects"][0], "id": "b_2\n"}]}, "id"),
        (lambda d: {**d, "objects": [d["objects"][0], {**d["objects"][0], "id": "b_2", "x": 1e6}]}, "x = 1000000"),
        (lambda d: "[" * 100_000 + "]" * 100_000, "not JSON"),
        (lambda d: '{"a": ' * 5000 + "1" + "}" * 5000, "not JSON"),
    ],
)
def test_refused_with_one_line_and_nothing_loaded(mutate, says: str) -> None:
    doc = json.loads(dumps([OBJ], "vision_test", "odom", 41.0))
    bad = mutate(doc)
    text = bad if isinstance(bad, str) else json.dumps(bad)
    with pytest.raises(MemoryFileError) as e:
        loads(text, "vision_test", "odom", 2)
    assert says in str(e.value) and "\n" not in str(e.value)
    assert isinstance(e.value, ConfigError)  # exit 2 in the CLI


def test_loaded_values_are_clamped_to_what_the_memory_allows() -> None:
    from go2vlm.world.memory import ObjectMemory

    doc = json.loads(dumps([OBJ], "vision_test", "odom", 41.0))
    doc["objects"][0].update(logodds=100.0, cov=[1e-30, 0.0, 1e-30])
    memory = ObjectMemory()
    memory.load(loads(json.dumps(doc), "vision_test", "odom", 2))
    o = memory.objects["blue_cylinder_1"]
    assert o.logodds == memory.params.max_logodds and o.sigma >= memory.params.min_sigma_m * 0.999


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300) | st.text(max_size=300))
def test_garbage_is_refused_never_half_loaded(blob: bytes | str) -> None:
    with pytest.raises(MemoryFileError):
        loads(blob, "vision_test", "odom", 64)
