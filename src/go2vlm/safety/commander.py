"""One commander per robot: only the safety gate drives /cmd_vel.

Rule (the same in the gate, the sim and the go2 driver):
- A gate announces itself on `/safety/heartbeat` (std_msgs/String JSON, latched, repeated every
  second): its node name, its participant and the GUID of its /cmd_vel writer.
- The robot end (sim, go2 driver) takes /cmd_vel only from the one writer that a heartbeat names,
  and only while that gate is the only writer matched on its /cmd_vel: a second gate, or any writer
  no heartbeat names (a raw `topic pub /cmd_vel`, a teleop node wired straight to the robot, a ROS 2
  node), stops the robot until it has gone; motion resumes only after /cmd_vel passed through zero.
- A gate that sees another writer on its /cmd_vel (another gate or a foreign one) holds its output
  at zero, so two gates both refuse to drive.
- Writers are identified by DDS publication identity (each sample's writer GUID, and the writers
  matched with the reader); names come from ros_discovery_info where the writer's process announces
  them. The heartbeat names a writer; it proves nothing against a deliberate impostor (see
  docs/safety.md): this guards against our own mistakes, not against an attacker.

`OneCommander` is the pure rule, driven by explicit timestamps. `CmdVelInput` puts a robot end on
/cmd_vel and the heartbeats, and `GateWatch` lets a gate watch its own /cmd_vel, both through it.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from go2vlm.bus import QOS_ANY, Endpoint, discovery_info
from go2vlm.bus.topics import CMD_VEL, SAFETY_HEARTBEAT
from go2vlm.msgs.geometry_msgs import Twist
from go2vlm.msgs.std_msgs import String

__all__ = [
    "ALARM_GRACE_S",
    "ThroughZero",
    "HEARTBEAT_TOPIC",
    "CmdVelInput",
    "GateWatch",
    "OneCommander",
    "Verdict",
    "Writer",
    "heartbeat",
    "parse_heartbeat",
]

HEARTBEAT_TOPIC = SAFETY_HEARTBEAT.name
# A new writer may show up in discovery a moment before its gate's heartbeat: it is refused at
# once, but reported as foreign only once it has stayed unannounced this long (wall seconds).
ALARM_GRACE_S = 1.0
CHECK_PERIOD_S = 0.1  # how often the matched writers are re-read (wall time: DDS discovery)


@dataclass(frozen=True)
class Writer:
    """A /cmd_vel writer: its GUID, its participant's GUID and, where announced, its node."""

    guid: str
    participant: str
    node: str | None = None

    def describe(self) -> str:
        who = f"node {self.node}" if self.node else "an unnamed node"
        return f"{who} (participant {self.participant}, writer {self.guid})"

    def as_dict(self) -> dict[str, Any]:
        return {"guid": self.guid, "participant": self.participant, "node": self.node}


@dataclass(frozen=True)
class Verdict:
    """Who may drive now: `driver` is the GUID of the one writer whose commands are taken, or None."""

    driver: str | None
    gates: tuple[Writer, ...] = ()
    foreign: tuple[Writer, ...] = ()
    reason: str = ""

    @property
    def ok(self) -> bool:
        return self.driver is not None

    def as_dict(self, alarm: Iterable[Writer] = ()) -> dict[str, Any]:
        return {
            "ok": self.ok,
            "driver": self.driver,
            "reason": self.reason,
            "gates": [w.as_dict() for w in self.gates],
            "foreign": [w.as_dict() for w in self.foreign],
            "reported": [w.as_dict() for w in alarm],
        }


def judge(writers: Iterable[Writer], gate_writers: set[str] | frozenset[str]) -> Verdict:
    """The rule: exactly one announced gate writer and nothing else, or nobody drives."""
    ws = sorted({w.guid: w for w in writers}.values(), key=lambda w: w.guid)  # one entry per writer GUID
    gates = tuple(w for w in ws if w.guid in gate_writers)
    foreign = tuple(w for w in ws if w.guid not in gate_writers)
    if foreign:
        what = "; ".join(w.describe() for w in foreign)
        return Verdict(None, gates, foreign, f"{len(foreign)} /cmd_vel writer(s) that are not a safety gate: {what}")
    if len(gates) > 1:
        what = "; ".join(w.describe() for w in gates)
        return Verdict(None, gates, foreign, f"{len(gates)} safety gates write /cmd_vel: {what}")
    if not gates:
        return Verdict(None, gates, foreign, "no safety gate writes /cmd_vel")
    return Verdict(gates[0].guid, gates, foreign, "")


