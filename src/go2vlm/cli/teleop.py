"""`go2vlm teleop`: drive from the keyboard through the safety gate, like teleop_twist_keyboard.

Publishes /teleop/cmd_vel (geometry_msgs/Twist, the gate's highest-priority input), never /cmd_vel:
the gate's limits, health monitor and e-stop still apply. Keys (teleop_twist_keyboard's):

   u i o / j k l / m , .   move (k stops); with shift (U I O J K L M < >) strafe instead of turn
   q/z  all speeds +-10 %   w/x  linear only   e/c  angular only
   space or k   stop: zero now; a second stop within 1 s latches the e-stop
   !            latch the e-stop (/emergency_stop true); `go2vlm estop --release` releases it
   Ctrl-C       send zero and quit (exit 130); q is a speed key, as in the ROS tool

A key sets the command, repeated at --rate Hz until the next key or --key-timeout without a key
(then zero: hold a key to keep moving; 0 keeps the command until another key). The status line shows
the speeds, the command and the gate's state (/safety/status). Time here is wall time: the keyboard
and the repeat rate are the person's.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import select
import sys
import termios
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from go2vlm.bus.topics import CMD_VEL, EMERGENCY_STOP, SAFETY_STATUS, TELEOP_CMD_VEL
from go2vlm.cli.args import add_dds_args, non_negative, positive
from go2vlm.errors import UsageError

# key -> (x, y, yaw) direction, as teleop_twist_keyboard's moveBindings (z is not a walking robot's)
MOVES: dict[str, tuple[int, int, int]] = {
    "i": (1, 0, 0), "o": (1, 0, -1), "j": (0, 0, 1), "l": (0, 0, -1), "u": (1, 0, 1),
    ",": (-1, 0, 0), ".": (-1, 0, 1), "m": (-1, 0, -1),
    "I": (1, 0, 0), "O": (1, -1, 0), "J": (0, 1, 0), "L": (0, -1, 0), "U": (1, 1, 0),
    "<": (-1, 0, 0), ">": (-1, -1, 0), "M": (-1, 1, 0),
}  # fmt: skip
# key -> (linear factor, angular factor), as its speedBindings
SPEEDS: dict[str, tuple[float, float]] = {
    "q": (1.1, 1.1), "z": (0.9, 0.9), "w": (1.1, 1.0), "x": (0.9, 1.0), "e": (1.0, 1.1), "c": (1.0, 0.9),
}  # fmt: skip
STOP_KEYS = {" ", "k", "K"}
ESTOP_KEY = "!"
DOUBLE_STOP_S = 1.0  # a second stop within this latches the e-stop

HELP = """go2vlm teleop: /teleop/cmd_vel through the safety gate
   u    i    o        U    I    O      (shift: strafe)
   j    k    l        J    K    L
   m    ,    .        M    <    >
