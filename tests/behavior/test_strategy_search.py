"""Property tests of the search (behavior/strategies/search.py) and of its hook in the mission: turn and
look never moves forward, turns only towards where the target was last seen and within its rates;
with slow answers it holds still until a look is answered and is exhausted only after a whole turn;
a search strategy appended to Mission.searches is asked only once turn-and-look is exhausted, and
the goal ends not_found only when every search is."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.behavior.goals import parse_goal
from go2vlm.behavior.mission import Mission, MissionParams, Sighting
from go2vlm.behavior.strategies.base import Command, Context, Pose
from go2vlm.behavior.strategies.search import TurnAndLook


@settings(max_examples=200)
@given(
    memory=st.booleans(),
    last_x=st.floats(-1.0, 1.0),
    timeout=st.floats(1.0, 30.0),
    latency=st.one_of(st.none(), st.floats(0.05, 5.0)),
    odometry=st.booleans(),
    steps=st.lists(st.floats(0.0, 0.5), min_size=1, max_size=200),
)
def test_turn_and_look_turns_towards_the_last_sighting_and_looks_before_giving_up(
    memory: bool, last_x: float, timeout: float, latency: float | None, odometry: bool, steps: list[float]
) -> None:
    p = MissionParams(search_timeout_s=timeout)
    ctx = Context(p, goal=parse_goal("look for the red ball"), view=1.27, memory=[] if memory else None)
    ctx.last_x = last_x
    s = TurnAndLook()
    s.reset(0.0)
    now = yaw = 0.0
    side = -1.0 if last_x > 0 else 1.0
    for dt in steps:
        now += dt
        if latency is not None:
            ctx.answers.take(now - latency, now)
        ctx.pose = Pose(0.0, 0.0, yaw, now) if odometry else None
        slow = s.stop_and_look(ctx)
        assert slow == (memory and not (latency is not None and latency * p.search_yaw_rate <= 0.5 * 1.27))
        before = s.phase
        cmd = s.step(ctx, now)
        if cmd is None:  # exhausted
            assert now > timeout and (not slow or s.turned >= 2 * math.pi - 1e-6)
            return
        assert cmd.vx == 0.0 and cmd.state == "searching"
        assert cmd.wz == 0.0 or math.copysign(1.0, cmd.wz) == side
        assert abs(cmd.wz) <= max(p.search_yaw_rate, p.search_step_rate)
        if slow and before == "look" and cmd.wz == 0.0:
            assert "holding still" in cmd.reason
        if not slow:
            assert cmd.wz != 0.0
        yaw += cmd.wz * dt


class Extra:
    """A search strategy of its own (what explore.py plugs in): asked only after turn-and-look."""

    name = "extra"

    def __init__(self, budget: float) -> None:
        self.budget = budget  # seconds it searches, then it is exhausted too
        self.asked: list[float] = []
        self.started: float | None = None

    def reset(self, now: float) -> None:
        self.started = None

    def pause(self, now: float, cause: str) -> None:
        self.started = None

    def step(self, ctx: Context, now: float) -> Command | None:
        self.asked.append(now)
        if self.started is None:
            self.started = now
        if now - self.started > self.budget:
            return None
        return Command(0.3, 0.0, "searching", f"walking somewhere else to find the {ctx.label}")


@settings(max_examples=50)
@given(timeout=st.floats(1.0, 10.0), budget=st.floats(0.0, 10.0))
def test_a_new_search_strategy_plugs_in_after_turn_and_look(timeout: float, budget: float) -> None:
    extra = Extra(budget)
    m = Mission(MissionParams(search_timeout_s=timeout, use_memory=False))
    m.searches.append(extra)
    m.observe(Sighting(0.0, "", "idle", hfov=1.27))
    m.set_goal("look for the red ball", 0.0)
    now, dt = 0.0, 0.05
    while m.state not in ("not_found", "found"):
        now += dt
        out = m.step(now)
        if now <= timeout:
            assert not extra.asked and out.wz != 0.0  # turn-and-look first
        elif out.state == "searching":
            assert extra.asked[-1] == now and out.vx == 0.3  # then the next one in the chain
        assert now < timeout + budget + 1.0
    assert m.state == "not_found" and now > timeout + budget
    assert m.reason == f"no red ball in view after {timeout:g} s"
