"""The headway watch of a tracked go to (behavior/strategies/headway.py) over the navigator: a robot
that keeps moving never stalls; one held near a spot for the navigator's progress window hands the
target's place to the navigator, whose route goes through the doorway, until it is `headway_out_m`
out, and the watch then starts afresh; a pause in the go to starts it afresh too. Through the tracked
approach: one that stalls in view walks with the navigator; an object seen through a doorway from
beside its jamb is walked to with the navigator from the first step (strategies/approach.py)."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st
from test_strategy_route import ctx_at, two_rooms

from go2vlm.behavior.strategies.approach import Approach
from go2vlm.behavior.strategies.base import Context, Sighting
from go2vlm.behavior.strategies.headway import Headway
from go2vlm.behavior.strategies.params import MissionParams

DUCK = (-4.8, -2.6)  # in the left room; the door is at x = 0, |y| < 0.6
P = MissionParams()
WINDOW, RADIUS = P.nav.progress_s, P.nav.progress_m


def crossings(ctx: Context) -> list[float]:
    """Where the route crosses the middle wall's line (x = 0)."""
    assert ctx.route is not None
    w = ctx.route.plan.waypoints
    return [float(a[1] + (b[1] - a[1]) * (0 - a[0]) / (b[0] - a[0])) for a, b in zip(w[:-1], w[1:], strict=True)
            if a[0] * b[0] < 0]  # fmt: skip


@settings(max_examples=100)
@given(speed=st.floats(RADIUS / WINDOW * 1.5, 0.6), heading=st.floats(-math.pi, math.pi), dt=st.floats(0.05, 0.5))
def test_a_robot_that_moves_never_stalls(speed: float, heading: float, dt: float) -> None:
    h, cm = Headway(), two_rooms()
    for i in range(int(3 * WINDOW / dt)):
        t = i * dt
        ctx = ctx_at(2.0 + speed * t * math.cos(heading), speed * t * math.sin(heading), 0.0, cm, now=t)
        assert h.walk(ctx, DUCK, 1.0, t, "duck") is None
        assert ctx.counters["stalled"] == 0


def test_a_stalled_go_to_walks_with_the_navigator_through_the_door_then_watches_afresh() -> None:
    h, cm, t = Headway(), two_rooms(), 0.0
    ctx = ctx_at(0.5, -1.0, 2.0, cm, now=t)
    while True:  # rocking within a few cm of (0.5, -1.0), beside the jamb
        ctx = ctx_at(0.5 + 0.05 * math.sin(t), -1.0, 2.0, cm, now=t)
        cmd = h.walk(ctx, DUCK, 1.0, t, "duck")
        if cmd is not None:
            break
        assert t < WINDOW + 0.5
        t += 0.1
    assert t >= WINDOW - 0.2 and ctx.counters["stalled"] == 1 and cmd.navigated
    assert crossings(ctx) and all(abs(y) < 0.6 for y in crossings(ctx))  # through the door
    # Still near the stall: the navigator goes on; out by headway_out_m: the watch restarts there.
    assert h.walk(ctx_at(0.2, -0.5, 2.0, cm, now=t + 1), DUCK, 1.0, t + 1, "duck") is not None
    out = ctx_at(0.5 - P.headway_out_m - 0.1, -0.2, math.pi, cm, now=t + 2)
    assert h.walk(out, DUCK, 1.0, t + 2, "duck") is None and h.stalled is None


def test_a_pause_in_the_go_to_starts_the_watch_afresh() -> None:
    h, cm = Headway(), two_rooms()
    for i in range(int(WINDOW * 10) - 5):
        assert h.walk(ctx_at(0.5, -1.0, 2.0, cm, now=i / 10), DUCK, 1.0, i / 10, "duck") is None
    t = WINDOW + 2 * P.lost_timeout_s + 1.0  # a search or a look in between
    for i in range(int(WINDOW * 10) - 5):
        assert h.walk(ctx_at(0.5, -1.0, 2.0, cm, now=t + i / 10), DUCK, 1.0, t + i / 10, "duck") is None


def test_no_route_leaves_the_approach_as_it_was() -> None:
    h, cm, t = Headway(), two_rooms(door=False), 0.0
    ctx = ctx_at(0.5, -1.0, 2.0, cm, now=t)
    while t < 2.5 * WINDOW:
        ctx.pose = ctx_at(0.5, -1.0, 2.0, cm, now=t).pose
        assert h.walk(ctx, DUCK, 1.0, t, "duck") is None
        t += 0.1
    assert ctx.counters["stalled"] == 2  # it stalled, the navigator found no route, it watched again


def test_the_tracked_approach_walks_with_the_navigator_once_it_stalls() -> None:
    """The duck in view straight through the door, ranged 1.5 m; the robot held where it stands (the
    map shows a straight way, so the approach steers): first the approach's own way, then, once it
    stalls, the navigator's."""
    a, cm = Approach(), two_rooms()
    states: list[str] = []
    t, ctx = 0.0, ctx_at(1.8, 0.0, math.pi, cm, now=0.0)
    while t < WINDOW + 2.0:
        ctx.pose = ctx_at(1.8, 0.0, math.pi, cm, now=t).pose
        s = Sighting(t, "duck", "tracking", 0.0, 1.5, "bottom", 0.0)
        ctx.sighting = s
        ctx.saw(s)
        cmd = a.step(ctx, t)
        assert cmd is not None and cmd.state != "reached"
        states.append(cmd.reason)
        t += 0.1
    assert not any("with the navigator" in r for r in states[: int(WINDOW * 10) - 2])
    assert "no headway, with the navigator" in states[-1] and ctx.route is not None


def test_a_target_seen_past_a_jamb_is_walked_to_through_the_door() -> None:
    """The duck in view through the door from beside its jamb: the straight way to it crosses the
    wall on the map, so the navigator walks the go to from the first step, through the door, and on
    to where it was seen when the jamb hides it."""
    a, cm = Approach(), two_rooms()
    ctx = ctx_at(0.5, -1.0, 2.6, cm, now=0.0)
    s = Sighting(0.0, "duck", "tracking", 0.1, 1.2, "bottom", -0.1)
    ctx.sighting = s
    ctx.saw(s)
    cmd = a.step(ctx, 0.0)
    assert cmd is not None and cmd.navigated and "no straight way on the map" in cmd.reason, cmd
    assert ctx.route is not None
    end = ctx.route.plan.waypoints[-1]  # in the doorway or past it: where the duck is in sight
    assert all(abs(y) < 0.6 for y in crossings(ctx)) and end[0] < 0.3 and abs(end[1]) < 0.6, ctx.route.plan.waypoints
    ctx.pose = ctx_at(0.5, -1.0, 2.6, cm, now=1.0).pose
    hidden = a.step(ctx, 1.0)  # no fresh sighting: out of view
    assert hidden is not None and hidden.navigated and "out of view" in hidden.reason, hidden
    late = 2.0 + P.detour_memory_s
    ctx.pose = ctx_at(0.5, -1.0, 2.6, cm, now=late).pose
    assert a.step(ctx, late) is None  # the track is too old: lost, then the search
