"""The target_tracker's pure core (perception/tracking.py) on drawn scenes: answers are refused unless
their box holds the label's object, nothing unconfirmed is ever reported, a lost track has no box,
late answers are caught up to the present, and a new query starts from nothing.

The property tests draw small scenes (160x120, up to three objects of different colours moving a few
pixels a frame) and feed the core random streams of frames and answers -- right, wrong-label,
wrong-object, background, non-finite and stale boxes -- and check every observation against the
scene's ground truth."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from go2vlm.geometry.camera import PinholeCamera
from go2vlm.perception.tracking import Grounding, TargetTracking, TrackingParams
from go2vlm.vocabulary.words import label_match, parse_label

W, H = 160, 120
BGR = {"red": (0, 0, 230), "green": (0, 200, 0), "blue": (230, 60, 0), "yellow": (0, 220, 240)}
SHAPE = {"red": "ball", "green": "box", "blue": "cylinder", "yellow": "ball"}
CAM = PinholeCamera.from_hfov(W, H, 1.274)


@dataclass(frozen=True)
class Obj:
    color: str
    x: float  # centre at frame 0
    y: float
    vx: float  # pixels per frame
    vy: float
    r: int  # half size

    def box(self, k: int) -> tuple[float, float, float, float]:
        cx, cy = self.x + self.vx * k, self.y + self.vy * k
        return cx - self.r, cy - self.r, cx + self.r, cy + self.r


def draw(objs: list[Obj], k: int, visible: set[str] | None = None) -> np.ndarray:
    img = np.full((H, W, 3), 140, np.uint8)
    for o in objs:
        if visible is not None and o.color not in visible:
            continue
        x1, y1, x2, y2 = (int(round(v)) for v in o.box(k))
        if SHAPE[o.color] == "ball":
            cv2.circle(img, ((x1 + x2) // 2, (y1 + y2) // 2), o.r, BGR[o.color], -1)
        else:
            cv2.rectangle(img, (x1, y1), (x2, y2), BGR[o.color], -1)
    return img


def near(box: tuple[float, float, float, float], truth: tuple[float, float, float, float], margin: float = 4) -> bool:
    """The box's centre lies on the true object (grown by `margin` pixels)."""
    cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
    return truth[0] - margin <= cx <= truth[2] + margin and truth[1] - margin <= cy <= truth[3] + margin


@st.composite
def scenes(draw_: st.DrawFn) -> list[Obj]:
    colors = draw_(st.lists(st.sampled_from(sorted(BGR)), min_size=1, max_size=3, unique=True))
    objs = []
    for i, c in enumerate(colors):
        r = draw_(st.integers(9, 14))
        # objects apart (one per third of the width), moving slowly, staying in the picture for 40 frames
        x = 28 + 52 * i + draw_(st.integers(-3, 3))
        y = draw_(st.integers(35, 85))
        objs.append(Obj(c, x, y, draw_(st.sampled_from([-0.4, 0.0, 0.3])), draw_(st.sampled_from([-0.3, 0.0, 0.2])), r))
    return objs


ANSWER_BOX = ("target", "target", "target", "other", "background", "random", "nan", "outside")
answer_ev = st.tuples(
    st.just("answer"),
    st.integers(0, 6),  # frames back
    st.sampled_from(["query", "query", "query", "wrong", "empty_label"]),
    st.sampled_from(ANSWER_BOX),
    st.tuples(st.floats(0, W), st.floats(0, H), st.floats(2, 60), st.floats(2, 60)),
)
events = st.lists(st.one_of(st.just(("frame",)), st.just(("frame",)), st.just(("frame",)), answer_ev), max_size=40)


