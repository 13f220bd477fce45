"""`go2vlm go2 stand|sit|rise|damp|recover|standdown|hello|balance|stop|move X Y Z|state`: talk to a Go2
(or the sim's Unitree bridge) directly over Unitree's sport RPC, for bring-up and checks.

`move` is teleop, not a side door: it publishes on /teleop/cmd_vel, the safety gate's
highest-priority input, so the gate's limits, watchdog and e-stop apply; it is also capped at
CLI_LIMITS and `--duration` (max 10 s) and ends with zero commands. It needs a running safety gate
and `go2` driver (or the sim). Posture verbs refuse while /emergency_stop is latched. While a `go2`
driver runs they go through it (/go2/command, and its answer on /go2/status): one commander per
robot, and the driver takes any other sport client for a foreign controller (it damps by default).
Without a driver they call the sport RPC directly, for bring-up.

Time here is wall time (time.monotonic): a tool's deadlines, rates and waits are for the person at
the terminal and for DDS discovery, not a node's clock.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from go2vlm.bus import exit_code, interrupt_on_signals, signal_of
from go2vlm.bus.topics import EMERGENCY_STOP, GO2_COMMAND, GO2_STATUS, SAFETY_STATUS, TELEOP_CMD_VEL
from go2vlm.cli.args import add_dds_args, positive
from go2vlm.robots.go2.protocol import POSTURES
from go2vlm.vocabulary.words import POSTURE_HELP

CLI_LIMITS = (0.6, 0.4, 1.0)  # |vx| m/s, |vy| m/s, |vyaw| rad/s
MAX_MOVE_S = 10.0


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "go2",
        help="command a Go2 (or the sim) over Unitree's sport RPC",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_dds_args(
        p,
        interface_help="network interface to the robot, e.g. enp3s0 (lo for a sim)",
        domain_help="DDS domain (the Go2 uses 0; default ROS_DOMAIN_ID or 0)",
    )
    p.add_argument("--timeout", type=positive, default=3.0, help="seconds to find the robot and for each answer")
    verbs = p.add_subparsers(dest="verb", metavar="VERB", required=True)
    for name in POSTURES:
        v = verbs.add_parser(name, help=POSTURE_HELP[name])
        v.set_defaults(func=cmd_posture, posture=name)
    mv = verbs.add_parser("move", help="teleop X m/s, Y m/s, Z rad/s for --duration s through the safety gate")
    mv.add_argument("x", type=float)
    mv.add_argument("y", type=float)
    mv.add_argument("z", type=float)
    mv.add_argument("--duration", type=float, default=1.0, help=f"seconds (max {MAX_MOVE_S:g})")
    mv.add_argument("--rate", type=float, default=20.0, help="commands per second")
    mv.set_defaults(func=cmd_move)
    st = verbs.add_parser("state", help="print rt/sportmodestate")
    st.add_argument("--count", "-n", type=int, default=1, help="samples to print (0: until Ctrl-C)")
    st.add_argument("--json", action="store_true", help="full message as one JSON object per line")
    st.set_defaults(func=cmd_state)


class _Session:
    """A node with a sport client and an /emergency_stop listener, spinning in the background."""

    def __init__(self, args: argparse.Namespace) -> None:
        from go2vlm.bus import Node
        from go2vlm.robots.go2 import protocol as p
        from go2vlm.robots.go2.client import RpcClient
        from go2vlm.safety import estop

        self.p = p
        self.node = Node(node_name="go2_cli", domain_id=args.domain, interface=args.interface, parameter_services=False)
        self._estop: dict[str, bool] = {}
        self.driver: dict[str, Any] | None = None  # the go2 driver's newest /go2/status, if one runs
        # The e-stop as the gate and the driver see it (they latch it; /emergency_stop false does
        # not release), plus the raw topic for setups without them.
        estop.listen(self.node, self._on_estop)
        for topic in (SAFETY_STATUS, GO2_STATUS):
            topic.subscription(self.node, lambda m, t=topic.name: self._on_status(t, m))
        self.sport = RpcClient(self.node, p.SPORT_SERVICE, timeout_s=args.timeout)
        self.command = GO2_COMMAND.publisher(self.node)
        self.node.start()
        self.timeout = args.timeout

    def _on_estop(self, msg: Any) -> None:
        if msg.data:
            self._estop[EMERGENCY_STOP.name] = True

    def _on_status(self, topic: str, msg: Any) -> None:
        try:
            status = json.loads(msg.data)
            self._estop[topic] = bool(status.get("estop"))
        except (ValueError, AttributeError):
            return
        if topic == GO2_STATUS.name:
            self.driver = status

    @property
    def estop(self) -> bool:
        statuses = [v for k, v in self._estop.items() if k != EMERGENCY_STOP.name]
        if statuses:  # the gate/driver know about releases; the raw topic keeps a stale `true`
            return any(statuses)
        return self._estop.get(EMERGENCY_STOP.name, False)

    def connect(self) -> bool:
        if self.sport.wait_for_server(self.timeout):
            time.sleep(0.2)  # let a latched /emergency_stop arrive before deciding anything
            return True
        print(
            f"go2vlm go2: no Go2 sport service found within {self.timeout:g} s. Is the robot on, on this network "
            "interface (--interface, e.g. enp3s0 for 192.168.123.x, lo for a local sim) and DDS domain 0?",
            file=sys.stderr,
        )
        return False

    def call(self, api: int) -> bool:
        result = self.sport.call(api)
        if result.code == self.p.ERR_CLIENT_API_TIMEOUT:
            # Posture calls are idempotent; the first request after discovery can be dropped while
            # the robot's reader has not matched us yet, so one retry is safe and enough.
            result = self.sport.call(api)
        name = self.p.SPORT_API_NAMES.get(api, str(api))
        if not result.ok:
            print(f"go2vlm go2: {name} failed: {result.describe()}", file=sys.stderr)
            return False
        print(f"{name}: ok")
        return True

    def through_driver(self, posture: str) -> int:
        """Send `posture` on /go2/command and wait for the driver to say how it ended."""
        from go2vlm.msgs.std_msgs import String

        before = ((self.driver or {}).get("last_command") or {}).get("seq", 0)
        deadline = time.monotonic() + self.timeout
        while self.command.matched == 0 and time.monotonic() < deadline:
            time.sleep(0.02)
        self.command.publish(String(data=posture))
        print(f"{posture}: sent to the go2 driver (/go2/command)", flush=True)
        deadline = time.monotonic() + self.timeout * len(self.p.COMMANDS[posture]) + 1.0

        def answer() -> dict[str, Any] | None:
            last = (self.driver or {}).get("last_command") or {}
            return last if last.get("seq", 0) > before and last.get("name") == posture else None

        while answer() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        last = answer()
        if last is None:
            print(f"go2vlm go2: the go2 driver did not report on {posture!r} in time", file=sys.stderr)
            return 1
        if last["result"] != "ok":
            print(f"go2vlm go2: {posture}: {last['result']}", file=sys.stderr)
            return 1
        print(f"{posture}: ok (through the go2 driver)")
        return 0

    def close(self) -> None:
        self.node.shutdown()


def cmd_posture(args: argparse.Namespace) -> int:
    interrupt_on_signals()
    s = _Session(args)
    try:
        if not s.connect():
            return 1
        if s.estop and args.posture not in s.p.ESTOP_ALLOWED:
            msg = f"go2vlm go2: refused {args.posture!r}: {EMERGENCY_STOP.name} is latched; release it first"
            print(msg, file=sys.stderr)
            return 1
        if s.driver is not None:
            return s.through_driver(args.posture)
        for api in s.p.COMMANDS[args.posture]:
            if not s.call(api):
                return 1
        return 0
    finally:
        s.close()


def _clamp(v: float, limit: float) -> float:
    return max(-limit, min(limit, v))


def cmd_move(args: argparse.Namespace) -> int:
    """Teleop through the safety gate: Twists on /teleop/cmd_vel (its highest-priority input), so
    the gate's limits, watchdog and e-stop apply as to every other motion command."""
    import math

    from go2vlm.bus import Node
    from go2vlm.msgs.geometry_msgs import Twist, Vector3

    interrupt_on_signals()
    values = (args.x, args.y, args.z)
    if not all(math.isfinite(v) for v in values):
        print(f"go2vlm go2 move: {values} must be finite numbers", file=sys.stderr)
        return 2
    if not 0 < args.duration <= MAX_MOVE_S:
        print(f"go2vlm go2 move: --duration must be in (0, {MAX_MOVE_S:g}] s", file=sys.stderr)
        return 2
    if not 1.0 <= args.rate <= 100.0:
        print("go2vlm go2 move: --rate must be in [1, 100] Hz", file=sys.stderr)
        return 2
    vx, vy, vz = (_clamp(v, lim) for v, lim in zip(values, CLI_LIMITS, strict=True))
    if (vx, vy, vz) != values:
        print(f"go2vlm go2 move: clamped to the CLI limits {CLI_LIMITS}: ({vx}, {vy}, {vz})", file=sys.stderr)
    node = Node(node_name="go2_cli_teleop", domain_id=args.domain, interface=args.interface, parameter_services=False)
    pub = TELEOP_CMD_VEL.publisher(node)
    try:
        deadline = time.monotonic() + args.timeout
        while pub.matched == 0 and time.monotonic() < deadline:
            time.sleep(0.02)
        if pub.matched == 0:
            print(
                "go2vlm go2 move: no safety gate listens on /teleop/cmd_vel; start one "
                "(`go2vlm run safety`, or a launch file with the go2 driver) and try again",
                file=sys.stderr,
            )
            return 1
        cmd = Twist(linear=Vector3(x=vx, y=vy), angular=Vector3(z=vz))
        end = time.monotonic() + args.duration
        sent = 0
        try:
            while time.monotonic() < end:
                pub.publish(cmd)
                sent += 1
                time.sleep(1.0 / args.rate)
        finally:
            for _ in range(3):  # the gate zeroes on its own timeout; this just stops sooner
                pub.publish(Twist())
                time.sleep(0.02)
        print(f"teleop: {sent} commands over {args.duration:g} s to /teleop/cmd_vel (through the safety gate)")
        return 0
    except KeyboardInterrupt as exc:
        return exit_code(signal_of(exc))
    finally:
        node.shutdown()


