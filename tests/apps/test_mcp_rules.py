"""The MCP server's movement rules (apps/mcp/rules.py), pure and timestamp-driven: no sequence of
tool calls, commander reports and silences starts a second goal without replace, starts any goal
under the e-stop, or lets a goal started here outlive the agent's silence by more than one check;
and a confirmation is only ever a person's yes to that very question."""

from __future__ import annotations

import math
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from go2vlm.apps.mcp.rules import CommanderState, Confirmations, MotionRules, Refused, object_label

TEXTS = ["go to the blue cylinder", "look for the green box", "follow the red ball", "turn left 20.0 degrees", "sit"]
KINDS = {"go to the blue cylinder": "go_to", "look for the green box": "look_for", "follow the red ball": "follow",
         "turn left 20.0 degrees": "turn", "sit": "sit", "stop": "stop", "": None}  # fmt: skip
STATES = ["searching", "approaching", "reached", "not_found", "tracking", "turning", "done", "stopped", "rejected"]

dt = st.one_of(st.floats(0.0, 0.5), st.floats(0.0, 20.0))
start_ev = st.tuples(st.just("start"), st.sampled_from(TEXTS), st.booleans(), st.booleans(), dt)
status_ev = st.tuples(st.just("status"), st.sampled_from([*TEXTS, "stop", ""]), st.sampled_from(STATES), dt)
poll_ev = st.tuples(st.just("poll"), dt)
tick_ev = st.tuples(st.just("tick"), dt)
events = st.lists(st.one_of(start_ev, status_ev, status_ev, poll_ev, tick_ev, tick_ev), min_size=1, max_size=60)


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(deadman=st.floats(1.0, 30.0), evs=events)
def test_one_goal_at_a_time_and_the_deadman(deadman: float, evs: list[tuple]) -> None:
    r = MotionRules(deadman)
    now = 0.0
    for ev in evs:
        now += ev[-1]
        if ev[0] == "start":
            _, text, replace, estop, _ = ev
            busy = r.busy_with()
            try:
                r.check_start(text, replace=replace, estop=estop)
            except Refused as exc:
                assert estop or (busy is not None and not replace)
                assert ("e-stop" in str(exc)) if estop else (busy in str(exc) and "replace=true" in str(exc))
                continue
            assert not estop, "no goal starts under the e-stop"
            assert busy is None or replace, "a second goal needs replace"
            r.started(text, now)
            assert r.busy_with() is not None  # sent, not answered: busy
        elif ev[0] == "status":
            _, text, state, _ = ev
            r.observe(CommanderState(text, KINDS[text], state), now)
        elif ev[0] == "poll":
            r.poll(now)
        else:
            ours = r.ours
            why = r.deadman(now)
            if why is not None:
                assert ours is not None and now - r.last_poll > deadman and r.ours is None
            elif ours is not None:
                assert now - r.last_poll <= deadman, "a silent agent's goal is stopped at the next check"
        # The busy rule follows the commander: a goal that lasts, not over, or ours not yet answered.
        c = r.commander
        if r.ours is None and (c is None or not c.busy):
            assert r.busy_with() is None


def test_a_goal_ends_when_the_commander_says_so_or_runs_another() -> None:
    r = MotionRules(10.0)
    r.started("go to the blue cylinder", 0.0)
    r.observe(CommanderState("", None, "idle"), 0.1)  # an old status: still waiting for the answer
    assert r.ours is not None and "not yet acknowledged" in (r.busy_with() or "")
    r.observe(CommanderState("go to the blue cylinder", "go_to", "searching"), 0.2)
    assert r.ours is not None and r.ours.acked and "searching" in (r.busy_with() or "")
    r.observe(CommanderState("go to the blue cylinder", "go_to", "reached"), 5.0)
    assert r.ours is None and r.busy_with() is None and r.deadman(100.0) is None
    r.started("follow the red ball", 6.0)
    r.observe(CommanderState("follow the red ball", "follow", "tracking"), 6.1)
    r.observe(CommanderState("look for the green box", "look_for", "searching"), 7.0)  # someone else's
    assert r.ours is None and "look for the green box" in (r.busy_with() or "")


