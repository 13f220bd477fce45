"""The health monitor's rules (safety/health.py), as property tests over explicit timestamps."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.safety.health import (
    BATTERY_PCT,
    MOTOR_TEMP_C,
    TILT_DEG,
    HealthMonitor,
    HealthPolicy,
    HealthSample,
    Ladder,
    Level,
)

POLICY = HealthPolicy()
tilts = st.floats(-90.0, 90.0)
temps = st.floats(0.0, 150.0)
batteries = st.floats(0.0, 100.0)
samples = st.builds(
    HealthSample,
    roll_deg=tilts,
    pitch_deg=tilts,
    motor_temp_c=st.lists(temps, min_size=0, max_size=12).map(tuple),
    battery_pct=st.one_of(st.none(), batteries),
)
gaps = st.floats(0.0, 0.4)  # below stale_s: the stream stays fresh


def demand(s: HealthSample) -> Level:
    """The level the sample alone demands."""
    levels = [TILT_DEG.demand(s.tilt_deg), MOTOR_TEMP_C.demand(s.hottest_c)]
    if s.battery_pct is not None:
        levels.append(BATTERY_PCT.demand(s.battery_pct))
    return max(levels)


def scale_of(level: Level) -> float:
    return 1.0 if level <= Level.WARN else POLICY.cap_scale if level == Level.CAP else 0.0


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(samples, gaps), min_size=1, max_size=40))
def test_never_below_what_the_newest_reading_demands(history: list[tuple[HealthSample, float]]) -> None:
    """An input never raises a limit: whatever came before, the verdict is at least as strict as the
    newest reading, and the speed scale is never above the one that reading allows."""
    mon = HealthMonitor(POLICY)
    now = 0.0
    for sample, gap in history:
        now += gap
        mon.observe(sample, now)
        v = mon.verdict(now)
        assert v.level >= demand(sample)
        assert 0.0 <= v.speed_scale <= scale_of(demand(sample))
        assert v.speed_scale == scale_of(v.level)
        assert (v.hold is not None) == (v.level >= Level.STOP)


@settings(max_examples=300, deadline=None)
@given(samples, samples)
def test_escalation_is_monotone_in_severity(a: HealthSample, b: HealthSample) -> None:
    """A reading that is worse in every respect never gets a milder verdict."""
    worse = HealthSample(
        roll_deg=max(abs(a.roll_deg), abs(b.roll_deg)),
        pitch_deg=max(abs(a.pitch_deg), abs(b.pitch_deg)),
        motor_temp_c=(max(a.hottest_c, b.hottest_c),),
        battery_pct=None if a.battery_pct is None else min(a.battery_pct, b.battery_pct or a.battery_pct),
    )
    ma, mw = HealthMonitor(POLICY), HealthMonitor(POLICY)
    ma.observe(a, 0.0)
    mw.observe(worse, 0.0)
    va, vw = ma.verdict(0.0), mw.verdict(0.0)
    assert vw.level >= va.level and vw.speed_scale <= va.speed_scale


LADDERS = [("tilt", TILT_DEG), ("motor", MOTOR_TEMP_C), ("battery", BATTERY_PCT)]


def sample_for(kind: str, x: float) -> HealthSample:
    if kind == "tilt":
        return HealthSample(roll_deg=x, battery_pct=80.0)
    if kind == "motor":
        return HealthSample(motor_temp_c=(x,), battery_pct=80.0)
    return HealthSample(battery_pct=x)


@pytest.mark.parametrize(("kind", "ladder"), LADDERS)
@settings(max_examples=100, deadline=None)
@given(
    step=st.integers(0, 3),
    noise=st.lists(st.tuples(st.floats(-0.49, 0.49), gaps), min_size=2, max_size=60),
)
def test_hysteresis_no_flapping(kind: str, ladder: Ladder, step: int, noise: list[tuple[float, float]]) -> None:
    """A reading that dithers around a threshold by less than half the hysteresis, at any rate and
    for any time, never makes the level go down: it escalates and stays."""
    th = ladder.steps[step]
    mon = HealthMonitor(POLICY)
    now, levels = 0.0, []
    for u, gap in noise:
        now += gap
        mon.observe(sample_for(kind, th + u * ladder.hysteresis), now)
        levels.append(mon.verdict(now).level)
    assert levels == sorted(levels)


@pytest.mark.parametrize(("kind", "ladder"), LADDERS)
def test_each_threshold_escalates_and_clears_after_clear_s(kind: str, ladder: Ladder) -> None:
    mon = HealthMonitor(POLICY)
    healthy = sample_for(kind, 0.0 if ladder.rising else 100.0)
    for lvl, th in zip((Level.WARN, Level.CAP, Level.STOP, Level.DOWN), ladder.steps, strict=True):
        mon.observe(sample_for(kind, th), 0.0)
        assert mon.verdict(0.0).level == lvl
    t = 0.0
    while t < POLICY.clear_s - 0.1:  # healthy again, but not for long enough
        t += 0.1
        mon.observe(healthy, t)
        assert mon.verdict(t).level == Level.DOWN
    t += 0.2
    mon.observe(healthy, t)
    v = mon.verdict(t)
    assert v.level == Level.OK and v.speed_scale == 1.0 and v.reasons == ()


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(samples, gaps), min_size=1, max_size=10), st.floats(0.501, 1e6))
def test_a_stale_stream_stops(history: list[tuple[HealthSample, float]], silence: float) -> None:
    mon = HealthMonitor(POLICY)
    now = 0.0
    for sample, gap in history:
        now += gap
        mon.observe(sample, now)
    v = mon.verdict(now + silence)
    assert v.level >= Level.STOP and v.speed_scale == 0.0 and "state stream lost" in (v.hold or "")


def test_require_state_stops_until_the_first_sample() -> None:
    assert HealthMonitor(HealthPolicy()).verdict(5.0).level == Level.OK  # not required: armed by the first sample
    mon = HealthMonitor(HealthPolicy(require_state=True))
    assert mon.verdict(0.0).level == Level.STOP
    mon.observe(HealthSample(battery_pct=90.0), 1.0)
    assert mon.verdict(1.0).level == Level.STOP  # clears like any reading: after clear_s
    mon.observe(HealthSample(battery_pct=90.0), 1.0 + POLICY.clear_s)
    assert mon.verdict(1.0 + POLICY.clear_s).level == Level.OK


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_an_unreadable_reading_stops(bad: float) -> None:
    for sample in (HealthSample(roll_deg=bad), HealthSample(motor_temp_c=(40.0, bad)), HealthSample(battery_pct=bad)):
        mon = HealthMonitor(POLICY)
        mon.observe(sample, 0.0)
        assert mon.verdict(0.0).level >= Level.STOP


def test_ladders_must_be_ordered() -> None:
    with pytest.raises(ValueError, match="increase"):
        Ladder(10, 30, 20, 40, 1)
    with pytest.raises(ValueError, match="decrease"):
        Ladder(10, 20, 30, 40, 1, rising=False)
    with pytest.raises(ValueError, match="finite"):
        Ladder(10, 20, 30, math.nan, 1)
    with pytest.raises(ValueError, match="cap_scale"):
        HealthPolicy(cap_scale=1.5)


@settings(max_examples=200, deadline=None)
@given(
    scale=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(0.0, 1.0)),
    hold=st.one_of(st.none(), st.just("health: motor 110 C (stop)")),
    commands=st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-5, 5)), min_size=1, max_size=20),
)
def test_the_gate_core_applies_the_verdict_and_never_exceeds_its_limits(
    scale: float, hold: str | None, commands: list[tuple[float, float, float]]
) -> None:
    """Whatever the verdict carries (a scale above 1, negative, NaN), the output stays within the
    configured limits times a factor in [0, 1], and a hold is exactly zero."""
    from go2vlm.safety.limits import Limits, Velocity
    from go2vlm.safety.mux import SafetyCore

    core = SafetyCore(limits=Limits(accel_linear=1e6, accel_angular=1e6))
    core.health(scale, hold)
    factor = min(1.0, max(0.0, scale)) if math.isfinite(scale) else 0.0
    bound = core.limits.scaled(factor)
    t = 0.0
    for vx, vy, wz in commands:
        t += 0.02
        core.command("teleop", Velocity(vx, vy, wz), t)
        out = core.step(t)
        assert bound.within(out) and core.limits.within(out)
        if hold:
            assert out.is_zero and core.reason == hold