def cmd_state(args: argparse.Namespace) -> int:
    import threading

    from go2vlm.bus import QOS_UNITREE_READER, Node
    from go2vlm.msgs.convert import to_dict
    from go2vlm.msgs.unitree import SportModeState
    from go2vlm.robots.go2 import protocol as p

    interrupt_on_signals()
    node = Node(node_name="go2_cli", domain_id=args.domain, interface=args.interface, parameter_services=False)
    got: list[Any] = []
    done = threading.Event()

    def on_state(msg: Any) -> None:
        if done.is_set():
            return
        got.append(msg)
        if args.json:
            print(json.dumps(to_dict(msg)), flush=True)
        else:
            pos = ", ".join(f"{v:.3f}" for v in msg.position)
            vel = ", ".join(f"{v:.3f}" for v in msg.velocity)
            rpy = ", ".join(f"{v:.3f}" for v in msg.imu_state.rpy)
            mode = p.SPORT_MODES.get(int(msg.mode), str(int(msg.mode)))
            print(
                f"mode {mode}  position [{pos}]  velocity [{vel}]  yaw_speed {msg.yaw_speed:.3f}  rpy [{rpy}]  "
                f"body_height {msg.body_height:.3f}  error_code {msg.error_code}",
                flush=True,
            )
        if args.count and len(got) >= args.count:
            done.set()

    node.create_subscription(SportModeState, p.SPORT_STATE_TOPIC, on_state, QOS_UNITREE_READER)
    node.start()
    try:
        deadline = time.monotonic() + args.timeout
        while not done.is_set():
            if not got and time.monotonic() > deadline:
                print(
                    f"go2vlm go2 state: no rt/sportmodestate within {args.timeout:g} s (check --interface, domain 0)",
                    file=sys.stderr,
                )
                return 1
            done.wait(0.05)
        return 0
    except KeyboardInterrupt as exc:
        return exit_code(signal_of(exc))
    finally:
        node.shutdown()
