"""The robot's health, without any I/O: tilt, motor temperature, battery and the state stream become
one verdict the safety gate obeys. Timestamp-driven (pure), so it is tested exhaustively.

    mon = HealthMonitor(HealthPolicy())
    mon.observe(HealthSample(roll_deg=2.0, pitch_deg=1.0, motor_temp_c=(41, 45), battery_pct=80), now)
    v = mon.verdict(now)          # v.level, v.speed_scale, v.reasons

Levels, escalating (the follow article, section 8.2: on an anomaly fall back to degraded control or stop):
  OK    nothing to do
  WARN  reported on /safety/status and logged; speed unchanged
  CAP   speed limits scaled by `cap_scale` (0.5): degraded control
  STOP  /cmd_vel held at exactly zero
  DOWN  STOP, and the gate latches the e-stop (the sim and the go2 driver Damp: the robot lies down);
        leaving it takes the deliberate release, like any e-stop

Each reading climbs a ladder of four thresholds (warn < cap < stop < down; for the battery a lower
reading is worse). Rules:
- Escalation is immediate: the level is never below what the newest reading demands.
- Hysteresis: a level is kept while the reading stays within `hysteresis` of its threshold, and a
  lower level is taken only after the lower demand has held for `clear_s` without a break. So a
  reading that dithers around a threshold escalates once and never flaps.
- The state stream: no sample for `stale_s` (node time) after one was seen is STOP ("state stream
  lost"); with `require_state`, no sample yet is STOP too. It clears like the readings (after
  `clear_s` of fresh samples).
- A reading that is not a number (NaN, inf) is STOP for that reading: a sensor we cannot read is not
  a healthy one.
- An input never raises a limit: the speed scale is 1 at OK and WARN, `cap_scale` (<= 1) at CAP, 0
  at STOP and DOWN.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum

from go2vlm.declare import param

__all__ = [
    "BATTERY_PCT",
    "MOTOR_TEMP_C",
    "TILT_DEG",
    "HealthMonitor",
    "HealthPolicy",
    "HealthSample",
    "HealthVerdict",
    "Ladder",
    "Level",
]


class Level(IntEnum):
    OK = 0
    WARN = 1
    CAP = 2
    STOP = 3
    DOWN = 4

    @property
    def action(self) -> str:
        return ("ok", "warn", "cap speed", "stop", "down (e-stop: Damp)")[self]


@dataclass(frozen=True)
class Ladder:
    """Thresholds for one reading: warn, cap, stop, down. `rising`: a higher reading is worse (a
    temperature); else a lower one is (a battery)."""

    warn: float
    cap: float
    stop: float
    down: float
    hysteresis: float
    rising: bool = True

    def __post_init__(self) -> None:
        steps = self.steps
        if not all(math.isfinite(x) for x in (*steps, self.hysteresis)) or self.hysteresis < 0:
            raise ValueError(f"thresholds and hysteresis must be finite (hysteresis >= 0): {self}")
        ordered = steps if self.rising else tuple(-x for x in steps)
        if any(b <= a for a, b in zip(ordered, ordered[1:], strict=False)):
            order = "increase" if self.rising else "decrease"
            raise ValueError(f"thresholds warn, cap, stop, down must {order} strictly, got {list(steps)}")

    @property
    def steps(self) -> tuple[float, float, float, float]:
        return (self.warn, self.cap, self.stop, self.down)

    def demand(self, x: float, margin: float = 0.0) -> Level:
        """The level reading `x` reaches, with every threshold moved `margin` towards the healthy side."""
        level = Level.OK
        for lvl, th in zip((Level.WARN, Level.CAP, Level.STOP, Level.DOWN), self.steps, strict=True):
            if (x >= th - margin) if self.rising else (x <= th + margin):
                level = lvl
        return level

    def target(self, x: float, current: Level) -> Level:
        """The level for reading `x` at `current`: up at once, and `current` kept within the hysteresis."""
        if not math.isfinite(x):
            return Level.STOP
        return max(self.demand(x), min(current, self.demand(x, self.hysteresis)))


# Defaults. Tilt: a walking Go2 pitches well under 15 deg on the slopes it is rated for; beyond 50 deg
# it is falling. Motor temperature: a logged Go2 standing still reads 72-78 deg C on its calf motors,
# so the ladder starts above that. Battery: state of charge in percent (the BMS's soc).
TILT_DEG = Ladder(warn=20.0, cap=25.0, stop=35.0, down=50.0, hysteresis=5.0)
MOTOR_TEMP_C = Ladder(warn=85.0, cap=95.0, stop=105.0, down=115.0, hysteresis=5.0)
BATTERY_PCT = Ladder(warn=20.0, cap=12.0, stop=6.0, down=3.0, hysteresis=3.0, rising=False)


@dataclass(frozen=True)
class HealthPolicy:
    tilt_deg: Ladder = TILT_DEG
    motor_temp_c: Ladder = MOTOR_TEMP_C
    battery_pct: Ladder = BATTERY_PCT
    # Declared with `param`: the safety gate's parameters too (health_stale_s, ...; read-only).
    stale_s: float = param(0.5, help="state stream silent this long: stop", min=0.05, max=10.0)
    clear_s: float = param(2.0, help="a lower health level is taken after it held this long", min=0.0)
    cap_scale: float = param(0.5, help="speed limits factor at health level cap", min=0.0, max=1.0)
    require_state: bool = param(False, help="stop until the first state sample (else armed by it)")

    def __post_init__(self) -> None:
        for name in ("stale_s", "clear_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v}")
        if not (math.isfinite(self.cap_scale) and 0.0 <= self.cap_scale <= 1.0):
            raise ValueError(f"cap_scale must be in [0, 1], got {self.cap_scale}")


@dataclass(frozen=True)
class HealthSample:
    """One reading of the state stream (rt/lowstate): body tilt, motor temperatures, battery.
    `battery_pct` None: no battery reading in this sample (left as it was)."""

    roll_deg: float = 0.0
    pitch_deg: float = 0.0
    motor_temp_c: Sequence[float] = ()
    battery_pct: float | None = None

    @property
    def tilt_deg(self) -> float:
        return _worst((abs(self.roll_deg), abs(self.pitch_deg)))

    @property
    def hottest_c(self) -> float:
        return _worst(self.motor_temp_c)


def _worst(values: Sequence[float]) -> float:
    """The largest value; NaN when any value is not finite (max() would skip a NaN)."""
    if not all(math.isfinite(v) for v in values):
        return math.nan
    return max(values, default=0.0)


@dataclass(frozen=True)
class HealthVerdict:
    level: Level
    speed_scale: float  # multiplies the gate's speed limits: 1, cap_scale or 0
    reasons: tuple[str, ...]  # one per reading at WARN or above, worst first

    @property
    def hold(self) -> str | None:
        """Why /cmd_vel must be zero, or None."""
        return f"health: {'; '.join(self.reasons)}" if self.level >= Level.STOP else None


@dataclass
class _Track:
    """One reading's level: up at once, down only after the lower target held for clear_s."""

    level: Level = Level.OK
    target: Level = Level.OK
    lower_since: float | None = None
    detail: str = ""

    def set(self, target: Level, now: float, clear_s: float, detail: str) -> None:
        self.target, self.detail = target, detail
        if target >= self.level:
            self.level, self.lower_since = target, None
        elif self.lower_since is None:
            self.lower_since = now
        self.settle(now, clear_s)

    def settle(self, now: float, clear_s: float) -> None:
        if self.lower_since is not None and now - self.lower_since >= clear_s:
            self.level, self.lower_since = self.target, None


