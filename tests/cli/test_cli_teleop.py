"""`go2vlm teleop` in a real pseudo-terminal, driving a real safety gate process: keys move /cmd_vel
through the gate, space stops, two stops within a second latch the e-stop, and Ctrl-C exits 130
after sending zero. The key rules themselves are checked on the pure keyboard state."""

from __future__ import annotations

import json
import os
import pty
import signal
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
from busutil import Procs, Recorder, env, wait_for

from go2vlm.bus import QOS_ANY, QOS_DEFAULT, QOS_LATCHED, Node
from go2vlm.cli.teleop import MOVES, Teleop
from go2vlm.msgs.geometry_msgs import Twist
from go2vlm.msgs.std_msgs import String


def test_keys_as_teleop_twist_keyboard() -> None:
    pad = Teleop(0.2, 0.5)
    assert pad.command(0.0, 0.6) == (0.0, 0.0, 0.0)
    pad.key("i", 0.0)
    assert pad.command(0.1, 0.6) == (0.2, 0.0, 0.0)
    pad.key("j", 0.2)
    assert pad.command(0.3, 0.6) == (0.0, 0.0, 0.5)
    pad.key("J", 0.3)  # shift: strafe
    assert pad.command(0.3, 0.6) == (0.0, 0.2, 0.0)
    assert pad.command(1.0, 0.6) == (0.0, 0.0, 0.0), "no key for key_timeout: zero"
    pad.key("q", 1.0)
    pad.key("x", 1.0)
    assert pad.speed == pytest.approx(0.2 * 1.1 * 0.9) and pad.turn == pytest.approx(0.55)
    pad.key("u", 2.0)
    assert pad.key(" ", 2.1) is None and pad.command(2.1, 0.0) == (0.0, 0.0, 0.0), "space stops"
    assert pad.key("k", 2.5) == "estop", "a second stop within 1 s latches the e-stop"
    assert pad.key(" ", 4.0) is None
    assert pad.key("!", 4.1) == "estop"
    assert set(MOVES) == set("uiojlm,.UIOJLM<>")


class Probe(Node):
    name = "teleop_probe"

    def __init__(self) -> None:
        super().__init__()
        self.cmd, self.teleop = Recorder(), Recorder()
        self.gate: dict[str, Any] = {}
        self.create_subscription(Twist, "/cmd_vel", self.cmd, QOS_DEFAULT)
        self.create_subscription(Twist, "/teleop/cmd_vel", self.teleop, QOS_ANY)
        self.create_subscription(String, "/safety/status", lambda m: self.gate.update(json.loads(m.data)), QOS_LATCHED)
        self.release = self.create_publisher(String, "/emergency_stop/release", QOS_DEFAULT)

    def vx(self) -> float | None:
        msgs = self.cmd.msgs()
        return msgs[-1].linear.x if msgs else None


class Terminal:
    """`go2vlm teleop` on the slave side of a pty (its controlling terminal); we type on the master."""

    def __init__(self) -> None:
        pid, fd = pty.fork()
        if pid == 0:  # the child: exec at once
            os.execve(sys.executable, [sys.executable, "-m", "go2vlm", "teleop"], env())
        self.pid, self.fd = pid, fd
        self.output = b""
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.code: int | None = None

    def _read(self) -> None:
        while True:
            try:
                data = os.read(self.fd, 4096)
            except OSError:
                return
            if not data:
                return
            self.output += data

    def type(self, keys: str) -> None:
        os.write(self.fd, keys.encode())

    def wait(self, timeout: float) -> int | None:
        deadline = time.monotonic() + timeout
        while self.code is None and time.monotonic() < deadline:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.code = os.waitstatus_to_exitcode(status)
            else:
                time.sleep(0.05)
        return self.code

    def close(self) -> None:
        if self.wait(0) is None:
            os.kill(self.pid, signal.SIGKILL)
            self.wait(5)
        os.close(self.fd)


@pytest.fixture
def term() -> Iterator[Terminal]:
    t = Terminal()
    try:
        yield t
    finally:
        t.close()


def test_teleop_drives_through_the_gate_and_stops(procs: Procs, term: Terminal) -> None:
    procs.start("run", "safety", "--param", "accel_linear=100")
    probe = Probe().start()
    try:
        # The gate is up (its status heard); teleop may already be its active input: the terminal starts
        # teleop before the gate, and its first (zero) command can reach the gate before the probe looks.
        assert wait_for(
            lambda: (
                b"go2vlm teleop" in term.output and "estop" in probe.gate and probe.gate["active"] in (None, "teleop")
            ),
            60,
        ), term.output

        def typing(keys: str, pred: Any, timeout: float = 15.0) -> bool:
            return wait_for(lambda: (term.type(keys), pred())[1], timeout, 0.2)

        # i: forward, through the gate (teleop publishes /teleop/cmd_vel; the gate /cmd_vel)
        assert typing("i", lambda: probe.vx() == 0.2 and probe.gate.get("active") == "teleop"), term.output[-500:]
        assert typing("i", lambda: b"gate: active=teleop" in term.output), "the status line shows the gate's state"
        term.type(" ")  # space: zero at once
        assert wait_for(lambda: probe.vx() == 0.0, 10)
        assert probe.gate["estop"] is False
        term.type("  ")  # two stops within 1 s: the e-stop latches
        assert wait_for(lambda: probe.gate.get("estop") is True, 10), probe.gate
        assert wait_for(lambda: b"E-STOP latched" in term.output, 10), term.output[-300:]
        probe.release.publish(String(data="RELEASE"))
        assert wait_for(lambda: probe.gate.get("estop") is False, 10)

        assert typing("i", lambda: probe.vx() == 0.2)
        term.type("\x03")  # Ctrl-C: zero, then exit 130
        assert term.wait(20) == 130, term.output[-800:]
        assert probe.teleop.msgs()[-1].linear.x == 0.0, "teleop's last word is zero"
        assert wait_for(lambda: probe.vx() == 0.0, 5)
        assert b"Traceback" not in term.output and b"sent zero" in term.output
    finally:
        probe.shutdown()


def test_teleop_needs_a_terminal() -> None:
    import subprocess

    from busutil import GO2VLM

    out = subprocess.run([*GO2VLM, "teleop"], stdin=subprocess.DEVNULL, capture_output=True, text=True, env=env())
    assert out.returncode == 2 and "not a TTY" in out.stderr and "Traceback" not in out.stderr