@settings(max_examples=120, deadline=None, suppress_health_check=list(HealthCheck))
@given(objs=scenes(), evs=events, pick=st.integers(0, 2), named=st.sampled_from(["color", "both", "shape"]))
def test_nothing_unconfirmed_is_ever_reported(objs: list[Obj], evs: list[tuple], pick: int, named: str) -> None:
    target = objs[pick % len(objs)]
    if named == "shape" and sum(SHAPE[o.color] == SHAPE[target.color] for o in objs) > 1:
        named = "both"  # "ball" alone would name two objects
    query = {"color": target.color, "both": f"{target.color} {SHAPE[target.color]}", "shape": SHAPE[target.color]}
    query = query[named]
    has_color = named != "shape"
    others = [o for o in objs if o is not target]
    t = TargetTracking(TrackingParams(grounding="vlm", stamp_tolerance_s=0.01, max_answer_age_s=0.45))
    t.set_query(query)
    k = -1
    tracked: Obj | None = None  # the object under the last accepted box
    for ev in [("frame",), *evs]:
        if ev[0] == "frame":
            k += 1
            obs = t.on_frame(1.0 + 0.1 * k, draw(objs, k), CAM)
            assert obs.label == query and obs.width == W and obs.height == H
            if obs.state != "tracking":
                assert obs.box is None and obs.confidence == 0.0 and obs.distance is None
                continue
            # A box only after an accepted answer, and always on the object that answer pointed at,
            # which is the object of the named colour whenever the label names one.
            assert tracked is not None and t.counters["accepted"] >= 1
            assert not has_color or tracked.color == target.color
            x1, y1, x2, y2 = obs.box
            assert 0 <= x1 < x2 <= W and 0 <= y1 < y2 <= H
            assert near(obs.box, tracked.box(k)), (obs.box, tracked.box(k), query)
            assert obs.grounding_age is not None and obs.grounding_age >= 0
            event("reported a tracked box")
            continue
        _, back, lab, where, rnd = ev
        j = max(0, k - back)
        back = k - j  # frames back it really is
        if where == "random" and not has_color:
            where = "target"  # without a colour to mask, a box over two objects is ambiguous
        on: Obj | None = None
        if where == "target":
            on, box = target, target.box(j)
        elif where == "other" and others:
            on, box = others[0], others[0].box(j)
        elif where in ("other", "background"):
            box = (W - 20.0, 2.0, W - 4.0, 10.0)  # a corner no object reaches (they stay at y >= 20)
        elif where == "random":
            on, box = target, (rnd[0], rnd[1], rnd[0] + rnd[2], rnd[1] + rnd[3])
        elif where == "nan":
            box = (math.nan, 1.0, 5.0, 9.0)
        else:
            box = (W + 10.0, H + 10.0, W + 50.0, H + 50.0)
        label = {"query": query, "wrong": "purple pyramid", "empty_label": ""}[lab]
        before = t.counters["accepted"]
        why = t.add_answer(Grounding(1.0 + 0.1 * j, ((label, box),)))
        if t.counters["accepted"] > before:
            assert why is None
            assert lab == "query" and back <= 4 and on is not None, (lab, back, where)
            assert not has_color or on.color == target.color, "a box on another colour was accepted"
            tracked = on
            event(f"accepted a box on the {'target' if on is target else 'other object'}")
        else:
            event(f"refused: {why}")
            assert why is not None
            if back > 4:
                assert why == "stale"
            elif lab != "query":
                assert why == "no_match"
            elif has_color and back <= 4 and (where == "background" or (where == "other" and others)):
                assert why == "color_mismatch", (why, t.last_refusal)


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(objs=scenes(), pick=st.integers(0, 2), gone=st.lists(st.booleans(), min_size=5, max_size=30))
def test_colour_grounding_tracks_only_what_is_there_and_reports_loss_without_a_box(
    objs: list[Obj], pick: int, gone: list[bool]
) -> None:
    target = objs[pick % len(objs)]
    query = f"{target.color} {SHAPE[target.color]}"
    t = TargetTracking(TrackingParams(grounding="color", min_shape_score=0.0))
    t.set_query(query)
    everyone = {o.color for o in objs}
    for k, hidden in enumerate(gone):
        visible = everyone - {target.color} if hidden else everyone
        obs = t.on_frame(0.1 * k, draw(objs, k, visible), CAM)
        if hidden:
            assert obs.state in ("searching", "lost") and obs.box is None, obs
        if obs.state == "tracking":
            assert near(obs.box, target.box(k)), (obs.box, target.box(k))
        else:
            assert obs.box is None


