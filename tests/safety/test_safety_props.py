"""Property tests of the safety gate's pure logic (mux + limits + e-stop latch): no sequence of
inputs, values (NaN, inf, huge), timings or e-stop/release events makes the output exceed its limits,
accelerate faster than allowed, move while latched, or leave the e-stop without the release token."""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from go2vlm.robot_profile.go2 import SIM
from go2vlm.safety.estop import EstopLatch
from go2vlm.safety.limits import ZERO, Limits, Velocity, ramp
from go2vlm.safety.mux import MAX_DT, InputSpec, SafetyCore

TOKEN = "RELEASE"
NAMES = ("teleop", "follower", "behavior")

# one_of picks its branches about evenly: repeating the plausible branches keeps most examples moving
# (so the ramp and limit checks have something to check) while NaN/inf/huge still come often.
plausible = st.floats(min_value=-5.0, max_value=5.0)
any_float = st.one_of(
    plausible,
    plausible,
    plausible,
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e308, -1e308, 1e-300, 3.8, -2.5, 4.0, 100.0, 100.0001]),
)
sane_limit = st.floats(min_value=0.05, max_value=5.0)
limit_float = st.one_of(sane_limit, sane_limit, sane_limit, sane_limit, st.floats(allow_nan=True, allow_infinity=True))
small_dt = st.floats(min_value=0.0, max_value=0.05)
dt = st.one_of(small_dt, small_dt, small_dt, st.floats(min_value=0.0, max_value=0.7))

cmd = st.tuples(st.just("cmd"), st.sampled_from(NAMES), any_float, any_float, any_float, dt)
step = st.tuples(st.just("step"), dt)
tokens = st.sampled_from([TOKEN, TOKEN, TOKEN, " RELEASE\n", "release", "", "RELEASE!", "x"])
estop_ev = st.tuples(st.just("estop"), st.sampled_from([True, False, False]), dt)
release_ev = st.tuples(st.just("release"), tokens, dt)
block_ev = st.tuples(st.just("block"), st.sampled_from([None, "another /cmd_vel writer"]), dt)
event = st.one_of(cmd, cmd, cmd, cmd, step, step, step, estop_ev, release_ev, release_ev, block_ev)


def _core(lim: tuple[float, ...], timeouts: tuple[float, float, float], engaged: bool) -> SafetyCore:
    specs = [InputSpec(n, f"/{n}/cmd_vel", p, t) for n, p, t in zip(NAMES, (100, 50, 10), timeouts, strict=True)]
    return SafetyCore(specs, Limits(*lim), TOKEN, engaged)


def _accel_ok(prev: float, out: float, max_delta: float) -> bool:
    """Speeding up (or reversing) stays within max_delta; slowing down towards zero is free."""
    if out == 0.0:
        return True
    if prev != 0.0 and (prev > 0) == (out > 0) and abs(out) <= abs(prev):
        return True
    base = prev if prev != 0.0 and (prev > 0) == (out > 0) else 0.0
    return abs(out - base) <= max_delta + 1e-9


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    lim=st.tuples(*([limit_float] * 6)),
    timeouts=st.tuples(*([st.floats(min_value=0.02, max_value=2.0)] * 3)),
    engaged=st.sampled_from([False, False, False, True]),
    events=st.lists(event, max_size=60),
)
def test_no_sequence_breaks_the_gate(lim, timeouts, engaged, events) -> None:
    core = _core(lim, timeouts, engaged)
    limits = core.limits
    # Configured limits never exceed the robot's ceilings (the Go2's), whatever they were given.
    c = SIM.ceilings
    assert limits.ceiling == c
    assert 0 <= limits.vx_forward <= c.vx_forward and 0 <= limits.vx_backward <= c.vx_backward
    assert 0 <= limits.vy <= c.vy and 0 <= limits.wz <= c.vyaw
    model_engaged = engaged
    blocked = None
    last_valid: dict[str, float] = {}
    now = 0.0
    prev, t_prev = ZERO, None
    for ev in events:
        now += ev[-1]
        kind = ev[0]
        if kind == "cmd":
            _, name, vx, vy, wz, _ = ev
            why = core.command(name, Velocity(vx, vy, wz), now)
            finite = all(math.isfinite(v) and abs(v) <= 100.0 for v in (vx, vy, wz))
            assert (why is None) == finite
            if finite:
                last_valid[name] = now
            else:
                last_valid.pop(name, None)
        elif kind == "estop":
            core.estop(ev[1])
            model_engaged = model_engaged or ev[1]
        elif kind == "release":
            released = core.release(ev[1])
            assert released == (model_engaged and ev[1] == TOKEN)  # exactly the token, no trimming
            if released:
                model_engaged = False
        elif kind == "block":
            core.block(ev[1])
            blocked = ev[1]
        assert core.estopped == model_engaged, "the e-stop left its state without the release token"
        out = core.step(now)
        assert all(math.isfinite(v) for v in (out.vx, out.vy, out.wz))
        assert limits.within(out), f"{out} exceeds {limits}"
        if model_engaged:
            assert out == ZERO, "moving while the e-stop is latched"
        if blocked:
            assert out == ZERO, "moving while another writer is on /cmd_vel"
            assert core.reason == ("estop" if model_engaged else blocked)
        live = [n for n, t in last_valid.items() if 0 <= now - t < dict(zip(NAMES, timeouts, strict=True))[n]]
        if not live:
            assert out == ZERO, "moving with no live input"
        step_dt = 0.0 if t_prev is None else min(now - t_prev, MAX_DT)
        assert _accel_ok(prev.vx, out.vx, limits.accel_linear * step_dt)
        assert _accel_ok(prev.vy, out.vy, limits.accel_linear * step_dt)
        assert _accel_ok(prev.wz, out.wz, limits.accel_angular * step_dt)
        prev, t_prev = out, now