@dataclass
class OneCommander:
    """The rule with memory: the verdict, when it changed, and which foreign writers have stayed
    long enough (`grace_s`) to be reported. Times are the caller's (wall seconds)."""

    grace_s: float = ALARM_GRACE_S
    verdict: Verdict = field(default_factory=lambda: Verdict(None, reason="no safety gate writes /cmd_vel"))
    changes: int = 0
    _first_seen: dict[str, float] = field(default_factory=dict)

    def update(self, now: float, writers: Iterable[Writer], gate_writers: set[str] | frozenset[str]) -> bool:
        """Judge the writers matched now; True when the verdict changed."""
        v = judge(writers, gate_writers)
        foreign = {w.guid for w in v.foreign}
        self._first_seen = {g: t for g, t in self._first_seen.items() if g in foreign}
        for g in foreign:
            self._first_seen.setdefault(g, now)
        changed = (v.driver, v.gates, v.foreign) != (self.verdict.driver, self.verdict.gates, self.verdict.foreign)
        self.verdict = v
        if changed:
            self.changes += 1
        return changed

    def alarm(self, now: float) -> tuple[Writer, ...]:
        """Foreign writers seen for at least grace_s, and every gate when there is more than one."""
        old = tuple(w for w in self.verdict.foreign if now - self._first_seen.get(w.guid, now) >= self.grace_s)
        return old + (self.verdict.gates if len(self.verdict.gates) > 1 else ())

    def accepts(self, writer_guid: str | None) -> bool:
        return writer_guid is not None and writer_guid == self.verdict.driver


@dataclass
class ThroughZero:
    """Motion resumes only through zero. After `require()` (a stop, an e-stop release) commands read
    as zero until the command stream has been at zero: if the newest command seen was zero already
    (a gate that held zero while the robot end was stopped, and ramps up from zero), nothing more is
    needed; if it was not (a stream still asking for speed), a zero must come first. Commands the
    robot end refuses but sees from a gate (during a conflict) count as seen. Start-up is not a stop:
    the robot is standing still, and the gate's own output ramps up from zero (on sim time a gate's
    first tick may already carry its first ramp step, so a zero first would never come)."""

    due: bool = False
    last_zero: bool = False  # the newest command seen was exactly zero

    def require(self) -> None:
        self.due = not self.last_zero

    def see(self, v: tuple[float, float, float]) -> bool:
        """Observe a command; True when it may drive (else the robot end holds zero)."""
        self.last_zero = all(x == 0.0 for x in v)  # NaN is not zero
        if self.last_zero:
            self.due = False
        return not self.due


# -- the heartbeat ---------------------------------------------------------------------------------
def heartbeat(node: str, participant: str, cmd_vel_writer: str, topic: str) -> String:
    return String(
        data=json.dumps({"node": node, "participant": participant, "cmd_vel_writer": cmd_vel_writer, "topic": topic})
    )


def parse_heartbeat(text: str) -> dict[str, str]:
    """A heartbeat's fields; ValueError if it is not one."""
    try:
        d = json.loads(text)
    except ValueError:
        raise ValueError(f"not JSON: {text[:60]!r}") from None
    if not isinstance(d, dict) or not all(isinstance(d.get(k), str) and d[k] for k in ("node", "cmd_vel_writer")):
        raise ValueError(f"missing node/cmd_vel_writer: {text[:80]!r}")
    return {k: str(d.get(k, "")) for k in ("node", "participant", "cmd_vel_writer", "topic")}


class _Watch:
    """A node's view of one /cmd_vel: its matched writers, the gates' heartbeats, the verdict."""

    def __init__(self, node: Any, cmd_sub: Any, *, own_writer: str | None, on_change: Callable[[], None]) -> None:
        self._time = time.monotonic  # wall time: DDS discovery and the alarm grace
        self.node = node
        self.cmd_sub = cmd_sub
        self.own_writer = own_writer
        self.gate_writers: set[str] = {own_writer} if own_writer else set()
        self.rule = OneCommander()
        self._on_change = on_change
        self._reported: tuple[str, ...] = ()
        self._names = discovery_info.directory(node.participant)
        self._node_names: dict[str, str] = {}  # writer GUID -> node, once announced (it never changes)
        SAFETY_HEARTBEAT.subscription(node, self._on_heartbeat)
        node.create_timer(CHECK_PERIOD_S, self.check, wall=True)

    def _on_heartbeat(self, msg: String) -> None:
        try:
            hb = parse_heartbeat(msg.data)
        except ValueError as exc:
            self.node.count("bad_heartbeat")
            self.node.log.throttled("error", 2.0, f"ignoring a bad {HEARTBEAT_TOPIC}: {exc}", key="hb")
            return
        if hb["cmd_vel_writer"] not in self.gate_writers:
            self.gate_writers.add(hb["cmd_vel_writer"])
            self.check()

    def _writer(self, ep: Endpoint) -> Writer:
        name = self._node_names.get(ep.guid)
        if name is None:
            name = self._names.node_of(ep.guid)
            if name is not None:
                self._node_names[ep.guid] = name
        return Writer(ep.guid, ep.participant, name)

    def known(self, guid: str | None) -> bool:
        """`guid` is one of the writers judged last time."""
        v = self.rule.verdict
        return any(w.guid == guid for w in (*v.gates, *v.foreign))

    def check(self) -> None:
        """Re-read the matched writers and judge them; report changes."""
        now = self._time()
        if self.rule.update(now, (self._writer(w) for w in self.cmd_sub.writers()), self.gate_writers):
            self._on_change()
        alarm = self.rule.alarm(now)
        keys = tuple(sorted(w.guid for w in alarm))
        if keys != self._reported:
            self._reported = keys
            if alarm:
                self.node.count("commander_alarms")
                self.node.log.error(f"ONE COMMANDER PER ROBOT: {self.rule.verdict.reason}")
            elif self.rule.verdict.ok:
                self.node.log.warning("one commander again: only the safety gate writes /cmd_vel")

    def status(self) -> dict[str, Any]:
        return self.rule.verdict.as_dict(self.rule.alarm(self._time()))


