"""Property tests of the commander's pure core (behavior/mission.py), in the manner of SafetyCore's: no
sequence of goals (good, bad, hostile, bounded turns), tracker reports (right or wrong label, tracked or lost, NaN,
late), VLM decisions (whitelisted or not) and timings makes it move toward a target the tracker does
not confirm, exceed its speed limits, turn more than 30 degrees on one decision, or move at all in a
terminal state, on "stop" or on a goal it cannot parse."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from go2vlm.behavior.mission import TERMINAL, ZERO_BURST_S, Mission, MissionParams, Sighting

GOALS = [
    "go to the blue cylinder",
    "look for the blue cylinder",
    "follow the blue cylinder",
    "follow the red ball",
    "走到蓝色圆柱",
    "stop",
    "停下",
    "sit",
    "stand",
    "turn left 20 degrees",
    "turn -30",
    "向右转15度",
    "turn 45 degrees",
    "please do a backflip",
    "",
    "follow",
    "go to the blue cylinder and RUN AT 5 M/S",
    "x" * 300,
]
DECISIONS = [
    '{"action": "stop"}',
    '{"action": "continue"}',
    '{"action": "turn", "angle_deg": 30}',
    '{"action": "turn", "angle_deg": -17.5}',
    '{"action": "turn", "angle_deg": 45}',
    '{"action": "forward"}',
    '{"action": "turn", "angle_deg": 10, "speed": 5}',
    '{"action": "sit"}',
    "RUN FORWARD AT 5 M/S",
    "",
]
LABELS = ["blue cylinder"] * 5 + ["red ball", "person", ""]
STATES = ["tracking"] * 8 + ["lost", "searching", "idle"]

dt = st.one_of(st.floats(0.0, 0.06), st.floats(0.0, 0.06), st.floats(0.0, 0.06), st.floats(0.0, 1.5))
xs = st.one_of(st.floats(-1.0, 1.0), st.floats(-0.2, 0.2), st.sampled_from([math.nan, math.inf, -3.0, 0.0, 0.05]))
dists = st.one_of(st.none(), st.floats(0.0, 6.0), st.sampled_from([math.nan, -1.0, math.inf]))
MOVING = GOALS[:3] + GOALS[4:5]  # goals whose object is the blue cylinder
goal_ev = st.tuples(st.just("goal"), st.one_of(st.sampled_from(MOVING), st.sampled_from(GOALS)), dt)
seen_ev = st.tuples(st.just("seen"), st.sampled_from(LABELS), st.sampled_from(STATES), xs, dists, dt)
ungroundable_ev = st.tuples(st.just("seen"), st.sampled_from(LABELS), st.just("ungroundable"), xs, dists, dt)
decide_ev = st.tuples(
    st.just("decide"), st.one_of(st.sampled_from(DECISIONS[:5]), st.sampled_from(DECISIONS)), dt
)  # sit (ends the goal) less often
step_ev = st.tuples(st.just("step"), dt)
events = st.tuples(
    st.tuples(st.just("goal"), st.sampled_from(MOVING), st.just(0.0)),  # most runs start with a motion goal
    st.lists(
        st.one_of(goal_ev, seen_ev, seen_ev, seen_ev, seen_ev, seen_ev, decide_ev, step_ev, step_ev, ungroundable_ev),
        min_size=10,
        max_size=80,
    ),
).map(lambda t: [t[0], *t[1]])
params = st.builds(
    MissionParams,
    max_linear=st.one_of(st.floats(0.05, 1.0), st.just(0.0)),
    max_angular=st.floats(0.0, 2.0),
    lost_timeout_s=st.floats(0.1, 2.0),
    search_timeout_s=st.floats(1.0, 60.0),
    search_on_loss=st.booleans(),
    decision_turn_rate=st.floats(0.05, 1.0),
    max_turn_deg=st.floats(0.0, 30.0),
)


@settings(max_examples=800, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(p=params, evs=events)
def test_no_sequence_makes_the_mission_unsafe(p: MissionParams, evs: list[tuple]) -> None:
    m = Mission(p)
    now = 0.0
    newest: tuple[float, bool] | None = None  # arrival, tracked? of the newest report for the goal's object
    turn_left = 0.0  # radians a turn decision may still turn
    t_terminal: float | None = None
    prev: tuple[float, float] | None = None  # the last published (t, wz) while turning
    for ev in evs:
        now += ev[-1]
        kind = ev[0]
        if kind == "goal":
            before = m.goal
            m.set_goal(ev[1], now)
            if m.goal is not before:  # a new goal (the running one sent again carries on)
                newest, turn_left, prev = None, 0.0, None
                if m.goal is not None and m.goal.kind == "turn":
                    assert abs(m.goal.angle_deg) <= 30.0
                    turn_left = math.radians(abs(m.goal.angle_deg))  # a turn goal: its own budget
        elif kind == "seen":
            _, label, state, x, dist, _ = ev
            s = Sighting(now, label, state, x if state == "tracking" else math.nan, dist, "bottom")
            m.observe(s)
            if m.active and label == m.label:
                newest = (now, s.tracked)
        elif kind == "decide":
            before = m.counters["decisions_accepted"]
            m.decide(ev[1], now)
            accepted = m.counters["decisions_accepted"] > before
            angle = _turn_angle(ev[1])
            if angle is None:
                assert accepted == (ev[1] in ('{"action": "stop"}', '{"action": "continue"}', '{"action": "sit"}'))
            else:
                assert accepted == (abs(angle) <= p.max_turn_deg), "turn angles beyond the bound are rejected"
                if accepted:
                    turn_left, prev = math.radians(abs(angle)), None  # a new turn: a new budget
        out = m.step(now)
        state = out.state
        # Speeds within the limits, never backwards.
        back = p.nav.back_up_speed  # the navigator's, making room to turn: never faster
        assert -back <= out.vx <= p.max_linear + 1e-12 and abs(out.wz) <= p.max_angular + 1e-12, out
        # Terminal states, "stop" and goals it cannot parse: zero, no target for the follower, no query.
        if state in TERMINAL:
            if t_terminal is None:
                t_terminal = now
            assert out.vx == 0.0 and out.wz == 0.0 and out.query == ""
            if out.publish_cmd:
                event("terminal zero burst")
        else:
            t_terminal = None
        if m.goal is not None and m.goal.kind in ("stop", "sit", "stand"):
            assert state in ("stopped", "done", "rejected") and out.vx == out.wz == 0.0
        # Motion toward a target (forward speed, or the follower's target) only while the tracker
        # confirms it: its newest report for the goal's object says tracking and is fresh.
        confirmed = newest is not None and newest[1] and now - newest[0] < p.lost_timeout_s
        if out.vx > 0.0:
            assert confirmed, (out, newest, now)
            assert out.query == m.label != ""
            event("moved toward a confirmed target")
        # Turning on a decision: at most the decided angle (plus one control period's hold).
        if state == "turning":
            assert out.vx == 0.0 and abs(out.wz) <= min(p.decision_turn_rate, p.max_angular) + 1e-12
            if prev is not None:
                turn_left -= abs(prev[1]) * (now - prev[0])
            assert turn_left >= -1e-9, "a turn (decision or goal) turned further than it said"
            prev = (now, out.wz)
            event("turning")
        else:
            prev = None


def _turn_angle(text: str) -> float | None:
    """The angle of a well-formed turn decision among DECISIONS (None for the others)."""
    if text.startswith('{"action": "turn", "angle_deg": ') and "speed" not in text:
        return float(text.split(":")[-1].strip(" }"))
    return None


def _seen(m: Mission, t: float, x: float = 0.0, d: float | None = 2.0, label: str = "blue cylinder") -> None:
    m.observe(Sighting(t, label, "tracking", x, d, "bottom"))


def test_go_to_approaches_a_confirmed_target_and_stops_at_the_distance() -> None:
    m = Mission(MissionParams(lost_timeout_s=0.5))
    m.set_goal("go to the blue cylinder", 0.0)
    out = m.step(0.0)
    assert out.state == "searching" and out.query == "blue cylinder" and out.vx == 0.0 and out.wz > 0
    _seen(m, 0.1, x=0.0, d=2.0)
    out = m.step(0.1)
    assert out.state == "approaching" and out.vx == pytest.approx(0.4)
    _seen(m, 0.2, label="red ball")  # another label: ignored, still confirmed by the last report
    assert m.step(0.2).vx > 0
    m.observe(Sighting(0.3, "blue cylinder", "lost"))  # the tracker says lost: stop at once
    out = m.step(0.3)
    assert out.state == "lost" and out.vx == 0.0 and out.wz == 0.0
    _seen(m, 0.4, x=0.3, d=2.0)
    assert m.step(0.4).vx > 0
    assert m.step(0.95).vx == 0.0  # the tracker went silent: a stale report confirms nothing
    assert m.step(1.5).state == "searching" and m.step(1.5).wz < 0  # towards where it was (right)
    _seen(m, 1.6, x=0.0, d=0.5)  # 0.5 + 0.327 from the base: within 0.8 + 0.05
    out = m.step(1.6)
    assert out.state == "approaching" and out.vx == out.wz == 0.0  # just seen again: held for the memory's say
    t = 1.6
    while t < 1.6 + MissionParams().reach_settle_s:
        t += 0.25
        _seen(m, t, x=0.0, d=0.5)
    out = m.step(t)
    assert out.state == "reached" and out.vx == out.wz == 0.0 and out.publish_cmd and out.query == ""
    assert m.step(t + ZERO_BURST_S + 0.01).publish_cmd is False  # then quiet


def test_follow_drives_only_a_confirmed_target_and_decisions_gate_it() -> None:
    m = Mission(MissionParams(decision_hold_s=1.0))
    m.set_goal("follow the red ball", 0.0)
    out = m.step(0.0)
    assert out.state == "waiting" and out.vx == out.wz == 0.0 and out.query == "red ball"
    _seen(m, 0.1, label="red ball", x=0.2, d=3.0)
    out = m.step(0.1)
    # The approach law with the mission's gains: towards the offset, forward while 3.3 m > 1.2 m away.
    assert out.state == "tracking" and out.publish_cmd and out.vx > 0.0 and out.wz < 0.0
    assert out.wz == max(-m.params.max_angular, -m.params.kp_angular * 0.2)
    m.decide('{"action": "stop"}', 0.2)
    out = m.step(0.2)
    assert out.state == "holding" and out.publish_cmd and out.vx == out.wz == 0.0
    m.decide('{"action": "continue"}', 0.3)
    _seen(m, 0.3, label="red ball", x=0.0, d=3.0)
    assert m.step(0.3).vx > 0.0
    m.decide('{"action": "forward"}', 0.4)  # outside the schema: counted, ignored
    assert m.counters["decisions_rejected.unknown_action"] == 1 and m.step(0.4).vx > 0.0
    _seen(m, 0.5, label="red ball", x=0.0, d=0.8)  # 0.8 + 0.327 from the base: within 1.2 + 0.05
    out = m.step(0.5)
    assert out.state == "tracking" and out.vx == out.wz == 0.0  # close enough: it waits there, never ends


def test_a_follow_searches_after_a_loss_and_then_waits_for_it() -> None:
    p = MissionParams(search_timeout_s=2.0)
    m = Mission(p)
    m.set_goal("follow the red ball", 0.0)
    for k in range(100):  # never seen: it waits, still
        out = m.step(0.05 * k)
        assert out.state == "waiting" and out.vx == out.wz == 0.0
    _seen(m, 5.0, label="red ball", x=0.5, d=2.0)
    assert m.step(5.0).state == "tracking"
    assert m.step(5.0 + p.lost_timeout_s).state == "lost"
    out = m.step(5.0 + 2 * p.lost_timeout_s)
    assert out.state == "searching" and out.wz < 0.0  # towards where it was (right)
    out = m.step(5.0 + 2 * p.lost_timeout_s + p.search_timeout_s + 0.1)
    assert out.state == "lost" and out.vx == out.wz == 0.0 and m.active  # a follow never ends by itself


def test_an_ungroundable_object_rejects_the_goal_and_bad_goals_move_nothing() -> None:
    m = Mission()
    m.set_goal("follow the person", 0.0)
    assert m.step(0.0).query == "person"
    m.observe(Sighting(0.1, "person", "ungroundable"))
    out = m.step(0.1)
    assert out.state == "rejected" and "grounding=vlm" in out.reason and out.query == "" and out.vx == out.wz == 0.0
    m.set_goal("please do a backflip", 0.2)
    out = m.step(0.2)
    assert out.state == "rejected" and out.reason.startswith("cannot understand")
    _seen(m, 0.3, label="")
    assert m.step(0.3).vx == 0.0 and m.goal is not None and m.goal.text == "please do a backflip"


def test_a_turn_goal_turns_in_place_by_its_angle_then_is_done() -> None:
    m = Mission(MissionParams(decision_turn_rate=0.5))
    m.set_goal("turn right 20 degrees", 0.0)
    out = m.step(0.0)
    assert out.state == "turning" and out.vx == 0.0 and out.wz == pytest.approx(-0.5) and out.query == ""
    turned, t = 0.0, 0.0
    while m.step(t).state == "turning":
        turned += 0.5 * 0.01
        t += 0.01
    assert turned == pytest.approx(math.radians(20), abs=0.01)
    out = m.step(t)
    assert out.state == "done" and out.vx == out.wz == 0.0 and "turned -20" in out.reason
    m.set_goal("turn 40", t)
    assert m.step(t).state == "rejected" and m.step(t).wz == 0.0


@pytest.mark.parametrize("speed", [1.0, 0.5])
def test_a_turn_goal_turns_its_angle_by_odometry_however_slowly_the_robot_turns(speed: float) -> None:
    """The robot turns at `speed` times the commanded rate (the navigator slows a turn where its
    sweep nears something): the turn goes on until odometry says 20 degrees, not for 20 degrees' time."""
    m = Mission(MissionParams(decision_turn_rate=0.5))
    m.set_goal("turn left 20 degrees", 0.0)
    yaw, t = 0.0, 0.0
    for _ in range(2000):
        m.observe_pose(0.0, 0.0, yaw, t)
        out = m.step(t)
        if out.state != "turning":
            break
        yaw += out.wz * speed * 0.01
        t += 0.01
    assert out.state == "done" and out.reason == "turned +20 deg", out.reason
    assert yaw == pytest.approx(math.radians(20), abs=0.01)
    assert t == pytest.approx(math.radians(20) / (0.5 * speed), abs=0.05)


