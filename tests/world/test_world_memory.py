"""The object memory's rules (world/memory.py): repeated answers tighten an object, a wrong one far
away does not move it, a place seen empty forgets it, and nothing grows without bound."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.world.memory import MemoryParams, ObjectMemory, View
from go2vlm.world.placement import Placed

HFOV = math.radians(73.0)


def sighting(label: str, x: float, y: float, sigma: float = 0.1, stamp: float = 1.0,
             camera: tuple[float, float] = (0.0, 0.0)) -> Placed:  # fmt: skip
    b = math.atan2(y - camera[1], x - camera[0])
    rng = max(0.0, math.hypot(x - camera[0], y - camera[1]) - 0.3)
    return Placed(label, stamp, x, y, 0.75, (sigma**2, 0.0, sigma**2), (0.6, 0.6, 1.5), rng, b,
                  (b - 0.1, b + 0.1), "bottom", camera)  # fmt: skip


def view_towards(x: float, y: float, stamp: float = 1.0, covers: frozenset[str] | None = None,
                 camera: tuple[float, float] = (0.0, 0.0), occluders: np.ndarray | None = None) -> View:  # fmt: skip
    return View(stamp, camera, math.atan2(y - camera[1], x - camera[0]), HFOV, covers, occluders)


@settings(max_examples=50, deadline=None)
@given(x=st.floats(-4, 4), y=st.floats(1, 4), noise=st.floats(0.02, 0.15), seed=st.integers(0, 2**31))
def test_repeated_answers_tighten_it(x: float, y: float, noise: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    m = ObjectMemory()
    sigmas = []
    for k in range(30):
        zx, zy = x + rng.normal(0, noise), y + rng.normal(0, noise)
        m.observe([sighting("blue cylinder", zx, zy, noise, stamp=k)], view_towards(x, y, k))
        o = max(m.snapshot(), key=lambda o: o.seen)  # (a rare 3.5-sigma sighting starts a doubtful other one)
        sigmas.append(o.sigma)
    assert all(b <= a + 1e-9 for a, b in zip(sigmas, sigmas[1:], strict=False))
    mp = MemoryParams()
    assert sigmas[-1] < sigmas[0] or sigmas[0] == pytest.approx(mp.min_sigma_m)
    floor = max(mp.min_sigma_m, mp.bias_fraction * noise) ** 2  # the gain never falls below floor / (floor + noise^2)
    k = floor / (floor + noise**2)
    assert math.hypot(o.x - x, o.y - y) < 0.02 + 3 * noise * max(1 / math.sqrt(30), math.sqrt(k / (2 - k)))
    assert o.seen >= 28 and o.confidence > 0.95 and o.last_seen >= 28


@settings(max_examples=50, deadline=None)
@given(far=st.floats(2.5, 20), angle=st.floats(-math.pi, math.pi))
def test_a_wrong_answer_far_away_does_not_move_it(far: float, angle: float) -> None:
    m = ObjectMemory()
    for k in range(5):
        m.observe([sighting("blue cylinder", -2.0, 0.0, stamp=k)], view_towards(-2.0, 0.0, k))
    before = {o.id: (o.x, o.y) for o in m.snapshot()}
    wx, wy = -2.0 + far * math.cos(angle), far * math.sin(angle)
    m.observe([sighting("blue cylinder", wx, wy, stamp=6)], view_towards(wx, wy, 6))
    after = {o.id: o for o in m.snapshot()}
    ((oid, xy),) = before.items()
    assert (after[oid].x, after[oid].y) == xy
    assert after[oid].refused == 1
    assert len(after) == 2  # the wrong answer is a separate, unconfirmed object ...
    new = next(o for o in after.values() if o.id != oid)
    assert new.confidence == pytest.approx(0.5) and new.seen == 1


def test_a_place_seen_empty_lowers_its_confidence_then_forgets_it() -> None:
    m = ObjectMemory()
    m.observe([sighting("red ball", 2.0, 1.0)], view_towards(2.0, 1.0))
    (o,) = m.snapshot()
    conf = [o.confidence]
    for k in range(2, 40):
        m.observe([], view_towards(2.0, 1.0, k, covers=frozenset({"red ball"})))
        objs = m.snapshot()
        if not objs:
            break
        conf.append(objs[0].confidence)
    assert not m.snapshot(), "forgotten"
    assert all(b < a for a, b in zip(conf, conf[1:], strict=False))
    assert 3 <= len(conf) - 1 <= 12, "several empty looks, not one"
    assert m.counters["forgotten"] == 1


def test_an_empty_answer_about_another_label_or_another_place_changes_nothing() -> None:
    m = ObjectMemory()
    m.observe([sighting("red ball", 2.0, 1.0)], view_towards(2.0, 1.0))
    m.observe([], view_towards(2.0, 1.0, 2, covers=frozenset({"green box"})))  # asked about something else
    m.observe([], view_towards(-2.0, -1.0, 3, covers=None))  # looking the other way
    m.observe([], view_towards(9.0, 1.0, 4, covers=None, camera=(8.0, 1.0)))  # it is behind the camera
    m.observe([], view_towards(2.0, 1.0, 5, camera=(1.95, 0.99)))  # too close to be seen whole
    (o,) = m.snapshot()
    assert o.missed == 0 and o.confidence == pytest.approx(0.5)


def test_a_hidden_object_is_not_missed() -> None:
    m = ObjectMemory()
    m.observe([sighting("red ball", 4.0, 0.0)], view_towards(4.0, 0.0))
    wall = np.array([[2.0, y] for y in np.linspace(-1, 1, 21)])  # a scan return in front of it
    m.observe([], view_towards(4.0, 0.0, 2, occluders=wall))
    for k in range(3, 6):  # a confident object in front of it hides it too
        m.observe([sighting("green box", 2.0, 0.0, stamp=k)], view_towards(4.0, 0.0, k))
    assert {o.label: o.missed for o in m.snapshot()} == {"red ball": 0, "green box": 0}


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 600), seed=st.integers(0, 2**31), cap=st.integers(1, 40))
def test_a_flood_of_answers_cannot_grow_it(n: int, seed: int, cap: int) -> None:
    rng = np.random.default_rng(seed)
    m = ObjectMemory(MemoryParams(max_objects=cap))
    labels = ["red ball", "green box", "blue cylinder", "person", "chair"]
    for k in range(n):
        x, y = rng.uniform(-50, 50, 2)
        m.observe([sighting(str(rng.choice(labels)), x, y, stamp=k)], view_towards(x, y, k))
        assert len(m.objects) <= cap


def test_two_sightings_of_one_label_in_one_answer_are_two_objects_and_close_ones_merge() -> None:
    m = ObjectMemory()
    m.observe([sighting("red ball", 2.0, 1.0), sighting("red ball", 2.0, -1.0)], view_towards(2.0, 0.0))
    assert len(m.snapshot()) == 2
    m2 = ObjectMemory(MemoryParams(gate_min_m=0.05, gate_sigma=0.5))
    m2.observe([sighting("red ball", 2.0, 1.0, 0.05)], view_towards(2.0, 1.0))
    m2.observe([sighting("red ball", 2.2, 1.0, 0.05, stamp=2)], view_towards(2.0, 1.0, 2))  # outside the gate
    assert len(m2.objects) == 1 and m2.counters["merged"] == 1


def test_where_is_names_the_exact_label_and_the_most_confident_first() -> None:
    m = ObjectMemory()
    for k in range(3):
        m.observe([sighting("red ball", 2.0, 1.0, stamp=k)], view_towards(2.0, 1.0, k))
    m.observe([sighting("red box", -2.0, 1.0)], view_towards(-2.0, 1.0))
    m.observe([sighting("yellow ball", 0.0, 3.0)], view_towards(0.0, 3.0))
    assert [o.label for o in m.where_is("ball")] == ["red ball", "yellow ball"]
    assert [o.label for o in m.where_is("red box")] == ["red box"]
    assert m.where_is("person") == []
    assert len(m.where_is("")) == 3


def test_a_bearing_only_sighting_confirms_what_lies_that_way() -> None:
    m = ObjectMemory()
    m.observe([sighting("green box", 1.2, 0.0)], view_towards(1.2, 0.0))
    blind = Placed("green box", 5.0, math.nan, math.nan, math.nan, (math.inf, 0.0, math.inf), (1, 1, None), None,
                   0.0, (-0.6, 0.6), "fills_view", (0.0, 0.0))  # fmt: skip
    assert m.observe([blind], view_towards(1.2, 0.0, 5.0)) == ["green_box_1"]
    (o,) = m.snapshot()
    assert o.last_seen == 5.0 and o.seen == 2 and (o.x, o.y) == (1.2, 0.0)
    away = Placed("green box", 6.0, math.nan, math.nan, math.nan, (math.inf, 0.0, math.inf), (1, 1, None), None,
                  3.0, (2.8, 3.1), "fills_view", (0.0, 0.0))  # fmt: skip
    assert m.observe([away], view_towards(-1.0, 0.0, 6.0)) == ["refused.unranged"]


def test_a_rough_far_sighting_and_sharp_near_ones_are_one_object() -> None:
    """Twenty sightings from far away, 0.6 m off (sigma 0.3 m each, and all off the same way), then sharp
    ones from close by: one object, where the sharp ones put it (a small VLM's boxes are loose, and a
    far box's bottom edge ranges it badly)."""
    m = ObjectMemory()
    for k in range(20):  # many from far away agree with each other (their error is the same each time)
        m.observe([sighting("blue cylinder", -1.5, -0.35, sigma=0.3, stamp=k / 10, camera=(4.0, -1.0))],
                  view_towards(-1.5, -0.35, k / 10, camera=(4.0, -1.0)))  # fmt: skip
    for k in range(2, 6):
        m.observe([sighting("blue cylinder", -2.0, 0.0, sigma=0.03, stamp=k, camera=(-0.8, 0.0))],
                  view_towards(-2.0, 0.0, k, camera=(-0.8, 0.0)))  # fmt: skip
    (o,) = m.snapshot()
    assert math.hypot(o.x + 2.0, o.y) < 0.1 and o.seen == 24


def test_a_sighting_too_unsure_of_its_place_starts_nothing_but_still_joins() -> None:
    """A far bottom edge is a metre or more off: it starts no object (refused.uncertain), since nothing
    seen later would refute a place behind a wall; the same sighting near a remembered object joins it."""
    m = ObjectMemory()
    loose = MemoryParams().new_max_sigma_m * 1.5
    assert m.observe([sighting("duck", 6.0, 0.0, sigma=loose)], view_towards(6.0, 0.0)) == ["refused.uncertain"]
    assert not m.objects and m.counters["refused.uncertain"] == 1
    [oid] = m.observe([sighting("duck", 2.0, 0.0, sigma=0.1, stamp=2.0)], view_towards(2.0, 0.0, 2.0))
    assert m.observe([sighting("duck", 2.4, 0.0, sigma=loose, stamp=3.0)], view_towards(2.0, 0.0, 3.0)) == [oid]
    assert m.objects[oid].seen == 2 and abs(m.objects[oid].x - 2.0) < 0.1