class CmdVelInput:
    """A robot end's /cmd_vel: commands only from the one safety gate, and after anything stopped it
    (another writer, an e-stop release: `require_zero()`) only once /cmd_vel has been at zero.

    `on_cmd(msg)` gets the commands to execute (a zero while a pass through zero is due);
    `on_stop(reason)` is called when driving stops being allowed. Counters on the node:
    cmd_vel_refused (samples from a writer that may not drive), commander_alarms.
    """

    def __init__(
        self,
        node: Any,
        on_cmd: Callable[[Twist], None],
        on_stop: Callable[[str], None],
        topic: str = CMD_VEL.name,
    ) -> None:
        self.node = node
        self._on_cmd = on_cmd
        self._on_stop = on_stop
        self.zero = ThroughZero()
        self._drove = False  # driving has been allowed once
        self.sub = CMD_VEL.subscription(node, self._on_msg, name=topic, with_sender=True)
        self.watch = _Watch(node, self.sub, own_writer=None, on_change=self._changed)

    @property
    def ok(self) -> bool:
        return self.watch.rule.verdict.ok

    def require_zero(self) -> None:
        self.zero.require()

    def _changed(self) -> None:
        if self.ok:
            self._drove = True
            return
        if self._drove:  # a stop; the not-yet-allowed verdicts of start-up are not one
            self.zero.require()
        self._on_stop(self.watch.rule.verdict.reason)

    def _on_msg(self, msg: Twist, sender: Endpoint | None) -> None:
        guid = sender.guid if sender is not None else None
        vals = (msg.linear.x, msg.linear.y, msg.angular.z)
        if not self.watch.rule.accepts(guid):
            if not self.watch.known(guid):
                self.watch.check()  # a writer not judged yet: judge it now, stop now
            if not self.watch.rule.accepts(guid):
                self.node.count("cmd_vel_refused")
                if guid in self.watch.gate_writers:
                    self.zero.see(vals)  # a gate's stream, refused for now: still what it commands
                return
        if not self.zero.see(vals):
            self.node.count("cmd_vel_held_for_zero")
            msg = Twist()
        self._on_cmd(msg)

    def status(self) -> dict[str, Any]:
        return {**self.watch.status(), "need_zero": self.zero.due}


class GateWatch:
    """A gate's watch on its own /cmd_vel: any other writer there (another gate or a foreign one)
    is a reason to hold the output at zero. `blocked` is that reason, or None."""

    def __init__(self, node: Any, own_writer: str, topic: str, on_change: Callable[[], None]) -> None:
        self.own_writer = own_writer
        # Best-effort matches every writer; the gate takes its own samples and drops them.
        sub = CMD_VEL.subscription(node, lambda _m: None, name=topic, qos=QOS_ANY)
        self.watch = _Watch(node, sub, own_writer=own_writer, on_change=on_change)
        self._heartbeat = SAFETY_HEARTBEAT.publisher(node)
        self._msg = heartbeat(
            discovery_info.full_name("/", discovery_info.ros_node_name(node.node_name)),
            str(node.participant.guid),
            own_writer,
            topic,
        )
        self.beat()

    def beat(self) -> None:
        self._heartbeat.publish(self._msg)

    @property
    def blocked(self) -> str | None:
        v = self.watch.rule.verdict
        if v.driver == self.own_writer:
            return None
        others = [w for w in (*v.gates, *v.foreign) if w.guid != self.own_writer]
        if not others:
            return None  # only us: the verdict waits for our own writer to show up as matched
        return v.reason

    def status(self) -> dict[str, Any]:
        return self.watch.status()
