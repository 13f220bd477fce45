"""`go2vlm eval --ray [ADDRESS]`: every episode a Ray task, on a local Ray or on a cluster.

    --ray            start a Ray on this machine for the run (as many tasks at once as --workers)
    --ray auto       join the cluster this machine belongs to (`ray start --head` / `ray start --address`)
    --ray HOST:PORT  join the cluster whose head listens there (also ray://HOST:10001, Ray Client)

A task runs one episode in a Ray worker process, every node in that process, as an eval worker runs it;
each Ray worker process claims a DDS domain of its own on the node it runs on (bus/domain.py
claim_free_domain, for as long as the process lives), so tasks side by side never hear each other. The
driver (this process) appends each result to results.jsonl as its task finishes. A task whose worker
process dies (killed, out of memory, its node lost) is retried once by Ray (`max_retries=1`); if the
retry dies too, or the episode raised, it is recorded as an error and the eval goes on. Ray is an
optional extra: `pip install 'go2vlm[cluster]'`; nothing here imports it until --ray is given.

What it costs against --workers on one machine (docs/benchmarks.md, "Episodes per hour"):
- Ray starts its workers at niceness 15 (`worker_niceness`), below everything else on the machine;
  on a shared host an episode then waits behind every other process, where a --workers worker (nice
  0) does not. The local Ray this run starts gives its workers niceness 0, as the process pool's.
  (A cluster's own `ray start` decides for its nodes: `RAY_worker_niceness=0 ray start ...`.)
- Every episode is submitted at once and Ray runs as many as there are CPUs: a worker that finishes
  one episode takes the next at once (the owner keeps its lease), instead of handing the lease back
  and waiting for the driver to submit another.
- One Ray serves every run of a command (`--latency 0,1,2.5,5`: four runs, one start-up).
- Ray worker processes run task after task, and the first task in each pays the imports and GL
  start-up once, as a pool worker's first episode does; a Ray worker gets OMP_NUM_THREADS=1 (Ray's
  default for a one-CPU task), a pool worker its share of the cores (worker.worker_threads).
"""

from __future__ import annotations

import signal
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from go2vlm.apps.episodes.episode import Episode
from go2vlm.bus import ShutdownRequested
from go2vlm.errors import UsageError

__all__ = ["RayEpisodes", "RaySession", "reachable"]

CONNECT_TIMEOUT_S = 5.0  # wall seconds to reach a cluster's head before it counts as unreachable
OBJECT_STORE_BYTES = 128 * 2**20  # a local Ray: results are small JSON, not arrays
POLL_S = 0.2
# A local Ray's system config: its workers at the priority of --workers' (Ray's default niceness is 15).
LOCAL_SYSTEM_CONFIG = {"worker_niceness": 0}

_TASK_STATE: dict[str, Any] = {}  # per Ray worker process: its DDS domain, claimed once


class ClusterError(UsageError):
    """A Ray that cannot be started or reached, or no ray installed."""


