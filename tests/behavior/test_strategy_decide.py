"""Property tests of the VLM decisions strategy (behavior/strategies/decide.py): whatever the answers
and timings, a decision never moves the robot forward, turns only at the bounded turn rate and (with
no pose to measure it by) for no longer than its angle asks, holds exactly `decision_hold_s` after a
stop, and counts every answer."""

from __future__ import annotations

import json
import math
from collections import Counter

from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.behavior.goals import parse_goal
from go2vlm.behavior.strategies.base import Context
from go2vlm.behavior.strategies.decide import Decisions
from go2vlm.behavior.strategies.params import MissionParams

answers = st.one_of(
    st.sampled_from(['{"action": "stop"}', '{"action": "continue"}', '{"action": "sit"}', "stop", "RUN", ""]),
    st.floats(-60.0, 60.0).map(lambda a: json.dumps({"action": "turn", "angle_deg": a})),
    st.text(max_size=20),
)


@settings(max_examples=150)
@given(
    evs=st.lists(st.tuples(answers, st.floats(0.0, 2.0)), min_size=1, max_size=30),
    rate=st.floats(0.05, 1.0),
    max_angular=st.floats(0.0, 2.0),
    hold=st.floats(0.1, 5.0),
)
def test_decisions_are_bounded_timing_only(
    evs: list[tuple[str, float]], rate: float, max_angular: float, hold: float
) -> None:
    p = MissionParams(decision_turn_rate=rate, max_angular=max_angular, decision_hold_s=hold)
    ctx = Context(p, goal=parse_goal("go to the blue cylinder"))
    d, counters, now = Decisions(), Counter[str](), 0.0
    held_until, turn_end, turn_dir = -math.inf, -math.inf, 0.0

    def check(t: float) -> None:
        cmd = d.step(ctx, t)
        if t < held_until:
            assert cmd is not None and cmd.state == "holding" and cmd.vx == cmd.wz == 0.0
        elif t < turn_end:
            assert cmd is not None and cmd.state == "turning" and cmd.vx == 0.0
            assert cmd.wz == turn_dir * min(rate, max_angular)
        else:
            assert cmd is None

    for text, dt in evs:  # time runs on: a step halfway to each answer, then one as it is taken
        check(now + dt / 2)
        now += dt
        dec = d.parse(text, p, counters)
        assert counters["decisions_accepted"] + counters["decisions_rejected"] > 0
        assert d.last is not None and d.last["accepted"] == (dec is not None)
        if dec is not None:
            d.apply(dec, p, now)
            if dec.action == "stop":
                held_until = now + hold
            elif dec.action == "continue":
                held_until = -math.inf
            elif dec.action == "turn":
                assert abs(dec.angle_deg) <= p.max_turn_deg
                r = min(rate, max_angular)
                turn_end = now + (math.radians(abs(dec.angle_deg)) / r if r > 0 else 0.0)
                turn_dir = math.copysign(1.0, dec.angle_deg) if dec.angle_deg else 0.0
        check(now)


@given(angle=st.floats(-30.0, 30.0), rate=st.floats(0.05, 1.0), t=st.floats(0.0, 20.0))
def test_a_turn_goal_turns_its_angle_then_is_done(angle: float, rate: float, t: float) -> None:
    p = MissionParams(decision_turn_rate=rate)
    goal = parse_goal(f"turn {angle:.3f}")
    ctx = Context(p, goal=goal)
    d = Decisions()
    d.start_turn(goal.angle_deg, p, 0.0)
    cmd = d.step(ctx, t)
    assert cmd is not None and cmd.vx == 0.0
    r = min(rate, p.max_angular)
    if t < math.radians(abs(goal.angle_deg)) / r:
        assert cmd.state == "turning" and abs(cmd.wz) == (r if goal.angle_deg else 0.0)
    else:
        assert cmd.state == "done" and cmd.wz == 0.0