q/z speeds +-10%  w/x linear  e/c angular  space/k stop (twice: e-stop)  ! e-stop  Ctrl-C quit"""


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "teleop",
        help="drive from the keyboard through the safety gate (like teleop_twist_keyboard)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--speed", type=positive, default=0.2, help="linear speed, m/s (default 0.2)")
    p.add_argument("--turn", type=positive, default=0.5, help="yaw rate, rad/s (default 0.5)")
    p.add_argument("--rate", type=positive, default=10.0, help="publish rate, Hz (default 10)")
    p.add_argument("--key-timeout", type=non_negative, default=0.6, help="zero after S s without a key; 0 = never")
    p.add_argument("--topic", default=TELEOP_CMD_VEL.name, help="the gate input to publish (never /cmd_vel)")
    add_dds_args(p)
    p.set_defaults(func=run)


class Teleop:
    """The keyboard state, pure: keys in, the command and what to do out."""

    def __init__(self, speed: float, turn: float) -> None:
        self.speed, self.turn = speed, turn
        self.direction = (0, 0, 0)
        self.last_key_t = -math.inf
        self.last_stop_t = -math.inf

    def key(self, k: str, now: float) -> str | None:
        """Apply one key at `now`; returns "estop" when the e-stop must latch, else None."""
        if k in MOVES:
            self.direction, self.last_key_t = MOVES[k], now
        elif k in SPEEDS:
            lin, ang = SPEEDS[k]
            self.speed, self.turn = self.speed * lin, self.turn * ang
        elif k in STOP_KEYS or k == ESTOP_KEY:
            self.direction = (0, 0, 0)
            double = now - self.last_stop_t <= DOUBLE_STOP_S
            self.last_stop_t = now
            if k == ESTOP_KEY or double:
                return "estop"
        return None

    def command(self, now: float, key_timeout: float) -> tuple[float, float, float]:
        if key_timeout > 0 and now - self.last_key_t > key_timeout:
            self.direction = (0, 0, 0)
        x, y, yaw = self.direction
        return (x * self.speed, y * self.speed, yaw * self.turn)


@contextmanager
def keyboard(fd: int) -> Iterator[None]:
    """Keys one at a time without echo; Ctrl-C still raises SIGINT (ISIG stays on)."""
    saved = termios.tcgetattr(fd)
    raw = termios.tcgetattr(fd)
    raw[3] &= ~(termios.ICANON | termios.ECHO)
    raw[6][termios.VMIN], raw[6][termios.VTIME] = 0, 0
    termios.tcsetattr(fd, termios.TCSADRAIN, raw)
    try:
        yield
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def run(args: argparse.Namespace) -> int:
    topic = args.topic if args.topic.startswith("/") else "/" + args.topic
    if topic == CMD_VEL.name:
        raise UsageError("teleop publishes a gate input, never /cmd_vel: only the safety gate drives the robot")
    if not sys.stdin.isatty():
        raise UsageError("teleop reads the keyboard: run it in a terminal (stdin is not a TTY)")

    from go2vlm.bus import Node, exit_code, interrupt_on_signals, signal_of
    from go2vlm.msgs.geometry_msgs import Twist, Vector3
    from go2vlm.msgs.std_msgs import Bool

    class _Teleop(Node):
        name = "teleop"

    interrupt_on_signals()
    node = _Teleop(node_name="go2vlm_teleop", domain_id=args.domain, interface=args.interface, parameter_services=False)
    pub = TELEOP_CMD_VEL.publisher(node, name=topic)
    estop = EMERGENCY_STOP.publisher(node)  # volatile: no latched sample outlives the release
    gate: dict[str, Any] = {}
    SAFETY_STATUS.subscription(node, lambda m: gate.update(json.loads(m.data)))
    node.start()
    pad = Teleop(args.speed, args.turn)
    fd = sys.stdin.fileno()
    period = 1.0 / args.rate
    out = sys.stdout

    def send(v: tuple[float, float, float]) -> None:
        pub.publish(Twist(linear=Vector3(x=v[0], y=v[1]), angular=Vector3(z=v[2])))

    def status(v: tuple[float, float, float], note: str) -> None:
        health = (gate.get("health") or {}).get("level", "?")
        state = f"gate: active={gate.get('active')} estop={gate.get('estop')} health={health}" if gate else "gate: -"
        line = f"speed {pad.speed:.2f} turn {pad.turn:.2f} | cmd {v[0]:+.2f} {v[1]:+.2f} {v[2]:+.2f} | {state} {note}"
        out.write("\r" + line + "\x1b[K")
        out.flush()

    stopped_by: int | None = None
    note = ""
    print(HELP, flush=True)
    try:
        with keyboard(fd):
            next_t = time.monotonic()
            while True:
                wait = max(0.0, next_t - time.monotonic())
                ready, _, _ = select.select([fd], [], [], wait)
                now = time.monotonic()
                if ready:
                    data = os.read(fd, 64)
                    if not data:
                        break  # the terminal went away: stop and quit
                    for k in data.decode(errors="ignore"):
                        if pad.key(k, now) == "estop":
                            estop.publish(Bool(data=True))
                            note = "E-STOP latched (go2vlm estop --release)"
                        elif k in STOP_KEYS and not note.startswith("E-STOP"):  # a latch stays on the line
                            note = "stopped (again within 1 s: e-stop)"
                        elif k in MOVES or k in SPEEDS:
                            note = ""
                    if any(k in STOP_KEYS or k == ESTOP_KEY for k in data.decode(errors="ignore")):
                        send((0.0, 0.0, 0.0))  # a stop goes out now, not at the next tick
                if now >= next_t:
                    next_t = max(next_t + period, now)
                    v = pad.command(now, args.key_timeout)
                    send(v)
                    status(v, note)
    except KeyboardInterrupt as exc:
        stopped_by = signal_of(exc)
    finally:
        for _ in range(3):  # zero, and again, so that a dropped sample cannot leave the last command live
            send((0.0, 0.0, 0.0))
            time.sleep(0.05)
        out.write("\r\nteleop: sent zero; bye\n")
        out.flush()
        node.shutdown()
    return exit_code(stopped_by)
