"""safety: the only node that publishes /cmd_vel. A priority mux with timeouts, velocity and
acceleration limits, a collision guard over the range scan and a latching emergency stop, output at a
fixed rate.

Topics
  subscribes  /teleop/cmd_vel    geometry_msgs/Twist  priority 100  } default `inputs`: any list of
              /follower/cmd_vel  geometry_msgs/Twist  priority 50   } {name, topic, priority,
              /behavior/cmd_vel  geometry_msgs/Twist  priority 10   }  timeout_s} (0.5 s default)
              /emergency_stop          std_msgs/Bool    true latches the e-stop; false does NOT release
              /emergency_stop/release  std_msgs/String  data == release_token ("RELEASE"), exactly, releases
              /scan              sensor_msgs/LaserScan  best-effort (`scan_topic`): obstacles for the
                                 collision guard, frame base_link (sim, go2 driver: geometry/scan.py)
              /cmd_vel           geometry_msgs/Twist  best-effort, only to see who else writes it
              /safety/heartbeat  std_msgs/String      the other gates' heartbeats (latched)
              /lowstate          unitree_go/LowState  best-effort (`health_topic`, '' = the robot profile's:
                                 sim /lowstate, go2 /go2/lowstate): the robot's health (tilt from
                                 imu_state.rpy, motor_state[].temperature, bms_state.soc) and stream loss
  publishes   /cmd_vel           geometry_msgs/Twist  at rate_hz (50 Hz), exactly zero when no input is
                                 live, the e-stop is latched or another writer is on /cmd_vel; a stop
                                 goes out at once
              /safety/status     std_msgs/String (latched) JSON {robot, active, estop, estop_since, estop_why,
                                 last_zero_reason, output, limits, guard, inputs, commander,
                                 estop_state_file, counters, health}, on every
                                 change and every status_period_s; guard = {mode: clear | limited |
                                 blind | off, reason, scale, nearest_m, scan_age_s, margin_m}
              /safety/heartbeat  std_msgs/String (latched) JSON {node, participant, cmd_vel_writer, topic}:
                                 this gate's /cmd_vel writer, every status_period_s (safety/commander.py)
              /emergency_stop    std_msgs/Bool (reliable, volatile) true, only at health level "down"
                                 (repeated every status_period_s while it lasts): the robot ends Damp

E-stop from a shell (cli/estop.py; it holds the latched e-stop until the release):
  go2vlm estop              # latch, and keep it latched for nodes that start later
  go2vlm estop --release    # the deliberate release; waits until the gates and robots report it

The robot (`robot`, a profile of robot_profile/: sim, go2): the gate holds every speed limit under
that robot's own ceilings, its collision guard sweeps that robot's footprint, and its health input is
that robot's health topic.
E-stop across restarts: the latch belongs to the robot. Every change of it is written atomically to
estop_state_file (default $XDG_STATE_HOME/go2vlm/estop/<robot>-domain<N>.json, ~/.local/state/...
without XDG_STATE_HOME): one file per robot and DDS domain, shared by every gate that commands that
robot there whatever its node name. A gate that went down latched (even kill -9) comes up latched,
so does a replacement under another --name, and a file it cannot read counts as latched; `go2vlm
demo` and `go2vlm eval` refuse to start on a latched robot.
One commander: any other writer on /cmd_vel (another gate, a raw publisher) holds the output at zero
and is named in /safety/status "commander" and in the log (safety/commander.py).
Rules: the live input with the highest priority wins, even when it commands zero; an input is live
while its last valid command is younger than its timeout_s. A command with NaN/inf or absurd values
(|v| > 100) is rejected with a rate-limited error, counted, and makes that input absent at once.
The winner is clamped to the limits (configurable, never above the robot's ceilings; a Go2's are
its sport-mode range vx -2.5..3.8 m/s, vy +-1.0 m/s, vyaw +-4.0 rad/s) and ramped within the
acceleration limits; slowing down and stopping are never ramped. Only linear.x, linear.y and angular.z are passed on.
Health (safety/health.py, docs/safety.md): with `health` on, every /lowstate sample feeds a monitor
whose verdict escalates warn -> cap speed (limits x health_cap_scale) -> stop (/cmd_vel zero) ->
down (the e-stop latches: Damp; the release is a deliberate act) on tilt, the hottest motor, the
battery, or a /lowstate stream that went silent for health_stale_s (armed by its first sample, or
from the start with health_require_state). Thresholds: health_tilt_deg, health_motor_temp_c,
health_battery_pct = [warn, cap, stop, down]; a lower level only after health_clear_s. Every level
and its reasons are on /safety/status "health".

Collision guard (safety/guard.py, docs/safety.md#the-collision-guard; `guard: false` turns it off at
start-up only): the output is scaled down, never up, so that the robot, braking at accel_linear and
accel_angular after reaction_s, stops `margin` (0.1 m) + `margin_per_speed_s` (0.4 s) x the speed of
its fastest footprint point short of every obstacle on the scan (the clearance rule the planners keep
too: 0.3 m at 0.5 m/s, a few centimetres at a creep through a doorway) along the
arc it is commanded (forward, sideways, turning: the footprint sweeps); with no scan, a scan older than
scan_timeout_s (0.5 s) or a garbage one (NaN, -inf, no beams, another frame), no footprint point moves
faster than blind_speed (0.2 m/s). A rejected scan is logged (rate-limited) and counted.
Parameters at runtime: the speed and acceleration limits may be LOWERED while the gate runs (it
clamps from the next tick; slowing down is never ramped); raising one is refused, even below the Go2
ceiling: raising takes a restart, a deliberate act. status_period_s is live too; inputs, rate_hz,
release_token, start_engaged, wall_timeout_s and the guard's parameters are read-only.
QoS: inputs are read best-effort (matches any publisher); /emergency_stop is read three ways (latched,
reliable, best-effort) so every publisher QoS matches and a latched e-stop reaches a late gate.
Time (use_sim_time, bus/clock.py): timeouts, ramps and the output rate are in the node's time, sim
time on a sim. On sim time the gate also keeps a wall-clock bound, because sim time that stops
(a hung or killed sim, a paused /clock) ages nothing: an input silent for wall_timeout_s (2 s) of wall
time is absent, and once /clock has not advanced for wall_timeout_s of wall time the gate publishes
exactly zero /cmd_vel at rate_hz of wall time until it advances again (reason "clock stalled"), so
that a robot, a bridge or a tool that is not on sim time hears an explicit stop rather than the last
command or silence. Before the first /clock the sim-time ticks wait; the same bound then applies.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from go2vlm.bus import QOS_ANY, Node, core_params, core_values, from_core, param
from go2vlm.bus.domain import dds_topic_name
from go2vlm.bus.topics import CMD_VEL, EMERGENCY_STOP, LOWSTATE, SAFETY_STATUS, SCAN
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.sensor_msgs import LaserScan
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.msgs.unitree import LowState
from go2vlm.robot_profile import DEFAULT_ROBOT, PROFILES, RobotProfile, profile
from go2vlm.safety.commander import GateWatch
from go2vlm.safety.estop import (
    RELEASE_TOKEN,
    EstopInput,
    LatchFile,
    check_token,
    latch_path,
    parse_stamp,
    stamp_text,
)
from go2vlm.safety.guard import CollisionGuard, GuardConfig, Scan
from go2vlm.safety.health import (
    BATTERY_PCT,
    MOTOR_TEMP_C,
    TILT_DEG,
    HealthMonitor,
    HealthPolicy,
    HealthSample,
    HealthVerdict,
    Ladder,
    Level,
)
from go2vlm.safety.limits import ZERO, Limits, Velocity
from go2vlm.safety.mux import DEFAULT_INPUTS, DEFAULT_WALL_TIMEOUT_S, InputSpec, SafetyCore

__all__ = ["SafetyGateConfig", "SafetyGateNode", "gate_latch_path", "parse_inputs"]

LOG_PERIOD_S = 1.0  # at most one state-change INFO line per second
# The parameters the pure cores share (limits, guard, health) are declared on their fields (from_core).
_INPUT_TIMEOUT_S = InputSpec.timeout_s


def parse_inputs(raw: list[dict[str, Any]]) -> list[InputSpec]:
    """`inputs` parameter entries -> InputSpec, with errors that name the entry."""
    out = []
    for i, item in enumerate(raw):
        if not isinstance(item, dict) or "topic" not in item:
            raise ValueError(f"inputs[{i}] = {item!r}: expected {{name, topic, priority, timeout_s}}")
        unknown = set(item) - {"name", "topic", "priority", "timeout_s"}
        if unknown:
            raise ValueError(f"inputs[{i}]: unknown key(s) {sorted(unknown)}")
        topic = str(item["topic"])
        dds_topic_name(topic)  # raises on a bad name
        name = str(item.get("name") or topic.strip("/").split("/")[0])
        try:
            priority = int(item.get("priority", 0))
            timeout = float(item.get("timeout_s", _INPUT_TIMEOUT_S))
        except (TypeError, ValueError):
            raise ValueError(f"inputs[{i}]: priority must be an int and timeout_s a number") from None
        if not (math.isfinite(timeout) and 0.0 < timeout <= 10.0):
            raise ValueError(f"inputs[{i}]: timeout_s {timeout} must be in (0, 10]")
        out.append(InputSpec(name, topic, priority, timeout))
    if not out:
        raise ValueError("inputs must list at least one input topic")
    names = [s.name for s in out]
    if len(set(names)) != len(names):
        raise ValueError(f"inputs: names must be unique, got {names}")
    if CMD_VEL.name in {s.topic for s in out}:
        raise ValueError(f"inputs: {CMD_VEL.name} is the gate's output and cannot be an input")
    return out


@dataclass
class SafetyGateConfig:
    robot: str = param(
        DEFAULT_ROBOT,
        help="the robot this gate commands (its profile: speed ceilings, footprint, health topic; its e-stop latch)",
        choices=tuple(PROFILES),
    )
    inputs: list[dict[str, Any]] = param(
        [{"name": s.name, "topic": s.topic, "priority": s.priority, "timeout_s": s.timeout_s} for s in DEFAULT_INPUTS],
        help="input topics: [{name, topic, priority, timeout_s}], higher priority wins",
    )
    rate_hz: float = param(50.0, help="fixed /cmd_vel output rate", min=20.0, max=500.0)
    max_vx_forward: float = from_core(Limits, "vx_forward")
    max_vx_backward: float = from_core(Limits, "vx_backward")
    max_vy: float = from_core(Limits, "vy")
    max_vyaw: float = from_core(Limits, "wz")
    accel_linear: float = from_core(Limits, "accel_linear")
    accel_angular: float = from_core(Limits, "accel_angular")
    release_token: str = param(
        RELEASE_TOKEN, help="the /emergency_stop/release text that releases the e-stop (exact match)"
    )
    start_engaged: bool = param(False, help="start with the e-stop latched (a release is needed to move)")
    estop_state_file: str = param(
        "",
        help="where the e-stop latch survives restarts; '' = the robot's, $XDG_STATE_HOME (~/.local/state)"
        "/go2vlm/estop/<robot>-domain<N>.json",
    )
    status_period_s: float = param(1.0, help="/safety/status period besides on-change", min=0.5, max=10.0, live=True)
    wall_timeout_s: float = param(
        DEFAULT_WALL_TIMEOUT_S,
        help="on sim time: an input silent this many wall seconds is absent, and a /clock that stands "
        "still this long makes /cmd_vel zero at rate_hz of wall time",
        min=0.1,
        max=60.0,
    )

    health: bool = param(True, help="watch the robot's health on health_topic (tilt, motors, battery, stream)")
    health_topic: str = param(
        "", help="unitree_go/msg/LowState topic of the robot's state; '' = the robot profile's health topic"
    )
    health_require_state: bool = from_core(HealthPolicy, "require_state")
    health_stale_s: float = from_core(HealthPolicy, "stale_s")
    health_clear_s: float = from_core(HealthPolicy, "clear_s")
    health_cap_scale: float = from_core(HealthPolicy, "cap_scale")
    health_tilt_deg: list[float] = param(
        list(TILT_DEG.steps), help="max(|roll|, |pitch|) thresholds [warn, cap, stop, down], degrees"
    )
    health_motor_temp_c: list[float] = param(
        list(MOTOR_TEMP_C.steps), help="hottest motor thresholds [warn, cap, stop, down], deg C"
    )
    health_battery_pct: list[float] = param(
        list(BATTERY_PCT.steps), help="battery state-of-charge thresholds [warn, cap, stop, down], percent"
    )
    guard: bool = param(True, help="the collision guard over scan_topic (false: no obstacle check, no blind cap)")
    scan_topic: str = param(SCAN.name, help="sensor_msgs/LaserScan in base_link for the collision guard")
    margin: float = from_core(GuardConfig, "margin")
    margin_per_speed_s: float = from_core(GuardConfig, "margin_per_speed_s")
    blind_speed: float = from_core(GuardConfig, "blind_speed")
    scan_timeout_s: float = from_core(GuardConfig, "scan_timeout_s")
    reaction_s: float = from_core(GuardConfig, "reaction_s")

    def validate(self) -> None:
        dds_topic_name(self.scan_topic)
        parse_inputs(self.inputs)
        check_token(self.release_token)
        dds_topic_name(self.health_topic or LOWSTATE.name)
        health_policy(self)
        c = profile(self.robot).ceilings
        for name, ceiling in (
            ("max_vx_forward", c.vx_forward),
            ("max_vx_backward", c.vx_backward),
            ("max_vy", c.vy),
            ("max_vyaw", c.vyaw),
        ):
            if getattr(self, name) > ceiling:
                raise ValueError(f"{name} {getattr(self, name):g} is above robot {self.robot!r}'s ceiling {ceiling:g}")

    @property
    def robot_profile(self) -> RobotProfile:
        return profile(self.robot)

    @property
    def health_input(self) -> str:
        """The topic the health monitor reads: `health_topic`, else the robot's."""
        return self.health_topic or self.robot_profile.health_topic


