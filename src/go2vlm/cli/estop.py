"""`go2vlm estop` holds the emergency stop; `go2vlm estop --release` is the deliberate release.

    go2vlm estop              # latch /emergency_stop and keep holding it (leave it running)
    go2vlm estop --release    # release it; waits until the gates and robot ends say so

The holder publishes `true` on /emergency_stop with a latched (transient-local) writer and keeps it
alive: a gate, sim or go2 driver that starts or restarts while it runs latches too (a `topic pub
--once` would take its latched sample with it when it exits). It prints what it holds and, as they
change, which gates (/safety/status) and robot ends (/go2/status, /sim/status) report latched. It
exits by itself once the release token arrives on /emergency_stop/release (0); stopped by a signal it
says that the latch stays engaged where it is engaged, and exits 128 + N.

`--release` publishes the token on /emergency_stop/release, then waits until every gate and robot
end that reported latched reports released (0), or says which still do not, for example because
their `release_token` differs (1). A latch that a gate left on disk for a robot (safety/estop.py
`latch_path`: one per robot and domain) while no gate of that robot runs is released there too, so
that `go2vlm demo` and `go2vlm eval` start again. Nothing reporting and nothing stored is a failure
(1): nobody confirmed it.

Time here is wall time (time.monotonic): a tool's deadlines and waits are for the person at the
terminal and for DDS discovery, not a node's clock.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

from go2vlm.bus import (
    QOS_LATCHED,
    Endpoint,
    Node,
    discovery_info,
    exit_code,
    interrupt_on_signals,
    signal_of,
)
from go2vlm.bus.topics import EMERGENCY_STOP, ESTOP_RELEASE, GO2_STATUS, SAFETY_STATUS, SIM_STATUS, TOPICS
from go2vlm.cli.args import add_dds_args
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.safety.estop import RELEASE_TOKEN, check_token

# Who reports the e-stop, and as what.
REPORTERS = {SAFETY_STATUS.name: "gate", GO2_STATUS.name: "robot (go2 driver)", SIM_STATUS.name: "robot (sim)"}
HOLDER_NODE = "go2vlm_estop"


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "estop",
        help="hold the emergency stop (latched until `go2vlm estop --release`)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--release", action="store_true", help="the deliberate release (publish the release token)")
    p.add_argument("--token", default=RELEASE_TOKEN, help=f"the release token (default {RELEASE_TOKEN})")
    p.add_argument("--timeout", type=float, default=10.0, help="--release: seconds to wait for the reports")
    p.add_argument("--wait", type=float, default=1.5, help="seconds of discovery before the first report")
    add_dds_args(p)
    p.set_defaults(func=run)


@dataclass
class Report:
    topic: str
    node: str
    estop: bool
    at: float  # wall time it arrived
    health: str = ""  # a gate's health verdict at level down: why it latches again after a release
    robot: str = ""  # a gate's robot (its latch is that robot's)


class Reports:
    """The newest e-stop state of every gate and robot end, one per status writer."""

    def __init__(self, node: Node) -> None:
        self._lock = threading.Lock()
        self._names = discovery_info.directory(node.participant)
        self.by_writer: dict[str, Report] = {}
        for topic in REPORTERS:
            TOPICS[topic].subscription(node, lambda m, s, t=topic: self._on(t, m, s), with_sender=True)

    def _on(self, topic: str, msg: String, sender: Endpoint | None) -> None:
        try:
            status = json.loads(msg.data)
            estop = status.get("estop")
            health = status.get("health") or {}
            down = "; ".join(health.get("reasons") or []) if health.get("level") == "down" else ""
        except (ValueError, AttributeError, TypeError):
            return
        if not isinstance(estop, bool) or sender is None:
            return
        name = self._names.node_of(sender.guid) or sender.participant
        robot = str(status.get("robot") or "")
        with self._lock:
            self.by_writer[sender.guid] = Report(topic, name, estop, time.monotonic(), down, robot)

    def snapshot(self) -> dict[str, Report]:
        with self._lock:
            return dict(self.by_writer)


def label(r: Report) -> str:
    return f"{r.node} ({REPORTERS[r.topic]})"


def describe(reports: dict[str, Report]) -> str:
    latched = sorted(label(r) for r in reports.values() if r.estop)
    free = sorted(label(r) for r in reports.values() if not r.estop)
    if not reports:
        return "no gate or robot end reports yet (/safety/status, /go2/status, /sim/status)"
    parts = [f"latched: {', '.join(latched) or 'none'}"]
    if free:
        parts.append(f"NOT latched: {', '.join(free)}")
    return "; ".join(parts)


def run(args: argparse.Namespace) -> int:
    try:
        token = check_token(args.token)
    except ValueError as exc:
        print(f"go2vlm estop: {exc}", file=sys.stderr)
        return 2
    if not args.timeout > 0 or not args.wait >= 0:
        print("go2vlm estop: --timeout must be positive and --wait not negative", file=sys.stderr)
        return 2
    interrupt_on_signals()
    node = Node(node_name=HOLDER_NODE, domain_id=args.domain, interface=args.interface)
    try:
        return release(node, token, args) if args.release else hold(node, token, args)
    except KeyboardInterrupt as exc:
        if not args.release:
            print(
                "go2vlm estop: stopped holding. Nodes that latched stay latched until `go2vlm estop --release`; "
                "a node that starts from now on does not hear this e-stop.",
                file=sys.stderr,
            )
        return exit_code(signal_of(exc))
    finally:
        node.shutdown()


def hold(node: Node, token: str, args: argparse.Namespace) -> int:
    released = threading.Event()
    by: list[str] = []
    names = discovery_info.directory(node.participant)

    def on_release(msg: String, sender: Endpoint | None) -> None:
        if msg.data == token and not released.is_set():
            by.append((names.node_of(sender.guid) if sender else None) or "an unnamed publisher")
            released.set()

    reports = Reports(node)
    ESTOP_RELEASE.subscription(node, on_release, with_sender=True)
    pub = EMERGENCY_STOP.publisher(node, qos=QOS_LATCHED)  # held latched: nodes that start later hear it
    node.start()
    pub.publish(Bool(data=True))
    print(
        f"go2vlm estop: HOLDING {EMERGENCY_STOP.name} = true (latched): every gate and robot end, including any that "
        f"starts later, stops and stays stopped. Release with `go2vlm estop --release`.",
        flush=True,
    )
    time.sleep(args.wait)
    last = ""
    while not released.wait(0.2):
        now = describe(reports.snapshot())
        if now != last:
            print(f"go2vlm estop: {now}", flush=True)
            last = now
    pub.close()  # no latched `true` left behind for late joiners
    print(f"go2vlm estop: released by {by[0]}; no longer holding {EMERGENCY_STOP.name}", flush=True)
    return 0


def release(node: Node, token: str, args: argparse.Namespace) -> int:
    reports = Reports(node)
    holders = EMERGENCY_STOP.subscription(node, lambda _m: None)
    pub = ESTOP_RELEASE.publisher(node)
    node.start()
    deadline = time.monotonic() + args.wait
    while time.monotonic() < deadline:  # discovery: the latched statuses and the release readers
        time.sleep(0.05)
    before = reports.snapshot()
    latched = {g for g, r in before.items() if r.estop}
    sent_at = time.monotonic()
    pub.publish(String(data=token))
    print(f"go2vlm estop: sent the release on {ESTOP_RELEASE.name}; {describe(before)}", flush=True)
    deadline = sent_at + args.timeout
    next_send = sent_at + 1.0

    def done() -> bool:
        now = reports.snapshot()
        return all(g in now and not now[g].estop and now[g].at > sent_at for g in latched)

    while not done() and time.monotonic() < deadline:
        if time.monotonic() >= next_send:  # a reader that matched late; a release is idempotent
            pub.publish(String(data=token))
            next_send += 1.0
        time.sleep(0.05)
    after = reports.snapshot()
    still = sorted(label(after[g]) for g in latched if g in after and after[g].estop)
    gone = sorted(label(before[g]) for g in latched if g not in after)
    stored = release_stored(args.domain, {r.robot for r in after.values() if r.topic == SAFETY_STATUS.name})
    for line in stored:
        print(f"go2vlm estop: released the stored latch of {line} (no gate of it is running)", flush=True)
    if not before and stored:
        return 0
    if not before:
        print(
            "go2vlm estop: no gate or robot end reported (/safety/status, /go2/status, /sim/status) and no latch "
            "is stored for this domain: the release was sent, but nobody confirmed it. Check --interface and the "
            "domain.",
            file=sys.stderr,
        )
        return 1
    unhealthy = sorted(f"{label(r)}: {r.health}" for g, r in after.items() if g in latched and r.estop and r.health)
    if unhealthy:
        print(
            f"go2vlm estop: still latched: the robot's health is at 'down' ({'; '.join(unhealthy)}); "
            "the gate latches again until the reading is healthy (docs/safety.md, Health)",
            file=sys.stderr,
        )
        return 1
    if still or not done():
        print(
            f"go2vlm estop: still latched after {args.timeout:g} s: {', '.join(still or gone)}. Is their "
            f"release_token {token!r}? Their status counts release_refused.",
            file=sys.stderr,
        )
        return 1
    released = sorted(label(after[g]) for g in latched) or ["nothing was latched"]
    print(f"go2vlm estop: released: {', '.join(released)}", flush=True)
    _report_holders(holders)
    return 0


def release_stored(domain_id: int | None, running: set[str]) -> list[str]:
    """Release the latch files of this domain's robots that no running gate keeps (a running gate
    writes its own); '<robot> on domain N (path)' for each one released."""
    from go2vlm.bus.domain import domain_id_from_env
    from go2vlm.robot_profile import PROFILES
    from go2vlm.safety.estop import LatchFile, latch_path

    did = domain_id if domain_id is not None else domain_id_from_env()
    out = []
    for robot in PROFILES:
        store = LatchFile(latch_path(robot, did))
        state = store.read()
        if state is None or not state.engaged or robot in running:
            continue
        store.save(False, HOLDER_NODE)
        out.append(f"robot {robot!r} on domain {did} ({store.path}; latched since {state.since or '?'}: {state.why})")
    return out


def _report_holders(holders: Any) -> None:
    """Say whether an `go2vlm estop` holder is still up (it exits by itself on the release)."""
    names = discovery_info.directory()
    deadline = time.monotonic() + 3.0

    def remaining() -> list[Endpoint]:
        return [w for w in holders.writers() if names.node_of(w.guid) == f"/{HOLDER_NODE}"]

    while remaining() and time.monotonic() < deadline:
        time.sleep(0.05)
    if remaining():
        print("go2vlm estop: an e-stop holder still publishes; it may use another token", file=sys.stderr)
    else:
        print("go2vlm estop: no e-stop holder left on /emergency_stop", flush=True)
