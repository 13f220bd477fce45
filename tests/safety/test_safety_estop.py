"""The e-stop holds: the exact release token, the latch on disk, a gate killed with kill -9 while
latched comes back latched, and so does a replacement under another name (the latch belongs to
the robot), `go2vlm estop` holds the latch for nodes that start later until
`go2vlm estop --release`, the gate's state-change log is rate-limited, and SIGTERM exits 143.
Nodes run as real processes over real DDS."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from busutil import GO2VLM, Procs, Recorder, env, wait_for
from hypothesis import given
from hypothesis import strategies as st
from pipeutil import is_zero

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node, ParamError, build_config, running
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.safety.estop import EstopLatch, LatchFile, check_token, latch_path
from go2vlm.safety.gate_node import SafetyGateConfig

# -- the pure rule ---------------------------------------------------------------------------------


@given(st.text(max_size=12))
def test_only_the_exact_token_releases(text: str) -> None:
    latch = EstopLatch("RELEASE", engaged=True)
    assert latch.release(text) is (text == "RELEASE")
    assert latch.engaged is (text != "RELEASE")


def test_padded_or_empty_tokens() -> None:
    latch = EstopLatch("RELEASE", engaged=True)
    for padded in ("RELEASE ", " RELEASE", "RELEASE\n", "release"):
        assert not latch.release(padded) and latch.engaged
    for bad in ("", "   ", " RELEASE", "RELEASE\t"):
        with pytest.raises(ValueError):
            check_token(bad)
        with pytest.raises(ParamError):
            build_config(SafetyGateConfig, {"release_token": bad})
    assert build_config(SafetyGateConfig, {"release_token": "GO ON"}).release_token == "GO ON"


def test_latch_file_round_trip_and_the_safe_default(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "xdg"))
    path = latch_path("sim", 7)  # one per robot and domain, whatever the gate's name
    assert path == tmp_path / "xdg" / "go2vlm" / "estop" / "sim-domain7.json"
    store = LatchFile(path)
    assert store.load()[0] is None and store.read() is None  # no file: the gate's own start_engaged decides
    store.save(True, "safety", since=0.0, why="/emergency_stop from /go2vlm_estop")
    assert store.load()[0] is True
    state = store.read()
    assert state is not None and state.engaged and state.by == "safety" and state.why.startswith("/emergency_stop")
    assert state.since.startswith(("1970-01-01", "1969-12-31"))  # the epoch, in local time
    line = state.line("sim", 7)
    assert "latched for robot 'sim' on DDS domain 7 since 19" in line and "`go2vlm estop --release`" in line
    store.save(False, "safety")
    assert store.load()[0] is False and not store.read().engaged
    assert [p.name for p in path.parent.iterdir()] == [path.name], "no temporary files left behind"
    for broken in ("", "{", '{"engaged": "no"}', "[]"):
        path.write_text(broken)
        engaged, note = store.load()
        assert engaged is True and "starting latched" in note, broken  # unreadable means stopped
    path.unlink()
    path.mkdir()  # cannot be read as a file
    assert store.load()[0] is True


# -- real processes --------------------------------------------------------------------------------


class Probe(Node):
    name = "estop_probe"

    def __init__(self) -> None:
        super().__init__()
        self.cmd, self.status = Recorder(), Recorder()
        self.create_subscription(Twist, "/cmd_vel", self.cmd, QOS_DEFAULT)
        self.create_subscription(
            String, "/safety/status", lambda m, s: self.status((s.guid if s else "", json.loads(m.data))),
            QOS_LATCHED, with_sender=True,
        )  # fmt: skip
        self.teleop = self.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)
        self.release = self.create_publisher(String, "/emergency_stop/release", QOS_DEFAULT)

    def last_status(self) -> dict[str, Any]:
        items = self.status.msgs()
        return items[-1][1] if items else {}

    def estop(self) -> bool | None:
        return self.last_status().get("estop")

    def cmds_after(self, t: float) -> list[Twist]:
        with self.cmd.lock:
            return [m for ts, m in self.cmd.items if ts >= t]


def gate(procs: Procs, state: Path, *extra: str, log: Path | None = None) -> subprocess.Popen[str]:
    out = open(log, "w") if log else subprocess.PIPE  # noqa: SIM115 - closed with the process
    return procs.start("run", "safety", "--param", f"estop_state_file={state}", *extra, stdout=out)


class Teleop:
    """Keeps /teleop/cmd_vel at 0.3 m/s from a thread, so the gate would drive if it could."""

    def __init__(self, probe: Probe) -> None:
        self.probe = probe
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self.stop.wait(0.05):
            self.probe.teleop.publish(Twist(linear=Vector3(x=0.3)))

    def __enter__(self) -> Teleop:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join()


def test_a_gate_killed_while_latched_comes_back_latched(procs: Procs, tmp_path: Path) -> None:
    state = tmp_path / "gate.json"
    probe = Probe()
    with running(probe), Teleop(probe):
        g = gate(procs, state)
        assert wait_for(lambda: probe.estop() is False and probe.last_status().get("active") == "teleop", 20)
        # A one-shot e-stop: its writer goes away at once, so no latched sample stays on the bus.
        sender = Node(node_name="estop_once")
        pub = sender.create_publisher(Bool, "/emergency_stop", QOS_LATCHED)
        assert wait_for(lambda: pub.matched > 0, 10)
        pub.publish(Bool(data=True))
        assert wait_for(lambda: probe.estop() is True, 10)
        assert wait_for(lambda: json.loads(state.read_text())["engaged"] is True, 5)
        sender.shutdown()

        os.kill(g.pid, signal.SIGKILL)  # a process this test started
        g.wait(10)
        n = len(probe.status)
        g = gate(procs, state)
        assert wait_for(lambda: len(probe.status) > n and probe.estop() is not None, 20)
        assert probe.estop() is True, "a gate that went down latched must come back latched"
        t = time.monotonic()
        assert wait_for(lambda: len(probe.cmds_after(t)) >= 20, 10)
        assert all(is_zero(m) for m in probe.cmds_after(t)), "latched after the restart: only zeros"

        probe.release.publish(String(data="RELEASE "))  # padded: not the token
        assert wait_for(lambda: probe.last_status()["counters"].get("release_refused", 0) >= 1, 5)
        assert probe.estop() is True
        probe.release.publish(String(data="RELEASE"))
        assert wait_for(lambda: probe.estop() is False, 10)
        assert json.loads(state.read_text())["engaged"] is False
        assert wait_for(lambda: any(m.linear.x > 0 for m in probe.cmds_after(time.monotonic() - 0.2)), 5)

        # SIGTERM: a clean shutdown, exit 143 (128 + 15); released, it comes back released.
        assert procs.stop(g, signal.SIGTERM, timeout=15) == 128 + signal.SIGTERM
        n = len(probe.status)
        gate(procs, state)
        assert wait_for(lambda: len(probe.status) > n and probe.estop() is not None, 20)
        assert probe.estop() is False


def test_a_replacement_gate_under_another_name_starts_latched(procs: Procs) -> None:
    """The latch belongs to the robot: latch, kill -9 the gate, start a replacement under another
    --name (both on their default latch file): it starts latched and sends only zeros."""
    probe = Probe()
    with running(probe), Teleop(probe):
        g = procs.start("run", "safety")
        assert wait_for(lambda: probe.estop() is False and probe.last_status().get("active") == "teleop", 20)
        sender = Node(node_name="estop_once")  # one-shot: no latched sample stays on the bus after it
        pub = sender.create_publisher(Bool, "/emergency_stop", QOS_LATCHED)
        assert wait_for(lambda: pub.matched > 0, 10)
        pub.publish(Bool(data=True))
        assert wait_for(lambda: probe.estop() is True, 10)
        why = probe.last_status()["estop_why"]
        assert "estop_once" in why and probe.last_status()["estop_since"], probe.last_status()
        sender.shutdown()
        os.kill(g.pid, signal.SIGKILL)  # a process this test started
        g.wait(10)

        n = len(probe.status)
        g2 = procs.start("run", "safety", "--name", "gate_b")
        assert wait_for(lambda: len(probe.status) > n and probe.estop() is not None, 20)
        first = probe.status.msgs()[n][1]
        assert first["estop"] is True, "a replacement gate under another name must start latched"
        assert "estop_once" in first["estop_why"] and "restored" in first["estop_why"], first
        t = time.monotonic()
        assert wait_for(lambda: len(probe.cmds_after(t)) >= 20, 10)
        assert all(is_zero(m) for m in probe.cmds_after(t)), "latched: not one non-zero /cmd_vel"
        probe.release.publish(String(data="RELEASE"))
        assert wait_for(lambda: probe.estop() is False, 10)
        assert procs.stop(g2) == 128 + signal.SIGINT


def test_estop_holder_latches_late_nodes_until_the_release(procs: Procs, tmp_path: Path) -> None:
    probe = Probe()
    with running(probe), Teleop(probe):
        holder = procs.start("estop", stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        lines: list[str] = []
        reader = threading.Thread(target=lambda: lines.extend(holder.stdout or []), daemon=True)
        reader.start()
        assert wait_for(lambda: any("HOLDING" in line for line in lines), 15), lines
        # Gates that start after the holder, and one restarted under it, latch.
        g1 = gate(procs, tmp_path / "g1.json")
        assert wait_for(lambda: probe.estop() is True, 20)
        os.kill(g1.pid, signal.SIGKILL)
        g1.wait(10)
        (tmp_path / "g1.json").unlink()  # not even the state file: the holder alone latches it
        n = len(probe.status)
        gate(procs, tmp_path / "g1.json")
        assert wait_for(lambda: len(probe.status) > n and probe.estop() is True, 20)
        assert wait_for(lambda: any("latched: /safety (gate)" in line for line in lines), 10), lines

        out = subprocess.run([*GO2VLM, "estop", "--release"], capture_output=True, text=True, timeout=60, env=env())
        assert out.returncode == 0, out.stdout + out.stderr
        assert "released: /safety (gate)" in out.stdout
        assert probe.estop() is False
        assert holder.wait(15) == 0, "the holder exits by itself after the release"
        reader.join(5)
        assert any("released by" in line for line in lines), lines

        # The holder is gone: a restarted gate does not latch again (its state file says released).
        n = len(probe.status)
        gate(procs, tmp_path / "g2.json")
        assert wait_for(lambda: len(probe.status) > n + 2, 20)
        assert all(s["estop"] is False for _, s in probe.status.msgs()[n:])


def test_release_without_anyone_to_confirm_fails() -> None:
    out = subprocess.run(
        [*GO2VLM, "estop", "--release", "--wait", "0.5", "--timeout", "1"],
        capture_output=True, text=True, timeout=60, env=env(),
    )  # fmt: skip
    assert out.returncode == 1 and "nobody confirmed it" in out.stderr
    bad = subprocess.run([*GO2VLM, "estop", "--token", " X"], capture_output=True, text=True, timeout=60, env=env())
    assert bad.returncode == 2 and "whitespace" in bad.stderr and "Traceback" not in bad.stderr


@pytest.mark.slow  # flips the gate's state for 4 s of wall time
def test_state_change_log_is_rate_limited(procs: Procs, tmp_path: Path) -> None:
    """Alternating NaN and valid commands flip the gate's state at the input rate; its INFO lines
    about state changes stay at about one per second."""
    log = tmp_path / "gate.log"
    probe = Probe()
    with running(probe):
        g = gate(procs, tmp_path / "g.json", log=log)
        assert wait_for(lambda: probe.estop() is False, 20)
        t0 = time.monotonic()
        bad = Twist(linear=Vector3(x=float("nan")))
        good = Twist(linear=Vector3(x=0.2))
        n_status = len(probe.status)
        while time.monotonic() - t0 < 4.0:
            probe.teleop.publish(good)
            time.sleep(0.02)
            probe.teleop.publish(bad)
            time.sleep(0.02)
        seconds = time.monotonic() - t0
        assert len(probe.status) - n_status > 20, "the state really flipped many times (one status per change)"
        procs.stop(g)
    lines = [line for line in log.read_text().splitlines() if "[INFO]" in line and "active=" in line]
    assert len(lines) <= seconds * 1.0 + 3, "\n".join(lines)
    assert any("changes since the last line" in line for line in lines), "\n".join(lines)