def gate_latch_path(c: SafetyGateConfig, domain_id: int) -> Path:
    """Where a gate with this configuration keeps its e-stop latch on `domain_id`."""
    return Path(c.estop_state_file) if c.estop_state_file else latch_path(c.robot, domain_id)


def health_policy(c: SafetyGateConfig) -> HealthPolicy:
    """The monitor's policy from the parameters (hysteresis per reading as in safety/health.py)."""
    ladders = {}
    for name, base in (("tilt_deg", TILT_DEG), ("motor_temp_c", MOTOR_TEMP_C), ("battery_pct", BATTERY_PCT)):
        steps = getattr(c, f"health_{name}")
        if len(steps) != 4:
            raise ValueError(f"health_{name}: expected [warn, cap, stop, down], got {steps}")
        try:
            warn, cap, stop, down = map(float, steps)
            ladders[name] = Ladder(warn, cap, stop, down, hysteresis=base.hysteresis, rising=base.rising)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"health_{name}: {exc}") from None
    return core_params(HealthPolicy, c, **ladders, clear_s=max(c.health_clear_s, 1e-3))


def limits_of(c: SafetyGateConfig) -> Limits:
    return core_params(Limits, c, ceiling=c.robot_profile.ceilings)


class SafetyGateNode(Node):
    name = "safety"
    Config = SafetyGateConfig

    def __init__(self, config: SafetyGateConfig | None = None, **kwargs: object) -> None:
        super().__init__(config, **kwargs)  # type: ignore[arg-type]
        c = self.config
        self.store = LatchFile(gate_latch_path(c, self.domain_id))
        was_engaged, note = self.store.load()
        stored = self.store.read() if was_engaged else None
        self.core = SafetyCore(
            parse_inputs(c.inputs),
            limits_of(c),
            c.release_token,
            c.start_engaged or bool(was_engaged),
            c.wall_timeout_s,
            CollisionGuard(
                GuardConfig.of(c.robot_profile, **core_values(GuardConfig, c)),
                enabled=c.guard,
            ),
        )
        if stored is not None:  # the latch as it was stored: since when, and why
            self.core.latch.since = parse_stamp(stored.since) or self.core.latch.since
            self.core.latch.why = f"{stored.why or note} (restored from {self.store.path})"
        elif c.start_engaged:
            self.core.latch.why = "start_engaged"
        self.cmd_pub = CMD_VEL.publisher(self)
        self.status_pub = SAFETY_STATUS.publisher(self)
        self._last_state: tuple[Any, ...] | None = None
        self._last_status = 0.0
        self._state_changes = 0  # logged at most once per LOG_PERIOD_S (alternating bad input flips state)
        self._last_state_log = -math.inf
        # The e-stop first: each executor pass takes it before the inputs (a stop is never queued behind them).
        self.estop = EstopInput(
            self,
            self.core.latch,
            held="/cmd_vel held at zero",
            on_engage=self.tick,
            on_release=self.tick,
            store=self.store,
        )
        for spec in self.core.specs:
            # Best-effort: an input is heard whatever QoS its sender picked.
            CMD_VEL.subscription(self, lambda m, n=spec.name: self.on_cmd(n, m), name=spec.topic, qos=QOS_ANY)
        if c.guard:
            SCAN.subscription(self, self.on_scan, name=c.scan_topic)
        self.commander = GateWatch(self, str(self.cmd_pub.guid), self.cmd_pub.topic, self._commander_changed)
        self.health = HealthMonitor(health_policy(c)) if c.health else None
        self.verdict = HealthVerdict(Level.OK, 1.0, ())
        self._down_sent = -math.inf
        if self.health is not None:
            self.estop_pub = EMERGENCY_STOP.publisher(self)
            LOWSTATE.subscription(self, self.on_lowstate, name=c.health_input)
        if was_engaged:
            self.log.warning(f"the e-stop was latched when this gate went down: {note}")
        if self.core.estopped:
            self.log.warning(
                f"starting with the e-stop latched; `go2vlm estop --release` (or {c.release_token!r} on "
                "/emergency_stop/release) releases it"
            )
            self.estop.persist()
        self.create_timer(1.0 / c.rate_hz, self.tick)
        if self.clock.sim:
            self.create_timer(1.0 / c.rate_hz, self._stall_watchdog, wall=True)
        self.tick()

    # -- parameters at runtime: the limits go down, never up (declared bound="max" on Limits; the
    # parameter service refuses a raise for every node, bus/params.py `loosened`) ------------------
    def on_params_changed(self, old: SafetyGateConfig, changed: frozenset[str]) -> None:
        self.core.limits = limits_of(self.config)

    def _times(self) -> tuple[float, float | None]:
        """(node time, wall time): the wall reading bounds a sim clock (see the contract); None on wall time."""
        return self.clock.monotonic(), (time.monotonic() if self.clock.sim else None)

    def _commander_changed(self) -> None:
        was = self.core.blocked
        self.core.block(self.commander.blocked)
        if self.core.blocked != was:
            self.tick()  # a block goes out now

    def _stall_watchdog(self) -> None:
        if self.core.clock_stalled(time.monotonic()):  # wall time: the bound on a stalled sim clock
            self.tick()

    # -- inputs ------------------------------------------------------------------------------
    def on_cmd(self, name: str, msg: Twist) -> None:
        now, wall = self._times()
        was_active = self.core.winner(now, wall) == name
        extra = (msg.linear.z, msg.angular.x, msg.angular.y)
        v = Velocity(msg.linear.x, msg.linear.y, msg.angular.z)
        why = self.core.command(name, v, now, wall)
        if why is None and not all(math.isfinite(e) for e in extra):
            self.core.command(name, Velocity(math.nan), now, wall)  # reject and make absent the same way
            why = f"a non-finite unused component in {extra}"
        if why is not None:
            n = self.core.counters.get(f"rejected_{name}", 0)
            self.log.throttled("error", 2.0, f"rejecting a command from {name} ({n} so far): {why}", key=f"rej:{name}")
        if was_active and (why is not None or v.is_zero) and not self.core.output.is_zero:
            self.tick()  # a stop goes out now, not at the next tick

    # -- health ------------------------------------------------------------------------------
    def on_lowstate(self, msg: LowState) -> None:
        if self.health is None:
            return
        rpy = msg.imu_state.rpy
        bms = msg.bms_state
        # soc 0 with no pack voltage is a robot that reports no battery, not an empty one
        battery = None if bms.soc == 0 and msg.power_v == 0.0 else float(bms.soc)
        temps = tuple(float(m.temperature) for m in msg.motor_state)
        sample = HealthSample(math.degrees(rpy[0]), math.degrees(rpy[1]), temps, battery)
        now = self.clock.monotonic()
        before = self.verdict.level
        self.health.observe(sample, now)
        if self.health.verdict(now).level > before:
            self.tick()  # an escalation goes out now

    def _apply_health(self, now: float) -> None:
        if self.health is None:
            return
        v = self.health.verdict(now)
        if v.level != self.verdict.level:
            log = self.log.warning if v.level > self.verdict.level else self.log.info
            why = "; ".join(v.reasons) or "all readings healthy"
            log(f"health {self.verdict.level.name.lower()} -> {v.level.name.lower()} ({v.level.action}): {why}")
            self.count(f"health_{v.level.name.lower()}")
        self.verdict = v
        self.core.health(v.speed_scale, v.hold)
        if v.level >= Level.DOWN:
            if not self.core.estopped:
                self.estop.engage(f"health: {'; '.join(v.reasons)}", notify=False)  # this tick applies it
            if now - self._down_sent >= self.config.status_period_s:
                self._down_sent = now
                self.estop_pub.publish(Bool(data=True))  # the robot ends latch too and Damp

    def on_scan(self, msg: LaserScan) -> None:
        scan = Scan(msg.header.frame_id, msg.ranges, msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max)
        why = self.core.guard.scan(scan, self.clock.monotonic())
        if why is not None:
            n = self.core.guard.counters.get("scans_rejected", 0)
            self.log.throttled("error", 2.0, f"rejecting a scan on {self.config.scan_topic} ({n} so far): {why}")

    # -- output ------------------------------------------------------------------------------
    def tick(self) -> None:
        now, wall = self._times()
        self._apply_health(now)
        out = self.core.step(now, wall)
        if self.core.active is None:  # keep the guard's state (blind or not) current for /safety/status while idle
            self.core.guard.limit(ZERO, now, self.core.limits)
        self.cmd_pub.publish(Twist(linear=Vector3(x=out.vx, y=out.vy), angular=Vector3(z=out.wz)))
        state = (self.core.active, self.core.estopped, self.core.reason, self.verdict.level, self.core.guard.state.mode)
        if state != self._last_state or now - self._last_status >= self.config.status_period_s:
            if state != self._last_state and self._last_state is not None:
                self._state_changes += 1
            if now - self._last_status >= self.config.status_period_s:
                self.commander.beat()
            self._last_state, self._last_status = state, now
            self.status_pub.publish(String(data=json.dumps(self.status(now, wall))))
        if self._state_changes:
            self._log_state(state)

    def _log_state(self, state: tuple[Any, ...]) -> None:
        """The state after a change, at most once per LOG_PERIOD_S of wall time: input that flips the
        state at the tick rate (alternating NaN and valid commands) must not flood the console. The
        line counts the changes it stands for and comes at the latest LOG_PERIOD_S after the last
        one; /safety/status has every change."""
        t = time.monotonic()  # wall time: the console's rate, whatever the node's clock
        if t - self._last_state_log < LOG_PERIOD_S:
            return
        why = f" ({state[2]})" if state[0] is None else ""
        more = f" [{self._state_changes} changes since the last line]" if self._state_changes > 1 else ""
        g = self.core.guard.state
        guard = f" guard={g.mode} ({g.reason})" if g.mode in ("blind", "limited") else f" guard={g.mode}"
        self.log.info(f"active={state[0]} estop={state[1]}{why}{guard}{more}")
        self._last_state_log, self._state_changes = t, 0

    def status(self, now: float, wall: float | None = None) -> dict[str, Any]:
        latch = self.core.latch
        return {
            "robot": self.config.robot,
            "active": self.core.active,
            "estop": self.core.estopped,
            "estop_since": stamp_text(latch.since) if latch.engaged and latch.since is not None else None,
            "estop_why": latch.why if latch.engaged else None,
            "last_zero_reason": self.core.reason,
            "output": self.core.output.as_dict(),
            "limits": {
                "vx": [-self.core.limits.vx_backward, self.core.limits.vx_forward],
                "vy": self.core.limits.vy,
                "wz": self.core.limits.wz,
            },
            "guard": {**self.core.guard.state.as_dict(), "margin_m": self.core.guard.config.margin},
            "inputs": self.core.inputs_status(now, wall),
            "commander": self.commander.status(),
            "estop_state_file": str(self.store.path),
            "counters": {**self.core.counters, **self.core.guard.counters, **self.counters},
            "health": self.health_status(),
        }

    def health_status(self) -> dict[str, Any] | None:
        if self.health is None:
            return None
        v = self.verdict
        return {
            "level": v.level.name.lower(),
            "action": v.level.action,
            "speed_scale": v.speed_scale,
            "reasons": list(v.reasons),
            **self.health.status(),
        }
