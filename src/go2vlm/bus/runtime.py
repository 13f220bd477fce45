"""Running nodes: in the foreground with clean SIGINT/SIGTERM shutdown, or in the background for
tests and the launcher.

Exit codes follow the shell's signal convention everywhere: a command stopped by signal N (after a
clean shutdown) exits 128 + N, so 130 for SIGINT (Ctrl-C) and 143 for SIGTERM; `exit_code()` says
which. Tools that are not node loops get KeyboardInterrupt for both signals (`interrupt_on_signals`,
the exception carries the signal) and turn it into the same code with `exit_code()`.
"""

from __future__ import annotations

import faulthandler
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from types import FrameType
from typing import Any

from go2vlm.bus.node import Node

# A node's shutdown normally takes well under a second; past this, print every thread's stack and
# exit hard, so Ctrl-C never hangs and a stuck shutdown says where it is stuck. The launcher waits
# a little longer than this before it kills a child.
SHUTDOWN_GRACE_S = 4.0


# The launcher's pid, set in the environment of each node it starts (`stop_with_parent`).
PARENT_ENV = "GO2VLM_PARENT_PID"


def stop_with_parent() -> None:
    """In a node the launcher started: SIGTERM (a clean shutdown) when the launcher dies, even by
    SIGKILL, so that no node outlives the launch that owns it (Linux: PR_SET_PDEATHSIG). A launcher
    gone before this runs means SIGTERM now. Nothing happens outside a launcher's child."""
    raw = os.environ.pop(PARENT_ENV, "")  # popped: a node's own children are not the launcher's
    if not raw.isdigit():
        return
    if sys.platform.startswith("linux"):
        import ctypes

        pr_set_pdeathsig = 1
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGTERM), 0, 0, 0)
    if os.getppid() != int(raw):
        os.kill(os.getpid(), signal.SIGTERM)


def exit_code(signum: int | None) -> int:
    """0 when not stopped by a signal, else 128 + signum (130 for SIGINT, 143 for SIGTERM)."""
    return 0 if signum is None else 128 + int(signum)


class Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGINT in a tool, as a KeyboardInterrupt that knows its signal."""

    def __init__(self, signum: int = signal.SIGINT) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)


def signal_of(exc: BaseException) -> int:
    """The signal behind a KeyboardInterrupt: its own for `Interrupted`, else SIGINT (Ctrl-C)."""
    return getattr(exc, "signum", int(signal.SIGINT))


def interrupt_on_signals() -> None:
    """SIGINT and SIGTERM raise `Interrupted` in the main thread (a launcher, `timeout` and `kill` end
    a tool as cleanly as Ctrl-C does); `exit_code(signal_of(exc))` is then the exit code."""

    def handler(signum: int, _frame: FrameType | None) -> None:
        raise Interrupted(signum)

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)


class _SignalRelay:
    """Hands SIGINT/SIGTERM from the signal handler to a thread of its own, through a pipe.

    Python runs a signal handler in the main thread between two bytecodes, wherever that thread
    is: also inside `Event.wait()` while it holds the Event's own lock (a plain, non-reentrant
    Lock). A handler that then calls `Event.set()` waits for that lock forever: the main thread
    never leaves its loop, so neither the shutdown nor its watchdog ever runs (seen as a node that
    ignores Ctrl-C on a loaded host; CPython documents the hazard: synchronization primitives do
    not mix with signal handlers). So the handler only writes the signal's number to a pipe, which
    takes no lock, and this thread does the rest, where taking a lock is safe.
    """

    def __init__(self) -> None:
        self._r, self._w = os.pipe()
        os.set_blocking(self._w, False)  # a flood of signals never blocks the handler
        self.target: ShutdownRequested | None = None
        threading.Thread(target=self._run, name="go2vlm:signals", daemon=True).start()

    def handler(self, signum: int, _frame: FrameType | None) -> None:
        try:
            os.write(self._w, bytes([signum]))
        except BlockingIOError:
            pass  # hundreds of signals not yet handed on: this one adds nothing

    def _run(self) -> None:
        while True:
            for signum in os.read(self._r, 64):
                if self.target is not None:
                    self.target._on_signal(signum)


_relay: _SignalRelay | None = None


class ShutdownRequested:
    """Set by SIGINT/SIGTERM; wait on it instead of sleeping. A second signal exits at once, except
    for a program that writes results: inside `hold()` further signals wait for the block (they are
    noted and ignored until it ends), and after a `hold()` a second signal sets `abort` (skip what is
    left, e.g. a video) while a third exits at once. `event` may be any Event-like object (a
    multiprocessing Event shared with worker processes). The signals are handled on a thread of
    their own (`_SignalRelay`), never inside the signal handler."""

    def __init__(self, event: Any = None) -> None:
        self.event = event if event is not None else threading.Event()
        self.signal: int | None = None
        self.abort = threading.Event()
        self._held: str | None = None
        self._graceful = False
        self._deferred: int | None = None

    @property
    def exit_code(self) -> int:
        """128 + the signal that stopped us (130 for SIGINT, 143 for SIGTERM), else 0."""
        return exit_code(self.signal)

    @contextmanager
    def hold(self, what: str) -> Iterator[None]:
        """While `what` is being written, a second signal waits for it (and then sets `abort`)."""
        self._graceful = True
        self._held = what
        try:
            yield
        finally:
            self._held = None
            if self._deferred is not None:
                self.abort.set()

    def _on_signal(self, signum: int) -> None:
        if not self.event.is_set():
            self.signal = signum
            self.event.set()
        elif self._held is not None:
            if self._deferred is None:
                print(f"signal {signum}: still writing {self._held}; stopping right after that", file=sys.stderr)
            self._deferred = signum
        elif self._graceful and not self.abort.is_set():
            print(f"signal {signum}: skipping what is left (once more exits at once)", file=sys.stderr)
            self.abort.set()
        else:
            print("second signal: exiting without a clean shutdown; threads were at:", file=sys.stderr)
            faulthandler.dump_traceback(all_threads=True)
            os._exit(128 + signum)

    def install(self) -> None:
        global _relay
        if threading.current_thread() is not threading.main_thread():
            return
        if _relay is None:
            _relay = _SignalRelay()
        _relay.target = self
        signal.signal(signal.SIGINT, _relay.handler)
        signal.signal(signal.SIGTERM, _relay.handler)


def spin(
    nodes: Sequence[Node],
    *,
    until: Callable[[], bool] | None = None,
    duration_s: float | None = None,
    shutdown: ShutdownRequested | None = None,
) -> int | None:
    """Run `nodes` until SIGINT/SIGTERM, `until()` is true or `duration_s` passes, then shut all down.
    Returns the signal that stopped them, or None (`exit_code()` turns it into the exit code). A node
    that called `fail(exc)` stops them all too, and `exc` is raised after the shutdown."""
    stop = shutdown or ShutdownRequested()
    if shutdown is None:
        stop.install()
    for node in nodes:
        node.start()
    elapsed = 0.0  # wall seconds: `duration_s` is a deadline for the process, not node time
    try:
        while not stop.event.is_set():
            if until is not None and until():
                break
            if duration_s is not None and elapsed >= duration_s:
                break
            if any(n.failure is not None for n in nodes):
                break
            stop.event.wait(0.05)
            elapsed += 0.05
    finally:
        # faulthandler's watchdog is a C thread: it fires even if the hang holds the GIL.
        faulthandler.dump_traceback_later(SHUTDOWN_GRACE_S, exit=True)
        try:
            for node in reversed(nodes):
                node.shutdown()
        finally:
            faulthandler.cancel_dump_traceback_later()
    failure = next((n.failure for n in nodes if n.failure is not None), None)
    if failure is not None and stop.signal is None:
        raise failure
    return stop.signal


@contextmanager
def running(*nodes: Node) -> Iterator[tuple[Node, ...]]:
    """`with running(a, b): ...` runs the nodes on background threads for the block."""
    for node in nodes:
        node.start()
    try:
        yield nodes
    finally:
        for node in reversed(nodes):
            node.shutdown()
