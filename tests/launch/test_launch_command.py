"""`go2vlm launch`: the packaged launch file in one process, and a launch file as one process per
node (pids printed, a dead child reported), both stopped cleanly by a signal, with the signal
convention's exit code (130 for SIGINT, 143 for SIGTERM)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest
import yaml
from busutil import wait_for
from pipeutil import is_zero, wait_settled


class _Lines:
    """Collects a child's stdout lines on a thread (an unread pipe would block it)."""

    def __init__(self, p: subprocess.Popen[str]) -> None:
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._read, args=(p,), daemon=True)
        self._t.start()

    def _read(self, p: subprocess.Popen[str]) -> None:
        assert p.stdout is not None
        for line in p.stdout:
            self.lines.append(line.rstrip("\n"))

    def text(self) -> str:
        return "\n".join(self.lines)


def test_packaged_launch_in_one_process(procs, probe) -> None:
    p = procs.start("launch", "follow_test_pattern")
    out = _Lines(p)
    assert wait_for(lambda: out.text().count("up:") == 4, 20.0), out.text()
    wait_settled(probe, timeout=20.0)
    p.send_signal(signal.SIGTERM)
    assert p.wait(10) == 128 + signal.SIGTERM, out.text()
    assert "all nodes stopped" in out.text()
    t = time.monotonic()
    time.sleep(0.5)
    assert not probe.items_after(t), "/cmd_vel still published after the launcher stopped"


def test_launch_processes_reports_pids_and_deaths(procs, probe, tmp_path) -> None:
    launch = tmp_path / "pipe.yaml"
    launch.write_text(
        yaml.safe_dump(
            [
                {"node": "safety"},
                {"node": "follower", "name": "chaser"},
                {"node": "color_detector"},
                {"node": "test_pattern", "params": {"period_s": 0.1}},
            ]
        )
    )
    p = procs.start("launch", str(launch), "--processes")
    out = _Lines(p)
    assert wait_for(lambda: out.text().count(" pid ") == 4, 20.0), out.text()
    pids = {m.group(1): int(m.group(2)) for m in re.finditer(r"up: (\w+) \(\w+\) pid (\d+)", out.text())}
    assert set(pids) == {"safety", "chaser", "color_detector", "test_pattern"}
    wait_settled(probe, timeout=25.0)

    t_kill = time.monotonic()
    os.kill(pids["chaser"], signal.SIGKILL)  # a child this test's launcher started
    assert wait_for(lambda: "died: chaser (follower)" in out.text(), 5.0), out.text()
    assert wait_for(lambda: probe.first_zero_after(t_kill) is not None, 3.0)
    assert all(is_zero(m) for _, m in probe.items_after(t_kill + 0.6))

    p.send_signal(signal.SIGINT)
    assert p.wait(15) == 128 + signal.SIGINT, out.text()
    for pid in pids.values():
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)  # signal 0 only checks: every child is gone


def _gone(pid: int) -> bool:
    """The process has ended (a zombie not yet reaped by whoever adopted it counts as ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except (FileNotFoundError, IndexError):
        return True


def test_a_launcher_killed_by_sigkill_takes_its_nodes_with_it(procs, probe, tmp_path) -> None:
    """No node outlives the launch that owns it: a launcher killed by -9 cannot stop its children, so
    each child stops itself (a clean shutdown on SIGTERM) as soon as its parent dies. Left running, a
    simulated robot goes on publishing on the domain for whatever starts next."""
    launch = tmp_path / "pipe.yaml"
    launch.write_text(yaml.safe_dump([{"node": "safety"}, {"node": "test_pattern", "params": {"period_s": 0.1}}]))
    p = procs.start("launch", str(launch), "--processes")
    out = _Lines(p)
    assert wait_for(lambda: out.text().count(" pid ") == 2, 20.0), out.text()
    pids = [int(m.group(1)) for m in re.finditer(r"up: \w+ \(\w+\) pid (\d+)", out.text())]
    assert wait_for(lambda: len(probe.cmd) > 3, 25.0), out.text()  # the gate is up and publishing
    os.kill(p.pid, signal.SIGKILL)
    p.wait(10)
    assert wait_for(lambda: all(_gone(pid) for pid in pids), 30.0), [pid for pid in pids if not _gone(pid)]


def test_launch_rejects_a_bad_file(procs, tmp_path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("- node: follower\n  params: {kp_angular: fast}\n")
    p = procs.start("launch", str(bad), "--processes")
    assert p.wait(20) == 2
    assert "kp_angular" in (p.stdout.read() if p.stdout else "")
    p2 = procs.start("launch", "no_such_file")
    assert p2.wait(20) == 2
    assert "not found" in (p2.stdout.read() if p2.stdout else "")
