"""The safety gate on sim time keeps a wall-clock bound: an input silent for wall_timeout_s of wall
time is absent, and a /clock that stands still for wall_timeout_s zeroes /cmd_vel, published at a
wall-clock rate. The pure rule (SafetyCore with two clocks) is property-tested; the node is tested
as a real process fed /clock by the test."""

from __future__ import annotations

import json
import math
import threading
from collections.abc import Iterator
from typing import Any

import pytest
from busutil import Procs, Recorder, wait_for
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.std_msgs import String
from go2vlm.safety.limits import ZERO, Limits, Velocity
from go2vlm.safety.mux import InputSpec, SafetyCore

NAMES = ("teleop", "follower", "behavior")
PRIORITY = dict(zip(NAMES, (100, 50, 10), strict=True))

# -- the pure rule ----------------------------------------------------------------------------------

velocity = st.one_of(
    st.tuples(*[st.floats(min_value=-2.0, max_value=2.0)] * 3),
    st.tuples(*[st.floats(min_value=-2.0, max_value=2.0)] * 3),
    st.tuples(st.floats(allow_nan=True, allow_infinity=True), st.just(0.0), st.just(0.0)),
)
# Sim time often stands still (a stalled /clock, or events within one tick); wall time always moves.
d_sim = st.one_of(st.just(0.0), st.just(0.0), st.floats(min_value=0.0, max_value=0.3))
d_wall = st.floats(min_value=0.0, max_value=1.5)
cmd_ev = st.tuples(st.just("cmd"), st.sampled_from(NAMES), velocity, d_sim, d_wall)
step_ev = st.tuples(st.just("step"), st.just(""), st.just((0.0, 0.0, 0.0)), d_sim, d_wall)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    timeouts=st.tuples(*[st.floats(min_value=0.05, max_value=2.0)] * 3),
    wall_timeout=st.floats(min_value=0.1, max_value=3.0),
    events=st.lists(st.one_of(cmd_ev, cmd_ev, step_ev, step_ev, step_ev), max_size=60),
)
def test_two_clock_core_never_drives_on_a_stale_input_or_a_stalled_clock(timeouts, wall_timeout, events) -> None:
    specs = [InputSpec(n, f"/{n}/cmd_vel", PRIORITY[n], t) for n, t in zip(NAMES, timeouts, strict=True)]
    core = SafetyCore(specs, Limits(), wall_timeout_s=wall_timeout)
    timeout = dict(zip(NAMES, timeouts, strict=True))
    now = wall = 0.0
    last: dict[str, tuple[float, float]] = {}  # input -> (sim, wall) of its last valid command
    advanced: tuple[float, float] | None = None  # (sim, wall) when the sim clock last moved forward
    for kind, name, (vx, vy, wz), ds, dw in events:
        now += ds
        wall += dw
        if advanced is None or now > advanced[0]:
            advanced = (now, wall)
        if kind == "cmd":
            why = core.command(name, Velocity(vx, vy, wz), now, wall)
            if why is None:
                last[name] = (now, wall)
            else:
                last.pop(name, None)
            continue
        out = core.step(now, wall)
        stalled = wall - advanced[1] >= wall_timeout
        live = [
            n
            for n, (t, w) in last.items()
            if 0.0 <= now - t < timeout[n] and 0.0 <= wall - w < wall_timeout and not stalled
        ]
        want = max(live, key=lambda n: PRIORITY[n]) if live else None
        assert core.active == want, (core.active, want, last, now, wall)
        assert math.isfinite(out.vx) and math.isfinite(out.vy) and math.isfinite(out.wz)
        if stalled:
            assert out == ZERO and core.reason == "clock stalled", "a stalled sim clock must stop the robot"
        if not live:
            assert out == ZERO, "moving on an input that is stale in sim time or in wall time"


def _settle(core: SafetyCore, now: float, wall: float | None) -> Velocity:
    """Step until the acceleration ramp has reached its target (0.05 s steps), return the output."""
    out = core.step(now, wall)
    for i in range(1, 21):
        out = core.step(now + 0.05 * i, None if wall is None else wall + 0.001 * i)
    return out


def test_one_clock_core_has_no_wall_bound() -> None:
    """Without a wall time (the gate on wall time), a live input stays live however long the pause."""
    core = SafetyCore([InputSpec("teleop", "/teleop/cmd_vel", 100, 5.0)], Limits(), wall_timeout_s=0.5)
    core.command("teleop", Velocity(0.2, 0, 0), 0.0)
    assert _settle(core, 0.0, None).vx == pytest.approx(0.2)
    assert core.step(4.0).vx == pytest.approx(0.2) and not core.clock_stalled(None)


