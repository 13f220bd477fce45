"""Inference in a process of its own: the node's bus work can no longer slow the model.

Eager decode is launch-bound: its token loop is Python, and in one process every other thread (the
image callbacks, and where a launch graph runs every node in one process, the sim's physics and
rendering, the tracker, the commander, the gate) competes with it for the interpreter. On an H100
the vlm node aged its results 2.34 s at 1.24 s of inference (issue 33). Here the backend runs in a
child process (`python -m go2vlm.perception.vlm.process_backend`, a fresh interpreter: never a fork
of a process with DDS threads, and no re-run of the parent's main script as multiprocessing's spawn
does) with an interpreter of its own; the node's worker hands it the newest frame through shared
memory (one block, grown when a frame is larger) and the prompt over a socket pair
(multiprocessing's Connection), and waits for the answer without holding the interpreter.

The child builds the backend the settings name (`process` off there), loads it and answers until it
is closed or its parent goes. Errors come back as the same exceptions (out of memory, backend
error); a child that dies is reported as a BackendError and started again (and its model loaded
again) by the next frame.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import replace
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory

import numpy as np

from go2vlm.errors import ConfigError
from go2vlm.perception.vlm.backend import BackendError, BackendSettings, Generation, VlmOutOfMemory

__all__ = ["InferenceProcess", "wants_process"]

_POLL_S = 0.2  # how often a waiting parent looks whether the child is still alive
_ERRORS: dict[str, type[Exception]] = {"oom": VlmOutOfMemory, "backend": BackendError, "config": ConfigError}


def wants_process(settings: BackendSettings) -> bool:
    """`process` auto: a model that computes in this interpreter (transformers, standin) gets its own
    process; openai's HTTP wait does not hold the interpreter."""
    if settings.process == "on":
        return True
    if settings.process == "off":
        return False
    if settings.process not in ("", "auto"):
        raise BackendError(f"process={settings.process!r}: use auto, on or off")
    return settings.backend in ("transformers", "standin")


def _error_reply(exc: BaseException) -> tuple[str, str, str]:
    kind = next((k for k, t in _ERRORS.items() if isinstance(exc, t)), "other")
    return ("error", kind, f"{type(exc).__name__}: {exc}" if kind == "other" else str(exc))


def _attach(name: str) -> SharedMemory:
    """The parent's block, without this process's resource tracker unlinking it when we exit
    (Python < 3.13 tracks attached blocks too; the parent owns and unlinks it)."""
    from multiprocessing import resource_tracker

    shm = SharedMemory(name=name)
    resource_tracker.unregister(shm._name, "shared_memory")  # type: ignore[attr-defined]
    return shm