def test_free_text_is_ungroundable_for_the_colour_grounder_and_never_tracked() -> None:
    objs = [Obj("red", 60, 60, 0, 0, 12)]
    t = TargetTracking(TrackingParams(grounding="color"))
    t.set_query("person")
    assert t.state == "ungroundable"
    assert t.add_answer(Grounding(0.0, (("person", (48, 48, 72, 72)),))) is None  # ignored, not applied
    for k in range(3):
        obs = t.on_frame(0.1 * k, draw(objs, k))
        assert obs.state == "ungroundable" and obs.box is None
    t.set_query("")
    assert t.on_frame(0.3, draw(objs, 3)).state == "idle"


def _vlm(**kw) -> TargetTracking:
    t = TargetTracking(TrackingParams(grounding="vlm", **kw))
    t.set_query("blue cylinder")
    return t


def test_a_late_answer_is_caught_up_to_the_present() -> None:
    obj = Obj("blue", 30, 60, 3.0, 0.0, 12)  # moves 3 px a frame to the right
    t = _vlm()
    for k in range(10):
        assert t.on_frame(0.1 * k, draw([obj], k), CAM).state == "searching"
    assert t.add_answer(Grounding(0.3, (("blue cylinder", obj.box(3)),))) is None  # about frame 3
    obs = t.on_frame(1.0, draw([obj], 10), CAM)
    assert obs.state == "tracking" and near(obs.box, obj.box(10), 2)  # where it is now, not at frame 3
    assert obs.grounding_age == pytest.approx(0.7)
    assert obs.distance is not None and obs.range_method != "none"
    assert obs.bearing == pytest.approx(CAM.bearing((obs.box[0] + obs.box[2]) / 2))  # the box centre's, + left


def test_an_answer_about_a_frame_not_received_yet_waits_for_it() -> None:
    obj = Obj("blue", 60, 60, 0.0, 0.0, 12)
    t = _vlm()
    t.on_frame(0.0, draw([obj], 0))
    assert t.add_answer(Grounding(0.2, (("blue cylinder", obj.box(0)),))) is None
    assert t.on_frame(0.1, draw([obj], 1)).state == "searching"  # not yet its frame
    assert t.on_frame(0.2, draw([obj], 2)).state == "tracking"


def test_refusals_are_counted_and_change_nothing() -> None:
    blue, red = Obj("blue", 40, 60, 0, 0, 12), Obj("red", 120, 60, 0, 0, 12)
    t = _vlm(max_answer_age_s=1.0)
    for k in range(15):
        t.on_frame(0.1 * k, draw([blue, red], k))
    now = 1.4
    cases = [
        (("red ball", red.box(14)), "no_match"),  # the wrong label
        (("blue cylinder", red.box(14)), "color_mismatch"),  # the right label on the wrong object
        (("blue cylinder", (2.0, 2.0, 20.0, 20.0)), "color_mismatch"),  # on the floor
        (("blue cylinder", (math.inf, 0.0, 10.0, 10.0)), "bad_box"),
        (("blue cylinder", (500.0, 500.0, 600.0, 600.0)), "bad_box"),  # outside the image
    ]
    for det, reason in cases:
        assert t.add_answer(Grounding(now, (det,))) == reason, t.last_refusal
    assert t.add_answer(Grounding(now, ())) == "no_match"  # an empty answer
    assert t.add_answer(Grounding(now - 1.2, (("blue cylinder", blue.box(2)),))) == "stale"
    assert t.state == "searching" and t.counters["accepted"] == 0
    assert t.counters["refused.no_match"] == 2 and t.counters["refused.color_mismatch"] == 2
    # Free text has no colour to check, but a box on nothing trackable is still refused.
    t.set_query("robot dog")
    t.on_frame(1.5, draw([blue, red], 15))
    assert t.add_answer(Grounding(1.5, (("robot dog", (2.0, 2.0, 20.0, 20.0)),))) == "untrackable"
    # With both a wrong and a right box, the right one wins.
    t.set_query("blue cylinder")
    t.on_frame(1.6, draw([blue, red], 16))
    assert t.add_answer(Grounding(1.6, (("blue cylinder", red.box(16)), ("blue cylinder", blue.box(16))))) is None
    assert t.state == "tracking"