def test_a_stalled_clock_zeroes_then_the_output_resumes_with_the_clock() -> None:
    core = SafetyCore([InputSpec("teleop", "/teleop/cmd_vel", 100, 2.0)], Limits(), wall_timeout_s=2.0)
    core.command("teleop", Velocity(0.1, 0, 0), 10.0, 100.0)
    assert _settle(core, 10.0, 100.0).vx == pytest.approx(0.1)  # sim 11.0, wall 100.02
    # /clock stops at 11.0; a wall-time teleop tool keeps sending: live in sim time, but the clock stalls.
    core.command("teleop", Velocity(0.1, 0, 0), 11.0, 101.0)
    assert core.step(11.0, 101.5).vx == pytest.approx(0.1)  # 1.48 s of wall time without sim time: not yet
    core.command("teleop", Velocity(0.1, 0, 0), 11.0, 102.0)
    assert core.step(11.0, 102.1) == ZERO and core.reason == "clock stalled"
    assert core.active is None and core.counters["clock_stalls"] == 1
    core.command("teleop", Velocity(0.1, 0, 0), 11.01, 102.2)  # the clock moves again
    assert _settle(core, 11.01, 102.2).vx == pytest.approx(0.1)


def test_an_input_silent_for_the_wall_bound_is_absent_even_if_young_in_sim_time() -> None:
    core = SafetyCore([InputSpec("follower", "/follower/cmd_vel", 50, 10.0)], Limits(), wall_timeout_s=2.0)
    core.command("follower", Velocity(0.0, 0, 0.5), 1.0, 50.0)
    assert _settle(core, 1.0, 50.0).wz == pytest.approx(0.5)  # sim 2.0, wall 50.02
    assert core.step(2.05, 51.9).wz == pytest.approx(0.5)  # 1.9 s of wall time: still live
    assert core.step(2.1, 52.0) == ZERO and core.active is None  # 2 s of wall time, 1.1 s of sim time
    assert core.reason == "follower timed out"


# -- the node, as a real process ---------------------------------------------------------------------

WALL_TIMEOUT = 0.5


class GateProbe(Node):
    name = "gate_sim_time_probe"

    def __init__(self) -> None:
        super().__init__()
        self.cmd = Recorder()
        self.status = Recorder()
        self.create_subscription(Twist, "/cmd_vel", self.cmd, QOS_DEFAULT)
        self.create_subscription(String, "/safety/status", self.status, QOS_LATCHED)
        self.clock_pub = self.create_publisher(Clock, "/clock", QOS_DEFAULT)
        self.teleop_pub = self.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)
        self.sim_t = 100.0
        self.clock_running = threading.Event()
        self._halt = threading.Event()
        self._driver = threading.Thread(target=self._drive, daemon=True)
        self._driver.start()

    def _drive(self) -> None:
        """/clock in 10 ms steps while clock_running; teleop at 20 Hz of wall time all along, as a
        person's teleop tool (not on sim time) would send it."""
        i = 0
        while not self._halt.wait(0.01):  # publisher pacing, not a timing assertion
            if self.clock_running.is_set():
                self.sim_t += 0.01
                self.clock_pub.publish(Clock(clock=Time.from_sec(self.sim_t)))
            if i % 5 == 0:
                self.teleop_pub.publish(Twist(linear=Vector3(x=0.3)))
            i += 1

    def last_status(self) -> dict[str, Any]:
        msgs = self.status.msgs()
        return json.loads(msgs[-1].data) if msgs else {}

    def close(self) -> None:
        self._halt.set()
        self._driver.join(2.0)


@pytest.fixture
def gate(procs: Procs) -> Iterator[GateProbe]:
    probe = GateProbe().start()
    procs.start(
        "run", "safety", "--param", "use_sim_time=true", "--param", f"wall_timeout_s={WALL_TIMEOUT}",
        "--param", "guard=false",  # no scan in this test: the blind cap is not what it checks
    )  # fmt: skip
    yield probe
    probe.shutdown()


def test_gate_on_sim_time_follows_the_clock_and_zeroes_at_wall_rate_when_it_stalls(gate: GateProbe) -> None:
    gate.clock_running.set()
    assert wait_for(lambda: gate.cmd.msgs() and gate.cmd.msgs()[-1].linear.x == pytest.approx(0.3), 30.0), (
        f"the gate did not pass teleop through on sim time; status {gate.last_status()}"
    )
    assert gate.last_status().get("active") == "teleop"

    gate.clock_running.clear()  # /clock stalls; teleop keeps coming
    assert wait_for(lambda: gate.last_status().get("last_zero_reason") == "clock stalled", 30.0), gate.last_status()
    n0 = len(gate.cmd)
    # Zeros keep coming while sim time stands still: the gate's wall-clock watchdog publishes them.
    assert wait_for(lambda: len(gate.cmd) >= n0 + 20, 30.0), "no /cmd_vel while /clock is stalled"
    tail = gate.cmd.msgs()[n0:]
    assert all(m.linear.x == 0.0 and m.angular.z == 0.0 for m in tail), tail[:3]
    assert gate.last_status()["counters"].get("clock_stalls", 0) >= 1

    gate.clock_running.set()  # the sim comes back: teleop drives again (ramped from zero)
    n1 = len(gate.cmd)
    assert wait_for(lambda: any(m.linear.x > 0.0 for m in gate.cmd.msgs()[n1:]), 30.0)
