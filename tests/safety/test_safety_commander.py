"""One commander per robot, the pure rules (safety/commander.py): who may drive /cmd_vel given the
writers matched and the gates announced, when a foreign writer is reported, and how motion resumes
only through zero. The processes are tested in tests/robots/go2_sim/test_go2_sim_stop_holds.py."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.safety.commander import OneCommander, ThroughZero, Writer, heartbeat, judge, parse_heartbeat

GUIDS = [f"g{i}" for i in range(5)]
writer = st.builds(Writer, st.sampled_from(GUIDS), st.sampled_from(["p1", "p2"]), st.sampled_from([None, "/x"]))


@settings(max_examples=300, deadline=None)
@given(writers=st.lists(writer, max_size=5), announced=st.sets(st.sampled_from(GUIDS)))
def test_exactly_one_announced_gate_and_nothing_else_drives(writers: list[Writer], announced: set[str]) -> None:
    v = judge(writers, announced)
    guids = {w.guid for w in writers}
    gates = guids & announced
    alone = len(gates) == 1 and guids <= announced
    assert v.ok is alone
    if alone:
        assert v.driver in gates and v.reason == ""
    else:
        assert v.driver is None and v.reason
    assert {w.guid for w in v.foreign} == guids - announced
    assert {w.guid for w in v.gates} == gates


@settings(max_examples=300, deadline=None)
@given(
    steps=st.lists(
        st.tuples(st.floats(min_value=0.0, max_value=0.8), st.lists(writer, max_size=4), st.sampled_from(GUIDS)),
        max_size=20,
    ),
    announced=st.sets(st.sampled_from(GUIDS), max_size=2),
)
def test_only_the_driver_is_accepted_and_foreign_writers_are_reported_after_the_grace(steps, announced) -> None:
    rule = OneCommander(grace_s=1.0)
    now = 0.0
    first_seen: dict[str, float] = {}
    for dt, writers, sender in steps:
        now += dt
        rule.update(now, writers, announced)
        foreign = {w.guid for w in writers} - announced
        first_seen = {g: first_seen.get(g, now) for g in foreign}
        assert rule.accepts(sender) is (rule.verdict.ok and sender == rule.verdict.driver)
        assert not rule.accepts(None)
        reported = {w.guid for w in rule.alarm(now) if w.guid not in announced}
        assert reported == {g for g, t in first_seen.items() if now - t >= 1.0}


vec = st.tuples(*[st.sampled_from([0.0, 0.0, 0.3, -0.2, float("nan")])] * 3)


@settings(max_examples=300, deadline=None)
@given(events=st.lists(st.one_of(st.tuples(st.just("cmd"), vec), st.tuples(st.just("stop"), vec)), max_size=40))
def test_motion_resumes_only_through_zero(events) -> None:
    """Model: after a stop, a non-zero command drives only if a zero command was seen since the stop,
    or the newest command seen at the stop was already zero. Start-up is not a stop."""
    rule = ThroughZero()
    allowed = True
    last_zero = False
    for kind, v in events:
        is_zero = all(x == 0.0 for x in v)
        if kind == "stop":
            rule.require()
            allowed = last_zero
            continue
        if is_zero:
            allowed = True
        assert rule.see(v) is allowed
        last_zero = is_zero


def test_through_zero_examples() -> None:
    rule = ThroughZero()
    assert rule.see((0.02, 0.0, 0.0)), "start-up is not a stop (the gate ramps up from zero)"
    rule.require()  # stopped while the stream asks for 0.3: a zero must come first
    assert not rule.see((0.3, 0.0, 0.0)) and not rule.see((float("nan"), 0.0, 0.0))
    assert rule.see((0.0, 0.0, 0.0)) and rule.see((0.02, 0.0, 0.0))
    rule.see((0.0, 0.0, 0.0))
    rule.require()  # stopped while the stream was at zero (a gate that held zero): ramps on at once
    assert rule.see((0.02, 0.0, 0.0))


def test_heartbeat_round_trip_and_bad_ones() -> None:
    hb = heartbeat("/safety", "p", "w", "/cmd_vel")
    expected = {"node": "/safety", "participant": "p", "cmd_vel_writer": "w", "topic": "/cmd_vel"}
    assert parse_heartbeat(hb.data) == expected
    for bad in ("", "{", "[]", json.dumps({"node": "/safety"}), json.dumps({"node": 1, "cmd_vel_writer": "w"})):
        with pytest.raises(ValueError):
            parse_heartbeat(bad)