def test_a_turn_held_ends_after_its_slack_and_says_how_far_it_turned() -> None:
    """The robot does not turn at all (no room): after turn_slack times the turn's time it is done,
    and says it turned 0 of the 20 degrees."""
    p = MissionParams(decision_turn_rate=0.5)
    m = Mission(p)
    m.set_goal("turn right 20 degrees", 0.0)
    t = 0.0
    while t < 60.0:
        m.observe_pose(0.0, 0.0, 0.0, t)
        out = m.step(t)
        if out.state != "turning":
            break
        t += 0.01
    assert t == pytest.approx(p.turn_slack * math.radians(20) / 0.5, abs=0.05)
    assert out.state == "done" and out.vx == out.wz == 0.0
    assert out.reason == "turned +0 of -20 deg: held (no room to turn)", out.reason
    m.observe_pose(0.0, 0.0, 0.0, t + 0.1)
    assert m.step(t + 0.1).reason == out.reason  # still says so


def test_sit_and_stand_are_posture_commands() -> None:
    m = Mission()
    m.set_goal("go to the blue cylinder", 0.0)
    m.step(0.0)
    m.decide('{"action": "sit"}', 0.1)
    out = m.step(0.1)
    assert out.postures == ("sit",) and out.state == "sat" and out.vx == out.wz == 0.0
    m.set_goal("站起来", 0.2)
    assert m.step(0.2).postures == ("stand",) and m.step(0.2).postures == ()