def test_the_deadman_stops_once_after_the_silence() -> None:
    r = MotionRules(10.0)
    r.started("follow the red ball", 0.0)
    r.observe(CommanderState("follow the red ball", "follow", "tracking"), 0.1)
    r.poll(5.0)
    assert r.deadman(15.0) is None
    why = r.deadman(15.1)
    assert why is not None and "deadman" in why and "follow the red ball" in why
    assert r.deadman(30.0) is None  # once
    with pytest.raises(ValueError):
        MotionRules(math.nan)


answers = st.sampled_from(["yes", "y", "YES", "no", "n", "maybe", "yes 1", "yes 2", "no 1", "yes #1", "", "yes please"])


@settings(max_examples=300, deadline=None)
@given(lines=st.lists(st.tuples(answers, st.booleans(), st.floats(0.0, 40.0)), max_size=8))
def test_a_confirmation_is_a_yes_to_that_question(lines: list[tuple[str, bool, float]]) -> None:
    c = Confirmations(timeout_s=60.0)
    qid = c.ask("go to the blue cylinder", 0.0)
    assert qid == 1
    now = 0.0
    yes_given = False
    for line, need_id, step in lines:
        now += step
        before = c.result(qid, now)
        c.answer(line, need_id=need_id)
        words = line.lower().split()
        if before is None and now < 60.0 and words and words[0] in ("y", "yes") and len(words) <= 2:
            named = len(words) == 2
            if (named and words[1].lstrip("#") == "1") or (not named and not need_id):
                yes_given = True
        result = c.result(qid, now)
        if result:
            assert yes_given, (line, need_id)
    if now >= 60.0 and c.result(qid, now) is None:
        pytest.fail("an unanswered question must time out as no")


def test_a_new_question_closes_the_old_one_as_no() -> None:
    c = Confirmations(60.0)
    first = c.ask("go to the blue cylinder", 0.0)
    second = c.ask("look for the green box", 1.0)
    assert c.result(first, 1.0) is False and c.result(second, 1.0) is None
    assert "#1" in c.answer("yes 1", need_id=True) and c.result(second, 1.0) is None  # a stale answer
    assert c.answer("yes 2", need_id=True) == "#2 confirmed" and c.result(second, 2.0) is True
    assert c.result(second, 200.0) is True  # an answer given stays given


@pytest.mark.parametrize(
    ("phrase", "grounding", "label", "why"),
    [
        ("blue cylinder", "color", "blue cylinder", None),
        ("the Blue Cylinder", None, "blue cylinder", None),
        ("蓝色圆柱", "color", "blue cylinder", None),
        ("person", "vlm", "person", None),
        ("unicorn", "color", None, "unknown object 'unicorn'"),
        ("unicorn", None, None, "has not reported"),
        ("purple ball", "vlm", None, "unknown word(s) 'purple'"),
        ("", "color", None, "no object named"),
        ("x" * 101, "vlm", None, "at most 100"),
    ],
)
def test_object_labels(phrase: str, grounding: str | None, label: str | None, why: str | None) -> None:
    if why is None:
        assert object_label(phrase, grounding) == label
    else:
        with pytest.raises(Refused, match=re.escape(why)):
            object_label(phrase, grounding)


def test_only_three_names_are_loopback_and_every_bind_names_its_hosts() -> None:
    pytest.importorskip("mcp")
    from go2vlm.apps.mcp.server import allowed_hosts, is_loopback

    for host in ("127.0.0.1", "::1", "[::1]", "localhost"):
        assert is_loopback(host)
    for host in ("127.0.0.7", "0:0:0:0:0:0:0:1", "127.1", "0.0.0.0", "::", "LOCALHOST.", "evil.example"):
        assert not is_loopback(host)
    assert set(allowed_hosts("127.0.0.1")) >= {"127.0.0.1:*", "localhost:*", "[::1]:*"}
    assert allowed_hosts("192.168.1.5") == ["192.168.1.5", "192.168.1.5:*"]
    assert allowed_hosts("fd00::5") == ["[fd00::5]", "[fd00::5]:*"]
    wild = allowed_hosts("0.0.0.0", ("robot-pc",))
    assert "robot-pc:*" in wild and "localhost" in wild and not any(h.startswith("0.0.0.0") for h in wild)
