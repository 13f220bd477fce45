"""Velocity limits, pure and deterministic.

The hard ceilings are the commanded robot's own velocity range (its profile's `ceilings`, e.g. the
Go2 sport-mode Move() range; robot_profile/). Configured limits can only be lower: `Limits` clamps
every configured value to its `ceiling`, whatever it is given. Only vx, vy and wz are ever commanded;
the other Twist components are not something a walking robot can do and are always output as zero.

Acceleration limits apply when a component speeds up (or reverses); slowing down towards zero is
never limited, so a stop is always immediate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from go2vlm.declare import param
from go2vlm.robot_profile import CEILING_BOUND, DEFAULT_ROBOT, PROFILES, SpeedCeilings

__all__ = ["ABSURD", "ZERO", "Limits", "Velocity"]

# A component beyond this is garbage (unit mix-up, uninitialised memory), not a fast command.
ABSURD = 100.0


@dataclass(frozen=True)
class Velocity:
    vx: float = 0.0
    vy: float = 0.0
    wz: float = 0.0

    @property
    def is_zero(self) -> bool:
        return self.vx == 0.0 and self.vy == 0.0 and self.wz == 0.0

    def as_dict(self) -> dict[str, float]:
        return {"vx": self.vx, "vy": self.vy, "wz": self.wz}


ZERO = Velocity()


def _limit(value: float, ceiling: float) -> float:
    """A configured limit, never negative, never above the ceiling, NaN treated as 0."""
    if not math.isfinite(value) and value != math.inf:
        return 0.0
    return max(0.0, min(float(value), ceiling))


@dataclass(frozen=True)
class Limits:
    """Velocity and acceleration limits; declared with `param`, they are the safety gate's parameters
    too (the gate's names: max_vx_forward, ...; live: they may be lowered while it runs)."""

    # Above 0.5 m/s only where the guard's stopping envelope holds: it scales every command to that.
    vx_forward: float = param(
        1.0, help="forward speed limit (m/s)", min=0.0, max=CEILING_BOUND.vx_forward, live=True, bound="max"
    )
    vx_backward: float = param(
        0.5, help="backward speed limit (m/s, positive)", min=0.0, max=CEILING_BOUND.vx_backward, live=True, bound="max"
    )
    vy: float = param(0.5, help="sideways speed limit (m/s)", min=0.0, max=CEILING_BOUND.vy, live=True, bound="max")
    wz: float = param(1.0, help="yaw rate limit (rad/s)", min=0.0, max=CEILING_BOUND.vyaw, live=True, bound="max")
    accel_linear: float = param(
        1.0, help="linear acceleration limit (m/s^2); braking is not limited", min=0.01, live=True, bound="max"
    )
    accel_angular: float = param(3.0, help="angular acceleration limit (rad/s^2)", min=0.01, live=True, bound="max")
    ceiling: SpeedCeilings = PROFILES[DEFAULT_ROBOT].ceilings  # the commanded robot's own range

    def __post_init__(self) -> None:
        # Frozen dataclass: clamp through object.__setattr__ so no Limits can exceed the ceilings.
        c = self.ceiling
        object.__setattr__(self, "vx_forward", _limit(self.vx_forward, c.vx_forward))
        object.__setattr__(self, "vx_backward", _limit(self.vx_backward, c.vx_backward))
        object.__setattr__(self, "vy", _limit(self.vy, c.vy))
        object.__setattr__(self, "wz", _limit(self.wz, c.vyaw))
        object.__setattr__(self, "accel_linear", _limit(self.accel_linear, 1e6))
        object.__setattr__(self, "accel_angular", _limit(self.accel_angular, 1e6))

    def scaled(self, factor: float) -> Limits:
        """The speed limits times `factor` in [0, 1] (degraded control); acceleration limits unchanged."""
        if factor >= 1.0:
            return self
        f = max(0.0, factor) if math.isfinite(factor) else 0.0
        return Limits(
            self.vx_forward * f,
            self.vx_backward * f,
            self.vy * f,
            self.wz * f,
            self.accel_linear,
            self.accel_angular,
            self.ceiling,
        )

    def clamp(self, v: Velocity) -> Velocity:
        return Velocity(
            vx=max(-self.vx_backward, min(self.vx_forward, v.vx)),
            vy=max(-self.vy, min(self.vy, v.vy)),
            wz=max(-self.wz, min(self.wz, v.wz)),
        )

    def within(self, v: Velocity) -> bool:
        return -self.vx_backward <= v.vx <= self.vx_forward and abs(v.vy) <= self.vy and abs(v.wz) <= self.wz


def check(v: Velocity) -> str | None:
    """Why a commanded velocity must be rejected, or None when it is usable (possibly after clamping)."""
    for name, value in (("linear.x", v.vx), ("linear.y", v.vy), ("angular.z", v.wz)):
        if not math.isfinite(value):
            return f"{name} is {value}"
        if abs(value) > ABSURD:
            return f"{name} = {value:g} is absurd (|v| > {ABSURD:g})"
    return None


def _ramp1(cur: float, tgt: float, max_delta: float) -> float:
    if tgt == 0.0:
        return 0.0
    same_side = (cur > 0.0) == (tgt > 0.0) and cur != 0.0
    if same_side and abs(tgt) <= abs(cur):
        return tgt  # slowing down: never limited
    base = cur if same_side else 0.0  # reversing: brake to zero at once, then accelerate
    if abs(tgt - base) <= max_delta:
        return tgt
    return base + math.copysign(max_delta, tgt - base)


def ramp(cur: Velocity, tgt: Velocity, limits: Limits, dt: float) -> Velocity:
    """One output step from `cur` towards `tgt` within the acceleration limits over `dt` seconds."""
    dt = max(0.0, dt)
    dl, da = limits.accel_linear * dt, limits.accel_angular * dt
    return Velocity(vx=_ramp1(cur.vx, tgt.vx, dl), vy=_ramp1(cur.vy, tgt.vy, dl), wz=_ramp1(cur.wz, tgt.wz, da))
