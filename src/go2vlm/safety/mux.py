"""The safety gate's logic without any I/O: a twist_mux-style priority mux, the e-stop latch and the
velocity limits, driven by explicit timestamps so it can be tested exhaustively.

    core = SafetyCore([InputSpec("teleop", "/teleop/cmd_vel", 100)], Limits())
    core.command("teleop", Velocity(0.3, 0, 0), now)
    out = core.step(now)          # what goes on /cmd_vel
    core.command("teleop", v, now, wall)   # on sim time: `now` is sim time, `wall` a steady wall clock
    out = core.step(now, wall)

Rules
- An input is live while its last valid command is younger than its timeout. The live input with the
  highest priority wins (ties: the one listed first), even when it commands zero.
- Two clocks (the gate on sim time, `wall` given): an input is also absent once its last valid
  command is `wall_timeout_s` of wall time old, and while the node clock has not advanced for
  `wall_timeout_s` of wall time (a stalled /clock) the output is zero whatever the inputs say: sim
  time that stands still can age nothing, so a frozen clock must not keep the last command alive.
  With one clock (`wall` None, the gate on wall time) neither applies: `now` is the wall clock.
- A command with NaN/inf or absurd values is rejected, counted, and makes that input absent at once.
- E-stop: `estop(True)` latches; while latched the output is exactly zero. `estop(False)` does NOT
  release it; only `release(token)` with the configured token does.
- Block: `block(reason)` holds the output at zero (another writer drives /cmd_vel, see
  safety/commander.py) until `block(None)`; then the output ramps up again from zero.
- Health (safety/health.py): `health(scale, hold)` scales the speed limits by `scale` (never above
  1: an input never raises a limit) and, with a `hold` reason, holds the output at zero like a block.
- The output is the winner clamped to the limits, then ramped within the acceleration limits, then
  scaled down by the collision guard (`guard`, safety/guard.py: stop short of obstacles, a speed cap
  without a fresh scan; off unless given one); zero (no live input, e-stop, block) is output
  immediately.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from go2vlm.bus.topics import BEHAVIOR_CMD_VEL, FOLLOWER_CMD_VEL, TELEOP_CMD_VEL
from go2vlm.safety.estop import RELEASE_TOKEN, EstopLatch
from go2vlm.safety.guard import CollisionGuard
from go2vlm.safety.limits import ZERO, Limits, Velocity, check, ramp

__all__ = ["InputSpec", "SafetyCore", "DEFAULT_INPUTS"]

MAX_DT = 0.1  # a stalled loop must not turn into one big acceleration step
DEFAULT_WALL_TIMEOUT_S = 2.0  # the wall-clock bound on a sim-time gate (see the rules above)


@dataclass(frozen=True)
class InputSpec:
    name: str
    topic: str
    priority: int
    timeout_s: float = 0.5


DEFAULT_INPUTS = (
    InputSpec("teleop", TELEOP_CMD_VEL.name, 100, 0.5),
    InputSpec("follower", FOLLOWER_CMD_VEL.name, 50, 0.5),
    InputSpec("behavior", BEHAVIOR_CMD_VEL.name, 10, 0.5),
)


@dataclass
class _Input:
    spec: InputSpec
    last: Velocity = ZERO
    t: float | None = None  # time of the last valid command; None = absent
    wall: float | None = None  # its wall time, when the core runs on two clocks
    why_absent: str = ""

    def live(self, now: float, wall: float | None = None, wall_timeout: float = math.inf) -> bool:
        if self.t is None or not 0.0 <= now - self.t < self.spec.timeout_s:
            return False
        return wall is None or self.wall is None or 0.0 <= wall - self.wall < wall_timeout


@dataclass
class SafetyCore:
    specs: list[InputSpec] | tuple[InputSpec, ...] = DEFAULT_INPUTS
    limits: Limits = field(default_factory=Limits)
    release_token: str = RELEASE_TOKEN
    engaged: bool = False  # start with the e-stop latched
    wall_timeout_s: float = DEFAULT_WALL_TIMEOUT_S  # used only when `wall` times are given
    guard: CollisionGuard = field(default_factory=lambda: CollisionGuard(enabled=False))

    def __post_init__(self) -> None:
        if not (math.isfinite(self.wall_timeout_s) and self.wall_timeout_s > 0):
            raise ValueError(f"wall_timeout_s must be positive, got {self.wall_timeout_s}")
        names = [s.name for s in self.specs]
        if len(set(names)) != len(names):
            raise ValueError(f"input names must be unique: {names}")
        for s in self.specs:
            if not (math.isfinite(s.timeout_s) and s.timeout_s > 0):
                raise ValueError(f"input {s.name!r}: timeout_s must be positive, got {s.timeout_s}")
        # Highest priority first; sorted() is stable, so ties keep their listed order.
        self._inputs = {s.name: _Input(s) for s in sorted(self.specs, key=lambda s: -s.priority)}
        self.latch = EstopLatch(self.release_token, self.engaged)
        self.output = ZERO
        self.active: str | None = None
        self.reason = "estop" if self.engaged else "no live input"
        self.blocked: str | None = None
        self.health_scale = 1.0  # the health verdict's factor on the speed limits
        self.health_hold: str | None = None  # the health verdict's reason to hold zero
        self._held = self.engaged  # the last step held zero for the e-stop, a block or a stalled clock
        self.counters: dict[str, int] = {}
        self._t_out: float | None = None
        self._clock_t: float | None = None  # the newest node-clock time seen ...
        self._clock_wall = 0.0  # ... and the wall time it was first seen at (stall detection)

    def _count(self, key: str) -> None:
        self.counters[key] = self.counters.get(key, 0) + 1

    # -- events ------------------------------------------------------------------------------
    def _observe(self, now: float, wall: float | None) -> None:
        if wall is not None and (self._clock_t is None or now > self._clock_t):
            self._clock_t, self._clock_wall = now, wall

    def clock_stalled(self, wall: float | None) -> bool:
        """Two clocks: the node clock has not advanced for wall_timeout_s of wall time."""
        return wall is not None and self._clock_t is not None and wall - self._clock_wall >= self.wall_timeout_s

    def command(self, name: str, v: Velocity, now: float, wall: float | None = None) -> str | None:
        """Store a command from input `name`; returns why it was rejected, or None."""
        self._observe(now, wall)
        inp = self._inputs[name]
        why = check(v)
        if why is not None:
            self._count(f"rejected_{name}")
            inp.t = None  # bad input counts as absent: never keep driving on the previous command
            inp.why_absent = f"{name} sent an invalid command"
            return why
        inp.last, inp.t, inp.wall, inp.why_absent = v, now, wall, ""
        return None

    def estop(self, flag: bool) -> None:
        if flag:
            if not self.latch.engaged:
                self._count("estops")
            self.latch.engage()
        else:
            self._count("estop_false_ignored")

    def block(self, reason: str | None) -> None:
        """Hold the output at zero for `reason`, or stop holding it (None)."""
        if reason and reason != self.blocked:
            self._count("blocks")
        self.blocked = reason or None

    def health(self, scale: float, hold: str | None) -> None:
        """Apply the health verdict: speed limits times `scale` (clamped to [0, 1]), zero while `hold`."""
        self.health_scale = min(1.0, max(0.0, scale)) if math.isfinite(scale) else 0.0
        if hold and hold != self.health_hold:
            self._count("health_stops")
        self.health_hold = hold or None

    def release(self, token: str) -> bool:
        ok = self.latch.release(token)
        self._count("releases" if ok else "release_refused")
        return ok

    @property
    def estopped(self) -> bool:
        return self.latch.engaged

    # -- output ------------------------------------------------------------------------------
    def winner(self, now: float, wall: float | None = None) -> str | None:
        if self.clock_stalled(wall):
            return None
        for name, inp in self._inputs.items():
            if inp.live(now, wall, self.wall_timeout_s):
                return name
        return None

    def step(self, now: float, wall: float | None = None) -> Velocity:
        """The output at time `now` (and wall time `wall` on two clocks)."""
        self._observe(now, wall)
        dt = 0.0 if self._t_out is None else min(max(now - self._t_out, 0.0), MAX_DT)
        self._t_out = now
        prev_active = self.active
        held = "estop" if self.latch.engaged else self.blocked or self.health_hold
        if not held and self.clock_stalled(wall):
            if self.reason != "clock stalled":
                self._count("clock_stalls")
            held = "clock stalled"
        if held:
            self.active = None
            self.output = ZERO
            self.reason = held
            self._held = True
            return ZERO
        was_held, self._held = self._held, False
        self.active = self.winner(now, wall)
        if self.active is None:
            if not self.output.is_zero or was_held:
                gone = self._inputs[prev_active] if prev_active else None
                self.reason = (gone.why_absent or f"{gone.spec.name} timed out") if gone else "no live input"
            self.output = ZERO
            return ZERO
        target = self.limits.scaled(self.health_scale).clamp(self._inputs[self.active].last)
        out = ramp(self.output, target, self.limits, dt)
        guarded = self.guard.limit(out, now, self.limits)  # only ever smaller: see safety/guard.py
        if guarded != out:
            self._count("guard_limited")
        if guarded.is_zero and not self.output.is_zero:
            self.reason = f"guard: {self.guard.state.reason}" if not out.is_zero else f"{self.active} commands zero"
        out = guarded
        self.output = out
        return out

    def inputs_status(self, now: float, wall: float | None = None) -> dict[str, dict[str, object]]:
        return {
            name: {
                "topic": inp.spec.topic,
                "priority": inp.spec.priority,
                "live": inp.live(now, wall, self.wall_timeout_s),
                "age_s": None if inp.t is None else round(now - inp.t, 3),
            }
            for name, inp in self._inputs.items()
        }