def test_a_lost_track_has_no_box_and_stale_or_unconfirmed_tracks_are_dropped() -> None:
    blue = Obj("blue", 60, 60, 0, 0, 12)
    t = _vlm(max_grounding_age_s=1.0)
    t.on_frame(0.0, draw([blue], 0))
    assert t.add_answer(Grounding(0.0, (("blue cylinder", blue.box(0)),))) is None
    assert t.on_frame(0.1, draw([blue], 1)).state == "tracking"
    obs = t.on_frame(0.2, draw([], 2))  # gone
    assert obs.state == "lost" and obs.box is None and t.counters["tracks_lost"] == 1
    assert t.on_frame(0.3, draw([blue], 3)).state == "lost"  # back in view, but nobody grounded it
    # Confirmed once, then never again: dropped after max_grounding_age_s.
    assert t.add_answer(Grounding(0.3, (("blue cylinder", blue.box(3)),))) is None
    states = [t.on_frame(0.3 + 0.1 * i, draw([blue], 3 + i)).state for i in range(1, 13)]
    assert states[:9] == ["tracking"] * 9 and states[-1] == "lost"
    assert t.counters["tracks_dropped.stale_grounding"] == 1
    # Answers that keep not finding it drop the track after max_unconfirmed_answers.
    t2 = _vlm(max_unconfirmed_answers=2)
    t2.on_frame(0.0, draw([blue], 0))
    t2.add_answer(Grounding(0.0, (("blue cylinder", blue.box(0)),)))
    assert t2.on_frame(0.1, draw([blue], 1)).state == "tracking"
    t2.add_answer(Grounding(0.1, ()))
    assert t2.on_frame(0.2, draw([blue], 2)).state == "tracking"
    t2.add_answer(Grounding(0.2, (("red ball", (1.0, 1.0, 9.0, 9.0)),)))
    obs = t2.on_frame(0.3, draw([blue], 3))
    assert obs.state == "lost" and obs.box is None and t2.counters["tracks_dropped.unconfirmed"] == 1


def test_a_new_query_starts_from_nothing() -> None:
    blue, red = Obj("blue", 40, 60, 0, 0, 12), Obj("red", 120, 60, 0, 0, 12)
    t = _vlm()
    t.on_frame(0.0, draw([blue, red], 0))
    t.add_answer(Grounding(0.0, (("blue cylinder", blue.box(0)),)))
    assert t.on_frame(0.1, draw([blue, red], 1)).state == "tracking"
    t.set_query("blue cylinder")  # the same query again: nothing changes
    assert t.on_frame(0.2, draw([blue, red], 2)).state == "tracking"
    t.set_query("red ball")
    obs = t.on_frame(0.3, draw([blue, red], 3))
    assert obs.state == "searching" and obs.box is None and obs.label == "red ball" and obs.grounding_age is None


@pytest.mark.parametrize(
    ("query", "label", "score"),
    [
        ("blue cylinder", "blue cylinder", 2),
        ("blue cylinder", "the Blue Cylinder", 2),
        ("blue cylinder", "cylinder", 0),  # no colour: it could be another cylinder
        ("blue cylinder", "red cylinder", 0),
        ("blue", "blue cylinder", 1),
        ("ball", "red ball", 1),
        ("red ball", "red box", 0),
        ("person", "a person", 1),
        ("person", "person", 2),
        ("person", "chair", 0),
        ("red ball", "", 0),
    ],
)
def test_label_match(query: str, label: str, score: int) -> None:
    assert label_match(parse_label(query), label) == score