def test_a_search_turn_beside_a_table_backs_away_first() -> None:
    """The gate's guard would hold a turn in place that sweeps the footprint into a table edge: the
    search asks the navigator for its turn, which backs away first (a leg of a driver's turn), then
    turns. The table stands 0.08 m ahead: the corners' sweep would come within a creep's clearance."""
    m = Mission(MissionParams())
    m.set_goal("look for the blue cylinder", 0.0)
    ys = np.arange(-0.6, 0.6, 0.02)
    table = np.column_stack([np.full_like(ys, 0.35 + 0.08), ys])
    m.observe_pose(0.0, 0.0, 0.0, 0.1)
    m.observe_scan(table, 0.1)
    out = m.step(0.1)
    assert out.vx < 0.0 and out.state == "searching" and "no room to turn" in out.reason, out
    assert "no room to turn" in m.planner_note
    m.observe_pose(0.0, 0.0, 0.0, 5.0)
    m.observe_scan(table + [1.0, 0.0], 5.0)  # backed off, the leg over: room to turn
    out = m.step(5.0)
    assert out.vx == 0.0 and out.wz != 0.0, out


def test_with_avoid_obstacles_off_a_turn_is_sent_as_asked() -> None:
    """avoid_obstacles off: the strategies' turns go out as they are (the guard alone holds them)."""
    m = Mission(MissionParams(avoid_obstacles=False))
    m.set_goal("look for the blue cylinder", 0.0)
    ys = np.arange(-0.6, 0.6, 0.02)
    m.observe_pose(0.0, 0.0, 0.0, 0.1)
    m.observe_scan(np.column_stack([np.full_like(ys, 0.43), ys]), 0.1)
    out = m.step(0.1)
    assert out.vx == 0.0 and out.wz != 0.0, out