def _child(conn: Connection) -> None:
    """The child's loop: settings in, load, then one reply per request, until close or the parent goes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the group: the parent closes us
    from go2vlm.perception.vlm.inprocess import make_in_process

    try:
        settings = conn.recv()
        backend = make_in_process(settings)
        backend.load()
    except BaseException as exc:  # noqa: BLE001 - every failure goes back to the node, which reports it
        conn.send(_error_reply(exc))
        return
    conn.send(
        ("ready", backend.description, getattr(backend, "settings", settings), getattr(backend, "load_report", {}))
    )
    blocks: dict[str, SharedMemory] = {}
    try:
        while True:
            try:
                req = conn.recv()
            except (EOFError, OSError):
                return  # the parent is gone
            if req[0] == "close":
                return
            _, name, shape, dtype, prompt = req
            try:
                if name not in blocks:
                    for old in blocks.values():
                        old.close()
                    blocks = {name: _attach(name)}
                # A copy (a millisecond): no view of the block outlives the request, so the block
                # can be closed when a larger one replaces it.
                rgb = np.ndarray(shape, dtype=dtype, buffer=blocks[name].buf).copy()
                conn.send(("ok", backend.generate(rgb, prompt)))
            except BaseException as exc:  # noqa: BLE001
                conn.send(_error_reply(exc))
    finally:
        for b in blocks.values():
            b.close()
        backend.close()


class InferenceProcess:
    """A Backend whose model runs in a child process (see the module docstring)."""

    def __init__(self, settings: BackendSettings) -> None:
        self.settings = settings
        self.name = settings.backend
        self.description = f"{settings.backend}:{settings.model} (own process)"
        self.load_report: dict[str, float] = {}
        self._proc: subprocess.Popen[bytes] | None = None
        self._conn: Connection | None = None
        self._shm: SharedMemory | None = None

    # -- lifecycle -------------------------------------------------------------------------------
    def load(self) -> None:
        t0 = time.perf_counter()
        ours, theirs = socket.socketpair()
        # The child imports what this process imports: the same sys.path (a test's src/ first, ...).
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
        cmd = [sys.executable, "-m", __name__, str(theirs.fileno())]
        self._proc = subprocess.Popen(cmd, pass_fds=[theirs.fileno()], env=env)
        theirs.close()
        self._conn = Connection(ours.detach())
        self._conn.send(replace(self.settings, process="off"))
        _, description, settings, report = self._reply("loading the model")
        assert isinstance(settings, BackendSettings) and isinstance(report, dict)
        # The child resolved what the checkpoint decides (max_pixels=0: its processor's limits).
        self.settings = replace(settings, process=self.settings.process)
        self.description = f"{description} (own process)"
        self.load_report = {**report, "process_start_s": round(time.perf_counter() - t0, 2)}

    def close(self) -> None:
        conn, proc, self._conn, self._proc = self._conn, self._proc, None, None
        if conn is not None:
            try:
                conn.send(("close",))
            except (OSError, ValueError):
                pass
            conn.close()
        if proc is not None:
            try:
                proc.wait(10.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5.0)
        if self._shm is not None:
            self._shm.close()
            self._shm.unlink()
            self._shm = None

    # -- inference -------------------------------------------------------------------------------
    def generate(self, rgb: np.ndarray, prompt: str) -> Generation:
        if self._conn is None or self._proc is None or self._proc.poll() is not None:
            self.close()
            self.load()  # started again after a crash (a model error is a reply, not a crash)
        assert self._conn is not None
        frame = np.ascontiguousarray(rgb)
        shm = self._block(frame.nbytes)
        np.ndarray(frame.shape, dtype=frame.dtype, buffer=shm.buf)[...] = frame
        self._conn.send(("gen", shm.name, frame.shape, frame.dtype.str, prompt))
        gen = self._reply("inference")[1]
        assert isinstance(gen, Generation)
        return gen

    def _block(self, nbytes: int) -> SharedMemory:
        """The shared block frames go through: one, replaced by a larger one when a frame needs it."""
        if self._shm is None or self._shm.size < nbytes:
            if self._shm is not None:
                self._shm.close()
                self._shm.unlink()
            self._shm = SharedMemory(create=True, size=max(nbytes, 1))
        return self._shm

    def _reply(self, what: str) -> tuple[object, ...]:
        """The child's answer; its exceptions raised here. Waits without holding the interpreter."""
        assert self._conn is not None and self._proc is not None
        while not self._conn.poll(_POLL_S):
            if self._proc.poll() is not None:
                code = self._proc.returncode
                self.close()
                raise BackendError(f"the inference process ended during {what} (exit code {code})")
        try:
            reply: tuple[object, ...] = self._conn.recv()
        except (EOFError, OSError) as exc:
            self.close()
            raise BackendError(f"the inference process ended during {what}") from exc
        if reply[0] == "error":
            _, kind, text = reply
            if what == "loading the model":
                self.close()
            raise _ERRORS.get(str(kind), BackendError)(str(text))
        return reply


if __name__ == "__main__":
    _child(Connection(int(sys.argv[1])))