def test_priority_timeout_and_zero_override() -> None:
    core = _core((0.5, 0.5, 0.5, 1.0, 100.0, 100.0), (0.5, 0.5, 0.5), False)
    core.command("behavior", Velocity(0.2, 0, 0), 0.0)
    assert core.step(0.0) == ZERO  # first step: dt = 0, the ramp starts from zero
    assert core.step(0.02) == Velocity(0.2, 0, 0) and core.active == "behavior"
    core.command("follower", Velocity(0, 0, -0.3), 0.03)
    core.command("teleop", Velocity(0, 0, 0), 0.03)  # teleop commanding zero still wins
    assert core.step(0.04) == ZERO and core.active == "teleop"
    assert core.reason == "teleop commands zero"
    core.command("follower", Velocity(0, 0, -0.3), 0.5)
    core.command("behavior", Velocity(0.2, 0, 0), 0.5)
    assert core.step(0.6) == Velocity(0, 0, -0.3) and core.active == "follower"  # teleop timed out
    assert core.step(1.2) == ZERO and core.active is None and core.reason == "follower timed out"
    core.command("follower", Velocity(0, 0, 9.0), 1.3)
    assert core.step(1.4) == Velocity(0, 0, 1.0)  # clamped to the 1.0 rad/s limit
    assert core.command("follower", Velocity(math.nan, 0, 0), 1.41) is not None
    assert core.step(1.42) == ZERO and core.reason == "follower sent an invalid command"
    assert core.counters["rejected_follower"] == 1


def test_acceleration_ramp_and_free_braking() -> None:
    lim = Limits(accel_linear=1.0, accel_angular=2.0)
    assert ramp(ZERO, Velocity(0.5, 0, 1.0), lim, 0.1) == pytest.approx(Velocity(0.1, 0, 0.2))
    assert ramp(Velocity(0.5, 0, 1.0), Velocity(0.1, 0, 0.2), lim, 0.01) == Velocity(0.1, 0, 0.2)
    assert ramp(Velocity(0.5, 0, 0), Velocity(-0.5, 0, 0), lim, 0.1).vx == pytest.approx(-0.1)  # brake, reverse
    assert ramp(Velocity(0.5, 0.3, 1.0), ZERO, lim, 0.0) == ZERO


def test_estop_latch_needs_the_token() -> None:
    latch = EstopLatch("GO")
    assert not latch.release("GO")  # nothing to release
    latch.engage()
    assert not latch.release("go") and not latch.release("") and latch.engaged
    assert not latch.release(" GO ") and latch.engaged  # exactly the token: padding does not release
    assert latch.release("GO") and not latch.engaged
    with pytest.raises(ValueError):
        EstopLatch("")
