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
"""

from __future__ import annotations

import socket
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from go2vlm.apps.episodes.episode import Episode
from go2vlm.bus import ShutdownRequested
from go2vlm.errors import UsageError

__all__ = ["RayEpisodes", "reachable"]

CONNECT_TIMEOUT_S = 5.0  # wall seconds to reach a cluster's head before it counts as unreachable
OBJECT_STORE_BYTES = 128 * 2**20  # a local Ray: results are small JSON, not arrays
POLL_S = 0.2

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
    import threading

    from go2vlm.apps.episodes.worker import claim_eval_domain, run_worker_episode, setup_process

    if "domain" not in _TASK_STATE:
        setup_process(interface, log_level)
        _TASK_STATE["domain"] = claim_eval_domain(interface, exclude)
    return run_worker_episode(index, episode, run, threading.Event(), interface, _TASK_STATE["domain"])


@dataclass
class RayEpisodes:
    ray: Any  # the ray module
    task: Any  # the remote function
    in_flight: int  # tasks submitted at once
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
        try:
            if address == "local":
                ray.init(num_cpus=workers, object_store_memory=OBJECT_STORE_BYTES, **kwargs)
            else:
                ray.init(address=address, **kwargs)
        except (ConnectionError, RuntimeError, ValueError, TimeoutError) as exc:
            where = "a local Ray" if address == "local" else f"the Ray cluster at {address}"
            raise ClusterError(f"cannot start {where}: {str(exc).splitlines()[0]}") from None
        cpus = int(ray.cluster_resources().get("CPU", 1))
        task = ray.remote(num_cpus=1, max_retries=1, retry_exceptions=False)(_episode_task)
        return RayEpisodes(ray, task, workers if address == "local" else cpus, interface, log_level, address == "local")

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
        `exclude`. True if interrupted."""
        ray = self.ray
        queue = list(todo)
        pending: dict[Any, tuple[int, Episode]] = {}
        interrupted = False
        while queue or pending:
            if stop.event.is_set():
                for ref in pending:
                    ray.cancel(ref, force=True)  # a running episode ends unrecorded; --resume runs it again
                return True
            while queue and len(pending) < self.in_flight:
                k, ep = queue.pop(0)
                ref = self.task.remote(k, ep.to_dict(), run, self.interface, self.log_level, exclude)
                pending[ref] = (k, ep)
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


def _why(exc: Exception) -> str:
    name = type(exc).__name__
    text = str(exc).strip().splitlines()
    if name in ("WorkerCrashedError", "NodeDiedError", "ObjectLostError", "OwnerDiedError"):
        return f"{name}: the task's worker died, and again when retried"
    cause = getattr(exc, "cause", None)
    if cause is not None:
        return f"{type(cause).__name__}: {cause}"
    return f"{name}: {text[-1] if text else ''}"