def reachable(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> str | None:
    """None when a TCP connection to the head at `address` (HOST:PORT or ray://HOST:PORT) opens within
    `timeout_s`, else why not. `ray.init` would wait much longer on an address nobody answers."""
    hostport = address.split("://", 1)[-1]
    host, _, port = hostport.rpartition(":")
    if not host or not port.isdigit():
        return f"{address!r} is not HOST:PORT (or ray://HOST:PORT, or auto)"
    try:
        with socket.create_connection((host, int(port)), timeout=timeout_s):
            return None
    except OSError as exc:
        return f"nothing answers at {hostport} ({exc.strerror or exc})"


def _episode_task(
    index: int, episode: dict[str, Any], run: dict[str, Any], interface: str, log_level: str, exclude: tuple[int, ...]
) -> dict[str, Any]:
    """Runs in a Ray worker process: one episode on this process's own DDS domain (none of `exclude`,
    the domains where the robot is latched)."""
    from go2vlm.apps.episodes.worker import claim_eval_domain, run_worker_episode, setup_process

    if "domain" not in _TASK_STATE:
        setup_process(interface, log_level)
        _TASK_STATE["domain"] = claim_eval_domain(interface, exclude)
    return run_worker_episode(index, episode, run, threading.Event(), interface, _TASK_STATE["domain"])


@dataclass
class RayEpisodes:
    ray: Any  # the ray module
    task: Any  # the remote function
    interface: str
    log_level: str
    started_here: bool  # a local Ray this run started (and stops)

    @staticmethod
    def connect(address: str, workers: int, interface: str, log_level: str) -> RayEpisodes:
        """Start a local Ray (`address == "local"`) or join a cluster; ClusterError when it cannot."""
        try:
            import ray
        except ImportError:
            raise ClusterError("--ray needs Ray: pip install 'go2vlm[cluster]'") from None
        if address not in ("local", "auto"):
            why = reachable(address)
            if why is not None:
                raise ClusterError(f"cannot reach the Ray cluster at {address}: {why}")
        kwargs: dict[str, Any] = {"log_to_driver": False, "include_dashboard": False}
        on_sigterm = signal.getsignal(signal.SIGTERM)  # ray.init puts its own (sys.exit) in place of the eval's
        try:
            if address == "local":
                ray.init(
                    num_cpus=workers,
                    object_store_memory=OBJECT_STORE_BYTES,
                    _system_config=LOCAL_SYSTEM_CONFIG,
                    **kwargs,
                )
            else:
                ray.init(address=address, **kwargs)
        except (ConnectionError, RuntimeError, ValueError, TimeoutError) as exc:
            where = "a local Ray" if address == "local" else f"the Ray cluster at {address}"
            raise ClusterError(f"cannot start {where}: {str(exc).splitlines()[0]}") from None
        finally:
            if on_sigterm is not None and threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGTERM, on_sigterm)
        task = ray.remote(num_cpus=1, max_retries=1, retry_exceptions=False)(_episode_task)
        return RayEpisodes(ray, task, interface, log_level, address == "local")

    def run(
        self,
        todo: list[tuple[int, Episode]],
        run: dict[str, Any],
        stop: ShutdownRequested,
        finished: Callable[[int, Episode, dict[str, Any]], None],
        failed: Callable[[int, Episode, str], None],
        exclude: tuple[int, ...] = (),
    ) -> bool:
        """Every episode of `todo` as a task; `finished` / `failed` as each ends; no task claims a domain of
        `exclude`. True if interrupted.

        All are submitted at once: Ray runs as many at a time as the cluster has CPUs (--workers on a
        local Ray), and a worker that finishes one goes straight on to the next."""
        ray = self.ray
        pending: dict[Any, tuple[int, Episode]] = {}
        for k, ep in todo:
            pending[self.task.remote(k, ep.to_dict(), run, self.interface, self.log_level, exclude)] = (k, ep)
        interrupted = False
        while pending:
            if stop.event.is_set():
                for ref in pending:
                    ray.cancel(ref, force=True)  # a running episode ends unrecorded; --resume runs it again
                return True
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=POLL_S)
            for ref in ready:
                k, ep = pending.pop(ref)
                try:
                    r = ray.get(ref)
                except Exception as exc:  # the task raised, or its worker died twice
                    failed(k, ep, _why(exc))
                    continue
                if r["interrupted"]:
                    interrupted = True
                    continue
                finished(k, ep, r)
        return interrupted

    def close(self) -> None:
        if self.started_here or self.ray.is_initialized():
            self.ray.shutdown()


class RaySession:
    """One Ray for every run of a command, connected when the first run has episodes to give it."""

    def __init__(self, address: str, workers: int, interface: str, log_level: str) -> None:
        self.args = (address, workers, interface, log_level)
        self._episodes: RayEpisodes | None = None

    def episodes(self) -> RayEpisodes:
        if self._episodes is None:
            self._episodes = RayEpisodes.connect(*self.args)  # ClusterError if it cannot
        return self._episodes

    def close(self) -> None:
        if self._episodes is not None:
            self._episodes.close()
            self._episodes = None


def _why(exc: Exception) -> str:
    name = type(exc).__name__
    text = str(exc).strip().splitlines()
    if name in ("WorkerCrashedError", "NodeDiedError", "ObjectLostError", "OwnerDiedError"):
        return f"{name}: the task's worker died, and again when retried"
    cause = getattr(exc, "cause", None)
    if cause is not None:
        return f"{type(cause).__name__}: {cause}"
    return f"{name}: {text[-1] if text else ''}"
