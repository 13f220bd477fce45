"""Helpers for tests that run go2vlm nodes and tools as real processes over real DDS."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

GO2VLM = [sys.executable, "-m", "go2vlm"]


def env() -> dict[str, str]:
    e = dict(os.environ)
    e.setdefault("PYTHONUNBUFFERED", "1")
    return e


class Procs:
    def __init__(self) -> None:
        self.procs: list[subprocess.Popen[str]] = []

    def start(self, *args: str, **kw: Any) -> subprocess.Popen[str]:
        """`procs.start("run", "follower", "--param", "kp_angular=0.5")`."""
        p = subprocess.Popen(
            [*GO2VLM, *args],
            stdout=kw.pop("stdout", subprocess.PIPE),
            stderr=kw.pop("stderr", subprocess.STDOUT),
            text=True,
            env=env(),
            start_new_session=kw.pop("start_new_session", True),  # its group: `stop` leaves nothing behind
            **kw,
        )
        self.procs.append(p)
        return p

    def stop(self, p: subprocess.Popen[str], sig: int = signal.SIGINT, timeout: float = 15.0) -> int:
        """`sig`, then SIGKILL past `timeout` (longer than a launcher takes to stop its children);
        then whatever is left of its process group, so that no process of this test outlives it and
        speaks on the domain during the next test."""
        if p.poll() is None:
            p.send_signal(sig)
            try:
                p.wait(timeout)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        _kill_group(p.pid)
        return p.returncode

    def stop_all(self) -> None:
        for p in reversed(self.procs):
            self.stop(p)


def _kill_group(pgid: int, grace_s: float = 5.0) -> None:
    """SIGKILL the process group `pgid` once its leader has exited, if members remain after grace_s."""

    def alive() -> bool:
        try:
            os.killpg(pgid, 0)
        except (ProcessLookupError, PermissionError):
            return False
        return True

    if alive() and not wait_for(lambda: not alive(), grace_s):
        try:
            os.killpg(pgid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def echo_json(topic: str, count: int = 1, timeout: float = 20.0, msg_type: str | None = None) -> list[dict]:
    """Run `go2vlm topic echo --json` in a subprocess and return the messages."""
    cmd = [*GO2VLM, "topic", "echo", topic, "--json", "--count", str(count), "--timeout", str(timeout)]
    if msg_type:
        cmd.insert(6, msg_type)
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout + 20, env=env())
    if out.returncode != 0:
        raise AssertionError(f"echo {topic} failed ({out.returncode}): {out.stderr[-2000:]}")
    return [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]


def rosbags_typestore(msgs: dict[str, str]) -> Any:
    """rosbags' ROS 2 Jazzy type store (the reference CDR implementation) plus these .msg definitions
    (ROS type name -> .msg text) for types the store lacks."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    found: dict[str, Any] = {}
    for name, text in msgs.items():
        (definition,) = get_types_from_msg(text, name).values()
        found[name] = definition  # under the name given: rosbags would file `pkg/srv/X` as `pkg/srv/msg/X`
    ts.register(found)
    return ts


def wait_for(pred: Callable[[], bool], timeout: float = 10.0, period: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(period)
    return pred()


class Recorder:
    """Collects messages from an in-process subscription with their receive times."""

    def __init__(self) -> None:
        self.items: list[tuple[float, Any]] = []
        self.lock = threading.Lock()

    def __call__(self, msg: Any) -> None:
        with self.lock:
            self.items.append((time.monotonic(), msg))

    def msgs(self) -> list[Any]:
        with self.lock:
            return [m for _, m in self.items]

    def __len__(self) -> int:
        with self.lock:
            return len(self.items)


# -- a DDS domain of our own ---------------------------------------------------------------------


def claim_free_domain(lo: int = 1, hi: int = 101) -> int:
    """A DDS domain in lo..hi for this test session (bus/domain.py claim_free_domain: no other
    go2vlm process holds it, no participant on this host speaks on it); GO2VLM_TEST_DOMAIN wins."""
    from go2vlm.bus.domain import claim_free_domain as claim

    fixed = os.environ.get("GO2VLM_TEST_DOMAIN")
    return int(fixed) if fixed else claim(lo, hi)


# -- foreign bytes: what a C++ ROS 2 node would put on the wire ---------------------------------
def foreign_write(writer: Any, sample: Any, raw: bytes) -> None:
    """Write `raw` CDR (produced by rosbags, as a C++ ROS 2 node would) verbatim: cyclonedds writes
    whatever `serialize()` returns after checking the sample's class."""
    sample.serialize = lambda **_kw: raw
    writer.write(sample)


def raw_take(reader: Any) -> list[bytes]:
    """The CDR bytes as they arrived, before any decoding by our classes."""
    from cyclonedds._clayer import ddspy_take
    from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState

    cond = ReadCondition(reader, SampleState.Any | ViewState.Any | InstanceState.Any)
    return [bytes(data) for data, info in ddspy_take(reader._ref, cond.mask, 16) if info.valid_data]


class Output:
    """A process's stdout, read on a thread: wait on a line instead of sleeping."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.proc = proc
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line)

    def wait_line(self, text: str, timeout: float = 60.0) -> bool:
        return wait_for(lambda: any(text in line for line in self.lines), timeout)

    def finish(self, timeout: float) -> str:
        """Wait for the exit (TimeoutExpired past `timeout`) and return everything it printed."""
        self.proc.wait(timeout)
        self._thread.join(5)
        return "".join(self.lines)
