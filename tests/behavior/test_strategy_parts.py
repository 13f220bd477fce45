"""Property tests of the strategies' shared tools (behavior/strategies/): the answers' measured latency
(latency.py), a look (look.py) and the local planner's side memory (navigate/steer.py)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.behavior.navigate.steer import Avoider
from go2vlm.behavior.strategies.latency import Answers
from go2vlm.behavior.strategies.look import Look
from go2vlm.behavior.strategies.params import MissionParams

times = st.floats(0.0, 1000.0)


@given(st.lists(st.tuples(st.one_of(st.none(), st.floats(-10.0, 100.0)), st.floats(0.0, 5.0)), max_size=60))
def test_latency_is_a_measured_one_and_only_newer_answers_count(answers: list[tuple[float | None, float]]) -> None:
    a, now, seen, through = Answers(), 0.0, [], None
    for stamp, dt in answers:
        now += dt
        a.take(stamp, now)
        if stamp is not None and (through is None or stamp > through):
            through = stamp
            seen.append(max(0.0, now - stamp))
        assert a.through == through
        lat = a.latency
        assert (lat is None) == (not seen)
        if lat is not None:
            assert lat in seen[-20:] and lat >= 0.0
            assert lat >= sorted(seen[-20:])[len(seen[-20:]) // 2]  # the 80th percentile: at least the median


@given(lat=st.floats(0.0, 10.0), rate=st.floats(0.05, 1.5), view=st.floats(0.1, 3.0), share=st.floats(0.05, 2.0))
def test_fast_only_when_known_and_within_the_share(lat: float, rate: float, view: float, share: float) -> None:
    a = Answers()
    assert not a.fast_for(rate, view, share)  # unknown latency: slow
    a.take(0.0, lat)
    assert not a.fast_for(rate, None, share)  # unknown view: slow
    assert a.fast_for(rate, view, share) == (lat * rate <= share * view)


@settings(max_examples=200)
@given(
    evs=st.lists(
        st.tuples(st.sampled_from(["a", "b", None]), st.floats(0.0, 2.0), st.one_of(st.none(), st.floats(-5.0, 50.0))),
        max_size=40,
    ),
    settle=st.floats(0.0, 1.0),
    lat=st.one_of(st.none(), st.floats(0.0, 5.0)),
)
def test_a_look_is_answered_only_by_a_frame_taken_after_the_stop(
    evs: list[tuple[str | None, float, float | None]], settle: float, lat: float | None
) -> None:
    look, now, start = Look(), 0.0, None
    for key, dt, answered in evs:
        now += dt
        if key is None:
            look.forget()
            start = None
            continue
        if key != look.key:
            start = now
        out = look.check(key, now, settle_s=settle, timeout_s=8.0, answered=answered, latency=lat)
        assert start is not None and look.still_since == start + settle
        if out == "answered":
            assert answered is not None and answered >= start + settle
        else:
            limit = 8.0 if lat is None else 2.5 * lat + 1.0
            assert (out == "timeout") == (now - (start + settle) > limit)


pts = st.lists(st.tuples(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0)), max_size=30).map(
    lambda p: np.array(p, dtype=float).reshape(-1, 2)
)


@settings(max_examples=200)
@given(
    steps=st.lists(
        st.tuples(st.one_of(st.none(), pts), st.floats(-1.5, 1.5), st.floats(0.3, 6.0), st.floats(0.0, 2.0)),
        max_size=15,
    )
)
def test_the_avoider_never_speeds_up_or_reverses_and_keeps_one_side(
    steps: list[tuple[np.ndarray | None, float, float, float]],
) -> None:
    p = MissionParams()
    ap = p.approach(p.stop_distance_m)
    av, now = Avoider(), 0.0
    for points, bearing, dist, dt in steps:
        now += dt
        before = av.detour_t
        st_ = av.steer(points, p.planner, 0.2, 0.1, ap, (bearing, dist), now)
        if points is None:
            assert st_ is None and av.detour_t == before
            continue
        assert st_ is not None
        assert 0.0 <= st_.vx <= max(0.2, ap.max_linear) and abs(st_.wz) <= ap.max_angular + 1e-9
        assert (av.detour_t == now) == st_.blocked or (before == now)
        assert av.side in (-1.0, 0.0, 1.0)
    av.reset()
    assert av.detour_t is None and av.side == 0.0 and math.isfinite(p.planner.kp)
