"""An eval worker: the process side of `go2vlm eval`, for its worker processes and its Ray tasks alike.

A worker claims one DDS domain of `EVAL_DOMAINS` for as long as it lives (bus/domain.py
claim_free_domain, leaving out the domains where the robot is latched), so that episodes side by
side never hear each other, and runs its episodes one after the other, every node in its process.
evaluate.py hands it episodes and collects the results; cluster.py does the same through Ray.
"""

from __future__ import annotations

import os
import platform
import signal
import time
from collections.abc import Collection
from pathlib import Path
from typing import Any

from go2vlm.apps.episodes.episode import Episode
from go2vlm.bus import ShutdownRequested

__all__ = [
    "EVAL_DOMAINS",
    "claim_eval_domain",
    "run_worker_episode",
    "setup_process",
    "worker_init",
    "worker_run",
    "worker_threads",
]

EVAL_DOMAINS = (102, 232)  # claimed per worker; test sessions claim 1..101, a robot speaks on 0

_WORKER: dict[str, Any] = {}  # a worker process's stop event, interface and domain


def setup_process(interface: str, log_level: str) -> None:
    """This process's nodes speak on `interface` and log at `log_level`."""
    from go2vlm.bus import Logger

    os.environ["GO2VLM_IFACE"] = interface
    Logger.set_level(log_level)  # the nodes' start-up chatter of every episode would bury the progress


def claim_eval_domain(interface: str, exclude: Collection[int] = ()) -> int:
    """A free domain of EVAL_DOMAINS, none of `exclude`, this process's for as long as it lives."""
    from go2vlm.bus.domain import claim_free_domain

    return claim_free_domain(*EVAL_DOMAINS, interface, exclude=exclude)


def worker_threads(workers: int) -> int:
    """OpenMP threads per worker process: its share of the cores. A local model's torch (imported by the
    vlm node, after this) would otherwise start one thread per core in every worker, and threads that
    outnumber the cores spin at OpenMP's barriers waiting for each other (training the tiny grounder took
    20x longer per step with 2 threads than with 1 on the loaded 2-core machine). Ray gives a one-CPU
    task one thread for the same reason."""
    return max(1, (os.cpu_count() or 1) // max(1, workers))


def worker_init(
    stop_event: Any, interface: str, domain_id: int | None, log_level: str, exclude: tuple[int, ...], threads: int
) -> None:
    """A worker process's initializer: `domain_id` when given (one worker), else a free eval domain;
    `threads` OpenMP threads (worker_threads) unless the user set OMP_NUM_THREADS."""
    # The parent hears Ctrl-C and SIGTERM and tells the workers through `stop_event`; a terminal's
    # Ctrl-C also reaches the workers (one process group), and must not kill an episode half-written.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    os.environ.setdefault("OMP_NUM_THREADS", str(threads))  # the user's own setting wins
    setup_process(interface, log_level)
    domain = claim_eval_domain(interface, exclude) if domain_id is None else domain_id
    _WORKER.update(stop=stop_event, domain=domain, interface=interface)


def worker_run(index: int, episode: dict[str, Any], run: dict[str, Any]) -> dict[str, Any]:
    """One episode in a worker process set up by `worker_init`."""
    return run_worker_episode(index, episode, run, _WORKER["stop"], _WORKER["interface"], _WORKER["domain"])


def run_worker_episode(
    index: int, episode: dict[str, Any], run: dict[str, Any], stop_event: Any, interface: str, domain: int
) -> dict[str, Any]:
    """One episode in this (worker) process on `domain`: the result a worker hands back."""
    from go2vlm.apps.episodes.runner import RunOptions, run_episode

    ep = Episode.from_dict(episode)
    folder = run["video"] or run["bag"] or run.get("plots")
    out = Path(run["episodes_dir"]) / ep.id.replace("/", "-") if folder else None
    opts = RunOptions(
        rtf=run["rtf"],
        fast=run["fast"],
        out=out,
        video=run["video"],
        plot=run["video"] or bool(run.get("plots")),
        bag=run["bag"],
        interface=interface,
        domain_id=domain,
    )
    started = time.time()
    result = run_episode(ep, opts, ShutdownRequested(event=stop_event))
    metrics = {k: v for k, v in result.metrics.items() if k != "options"}
    return {
        "index": index,
        "metrics": metrics,
        "interrupted": result.interrupted,
        "started_at": started,
        "finished_at": time.time(),
        "worker": {"pid": os.getpid(), "domain": domain, "host": platform.node()},
    }