@dataclass
class HealthMonitor:
    policy: HealthPolicy = field(default_factory=HealthPolicy)

    def __post_init__(self) -> None:
        self.tracks = {name: _Track() for name in ("stream", "tilt", "motor_temp", "battery")}
        self.last_sample_t: float | None = None
        self.last: HealthSample | None = None
        self.counters: dict[str, int] = {}

    def observe(self, sample: HealthSample, now: float) -> None:
        """A state sample received at `now` (node time)."""
        p = self.policy
        self.last_sample_t, self.last = now, sample
        self.counters["samples"] = self.counters.get("samples", 0) + 1
        self._set("stream", Level.OK, now, "")
        t = self.tracks
        tilt = sample.tilt_deg
        self._set("tilt", p.tilt_deg.target(tilt, t["tilt"].level), now, f"tilt {tilt:.1f} deg")
        hot = sample.hottest_c
        self._set("motor_temp", p.motor_temp_c.target(hot, t["motor_temp"].level), now, f"motor {hot:.0f} C")
        if sample.battery_pct is not None:
            pct = sample.battery_pct
            self._set("battery", p.battery_pct.target(pct, t["battery"].level), now, f"battery {pct:.0f} %")

    def _set(self, name: str, target: Level, now: float, detail: str) -> None:
        self.tracks[name].set(target, now, self.policy.clear_s, detail)

    def verdict(self, now: float) -> HealthVerdict:
        """The verdict at `now`: staleness and pending de-escalations are applied here."""
        p = self.policy
        if self.last_sample_t is None:
            if p.require_state:
                self._set("stream", Level.STOP, now, "no state sample yet")
        else:
            age = now - self.last_sample_t
            if age > p.stale_s:
                self._set("stream", Level.STOP, now, f"state stream lost ({age:.1f} s)")
        for track in self.tracks.values():
            track.settle(now, p.clear_s)
        level = max(t.level for t in self.tracks.values())
        scale = 1.0 if level <= Level.WARN else p.cap_scale if level == Level.CAP else 0.0
        worst = sorted((t for t in self.tracks.values() if t.level >= Level.WARN), key=lambda t: -t.level)
        reasons = tuple(f"{t.detail} ({t.level.name.lower()})" for t in worst)
        return HealthVerdict(level, scale, reasons)

    def status(self) -> dict[str, object]:
        """The readings and each track's level, for /safety/status."""
        s = self.last
        return {
            "levels": {name: t.level.name.lower() for name, t in self.tracks.items()},
            "tilt_deg": None if s is None else round(s.tilt_deg, 1),
            "motor_temp_max_c": None if s is None else s.hottest_c,
            "battery_pct": None if s is None else s.battery_pct,
            "samples": self.counters.get("samples", 0),
        }
