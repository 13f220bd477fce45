"""`go2vlm eval`: a suite of seeded episodes for one perception variant, in worker processes, into an
eval folder that grows by whole results and can be resumed.

    DIR/results.jsonl    one line per finished episode: its metrics, the episode and the exact
                         configuration of its run (suite file text, variant, model, seeds, git commit,
                         versions, machine); appended and synced line by line
    DIR/runs/RUN.json    that configuration, once per run
    DIR/summary.json, DIR/report.md, DIR/*.png   rewritten from results.jsonl at the end (report.py)
    DIR/episodes/ID/     with --video, --plots or --bag: each episode's run folder (metrics.json,
                         series.json: the commander's reasons on each change; plot.png with --video
                         or --plots; video.mp4 with --video; bag/ with --bag)

A run is (suite file, variant, model, server, seed, speed, node parameters): its id is a hash of them.
Several runs share a folder (oracle, color and vlm side by side); the report compares them. An
interrupted run goes on with --resume: finished episodes are kept and skipped, the unfinished one is
run again from its start.

Workers (apps/episodes/worker.py): every worker is a process with its own DDS domain (bus/domain.py
claim_free_domain), so episodes in parallel never hear each other; each runs its episodes one after
the other, every node in the worker process. A vlm variant's workers all ask the one server at --base-url.

The e-stop (apps/episodes/latch.py): with a fixed --domain, an eval on a latched robot is refused
before any worker starts (exit 2, one line with the release command); the free domains the workers
(and the Ray tasks) claim leave out every domain whose latch file on this machine holds the suite's
robot latched.

Ray (`--ray [ADDRESS]`, apps/episodes/cluster.py): every episode is a Ray task instead, on a local Ray
started for the run or on a cluster; each Ray worker process claims its DDS domain on the node it
runs on, as a worker does. Results stream into the same results.jsonl as they finish. A task whose
worker dies is retried once, then recorded in errors.jsonl (it is not in results.jsonl, so --resume
runs it again); the eval goes on.

Latency (`--latency L`, `EvalOptions.latency`): every episode's grounding answers are held back L sim
seconds (Episode.answer_latency_s), and a goal's timeout grows with it (episode.latency_timeout): a run
of its own per latency, side by side in the report.

Odometry drift (`--drift [GAIN]`, `EvalOptions.odom_drift`): every episode's sim reports a drifting
leg odometry on /odom and /tf (the sim node's `odom_drift`, sim/odometry_drift.py: gain 1 is a Go2's
size); the metrics stay on the ground truth. A run of its own, a row of its own in the report.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import subprocess
import sys
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from go2vlm.apps.episodes.episode import Episode, graph_name, latency_timeout, node_overrides, vlm_node_params
from go2vlm.apps.episodes.outputs import append_jsonl, read_jsonl, write_json
from go2vlm.apps.episodes.suites import Suite, load_suite
from go2vlm.apps.episodes.worker import EVAL_DOMAINS, worker_init, worker_run, worker_threads
from go2vlm.bus import ShutdownRequested
from go2vlm.errors import UsageError

__all__ = ["EvalError", "EvalOptions", "EvalOutcome", "run_eval"]


class EvalError(UsageError):
    """An eval that cannot start as asked (a usage or configuration error)."""


@dataclass
class EvalOptions:
    suite: str
    perception: str
    out: Path
    model: str | None = None
    base_url: str | None = None
    episodes: int | None = None  # None: the suite's
    only: tuple[int, ...] | None = None  # run only these episode indices (a miss again, a slice): same run id
    seed: int | None = None  # None: the suite's
    workers: int = 1
    resume: bool = False
    fast: bool = False
    rtf: float = 1.0
    mode: str | None = None  # None: the suite's
    video: bool = False
    plots: bool = False  # each episode's run folder with its plot and series, no video (why a miss ended so)
    bag: bool = False  # each episode's run folder gets bag/
    params: dict[str, dict[str, Any]] = field(default_factory=dict)
    interface: str = "lo"
    domain_id: int | None = None  # one fixed domain (one worker only)
    log_level: str = "error"  # of the nodes in the workers (every episode's start and stop would bury the progress)
    progress: bool = True
    latency: float | None = None  # sim seconds every grounding answer is held back (None: no latency axis)
    ray: str | None = None  # None: worker processes; "local": a Ray of this machine; "auto" or an address: a cluster
    odom_drift: float | None = None  # the sim's leg-odometry drift gain (1: a Go2's); None: perfect odometry


@dataclass
class EvalOutcome:
    run_id: str
    total: int
    done_before: int
    done: int
    interrupted: bool
    errors: list[str]
    summary: dict[str, Any]
    wall_s: float

    @property
    def group(self) -> dict[str, Any] | None:
        """This run's row of the summary (its suite, variant and model)."""
        return next((g for g in self.summary["groups"] if g.get("run_ids") and self.run_id in g["run_ids"]), None)


# -- the exact configuration ---------------------------------------------------------------------


def _git() -> dict[str, Any]:
    src = Path(__file__).resolve().parent
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=src, capture_output=True, text=True, timeout=10
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=src,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return {}
    return {"commit": commit or None, "dirty": bool(dirty)} if commit else {}


def _versions() -> dict[str, str | None]:
    from importlib.metadata import PackageNotFoundError, version

    out: dict[str, str | None] = {"python": platform.python_version()}
    for pkg in ("go2vlm", "mujoco", "cyclonedds", "numpy", "opencv-python-headless", "torch", "transformers"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    return out


def _machine() -> dict[str, Any]:
    cpu = None
    mem_gb = None
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                mem_gb = round(int(line.split()[1]) / 2**20, 1)
    except OSError:
        pass
    return {
        "host": platform.node(),
        "platform": platform.platform(),
        "cpu": cpu or platform.processor(),
        "cores": os.cpu_count(),
        "memory_gb": mem_gb,
        "mujoco_gl": os.environ.get("MUJOCO_GL"),
        "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),  # None: each worker its share of the cores
    }


def run_config(suite: Suite, opts: EvalOptions, seed: int, params: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """What decides a run's results, hashed into its id, plus where and with what it ran."""
    decides = {
        "suite": suite.name,
        "suite_sha256": suite.sha256,
        "perception": opts.perception,
        "model": opts.model,
        "base_url": opts.base_url,
        "seed": seed,
        "fast": opts.fast,
        "rtf": None if opts.fast else opts.rtf,
        "mode": opts.mode,
        "params": params,
    }
    if opts.latency is not None:  # only then, so that the ids of runs without a latency axis stay as they were
        decides["answer_latency_s"] = opts.latency
    if opts.odom_drift is not None:  # likewise
        decides["odom_drift"] = opts.odom_drift
    digest = hashlib.sha256(json.dumps(decides, sort_keys=True).encode()).hexdigest()[:10]
    return {
        "run_id": f"{suite.name}-{opts.perception}-{digest}",
        **decides,
        "suite_file": str(suite.path),
        "suite_text": suite.text,
        "git": _git(),
        "versions": _versions(),
        "machine": _machine(),
    }


# -- the run -------------------------------------------------------------------------------------


def _episodes(suite: Suite, opts: EvalOptions, seed: int, params: dict[str, dict[str, Any]]) -> list[Episode]:
    n = suite.episodes if opts.episodes is None else opts.episodes
    beyond = sorted(k for k in opts.only or () if not 0 <= k < n)
    if beyond:
        raise EvalError(f"--only: no episode {', '.join(map(str, beyond))} in {suite.name} (episodes 0-{n - 1})")
    out = []
    for k in range(n):
        ep = suite.episode(k, opts.perception, seed)
        merged = {name: dict(p) for name, p in ep.params.items()}
        for name, p in params.items():
            merged.setdefault(name, {}).update(p)
        if opts.odom_drift is not None:
            merged.setdefault("sim", {})["odom_drift"] = opts.odom_drift
        values = ep.to_dict()
        values.update(params=merged)
        if opts.mode is not None:
            values["mode"] = opts.mode
        if opts.latency is not None:
            values["answer_latency_s"] = opts.latency
            values["duration_s"] = latency_timeout(ep.duration_s, opts.latency, ep.kind)
        try:
            out.append(Episode.from_dict(values))
        except ValueError as exc:
            raise EvalError(str(exc)) from None
    return out


def _check(episodes: list[Episode], opts: EvalOptions) -> None:
    """Every graph builds with its parameters (a typo fails here, before any worker starts)."""
    from go2vlm.launch.launcher import check_entries, load_launch, with_overrides

    seen: set[tuple[str, str]] = set()
    for ep in episodes:
        key = (graph_name(ep), json.dumps(ep.params, sort_keys=True))
        if key in seen:
            continue
        seen.add(key)
        _, entries = load_launch(graph_name(ep))
        check_entries(with_overrides(entries, node_overrides(ep, opts.rtf, opts.fast), every={"use_sim_time": True}))


def _latched(episodes: list[Episode], opts: EvalOptions) -> tuple[int, ...]:
    """With a fixed domain: RobotLatched (exit 2) if the robot is latched there. Else the domains
    of EVAL_DOMAINS where a latch file holds the robot latched, for the workers to leave out."""
    from go2vlm.apps.episodes.latch import gate_latch, refuse_if_latched
    from go2vlm.apps.episodes.runner import RunOptions, episode_entries
    from go2vlm.safety.estop import LatchFile

    run = RunOptions(rtf=opts.rtf, fast=opts.fast)
    graphs = {graph_name(ep): episode_entries(ep, run) for ep in episodes}
    if opts.domain_id is not None:
        for entries in graphs.values():
            refuse_if_latched(entries, opts.domain_id, opts.interface)
        return ()
    out = set()
    for d in range(EVAL_DOMAINS[0], EVAL_DOMAINS[1] + 1):
        for entries in graphs.values():
            found = gate_latch(entries, d)
            state = LatchFile(found[1]).read() if found is not None else None
            if state is not None and state.engaged:
                out.add(d)
    if len(out) > EVAL_DOMAINS[1] - EVAL_DOMAINS[0]:
        raise EvalError("the e-stop is latched for this suite's robot on every eval domain; `go2vlm estop --release`")
    return tuple(sorted(out))


def _vlm_params(opts: EvalOptions) -> dict[str, dict[str, Any]]:
    try:
        return vlm_node_params(opts.perception, opts.model, opts.base_url, opts.params)
    except ValueError as exc:
        raise EvalError(str(exc)) from None


@dataclass
class _Prepared:
    suite: Suite
    seed: int
    params: dict[str, dict[str, Any]]
    episodes: list[Episode]
    config: dict[str, Any]
    exclude: tuple[int, ...] = ()  # eval domains where the suite's robot is latched: no worker claims them


def prepare(opts: EvalOptions) -> _Prepared:
    """Everything that can be checked before an episode runs: the options, the suite (its worlds load,
    its objects are in them), every episode and graph, the e-stop latch. EvalError / SuiteError / LaunchError /
    RobotLatched otherwise."""
    if opts.workers < 1:
        raise EvalError("--workers must be at least 1")
    if opts.domain_id is not None and (opts.workers > 1 or opts.ray is not None):
        raise EvalError("--domain gives every worker the same domain: use it with --workers 1 only")
    if opts.latency is not None and not (math.isfinite(opts.latency) and 0 <= opts.latency <= 60):
        raise EvalError(f"--latency: {opts.latency:g} s is not in 0..60")
    if opts.latency is not None and opts.perception == "color":
        raise EvalError("--latency is for --perception oracle and vlm (the colour grounder runs in the tracker)")
    if opts.odom_drift is not None and not (math.isfinite(opts.odom_drift) and 0 < opts.odom_drift <= 10):
        raise EvalError(f"--drift: {opts.odom_drift:g} is not a gain in (0, 10] (1: a Go2's odometry drift)")
    suite = load_suite(opts.suite)
    seed = suite.seed if opts.seed is None else opts.seed
    params = _vlm_params(opts)
    episodes = _episodes(suite, opts, seed, params)
    _check(episodes, opts)
    exclude = _latched(episodes, opts)
    return _Prepared(suite, seed, params, episodes, run_config(suite, opts, seed, params), exclude)


def run_eval(
    opts: EvalOptions, stop: ShutdownRequested, prepared: _Prepared | None = None, ray_session: Any = None
) -> EvalOutcome:
    """Run the suite's episodes that the folder does not hold yet; rewrite the report.

    `ray_session` (cluster.RaySession): a Ray shared by the command's runs, left running; without it a
    run with `opts.ray` connects (or starts) its own and closes it at the end."""
    from go2vlm.apps.episodes.report import write_report

    prep = prepared or prepare(opts)
    suite, seed, episodes, config = prep.suite, prep.seed, prep.episodes, prep.config
    run_id = config["run_id"]
    out = Path(opts.out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    results = out / "results.jsonl"
    lines = read_jsonl(results)
    mine = {line["index"] for line in lines if line.get("config", {}).get("run_id") == run_id}
    clash = {
        line["config"]["run_id"]
        for line in lines
        if line["config"]["run_id"] != run_id
        and (
            line["config"]["suite"],
            line["config"]["perception"],
            line["config"].get("model"),
            line["config"]["seed"],
            line["config"].get("answer_latency_s"),
            line["config"].get("odom_drift"),
        )
        == (suite.name, opts.perception, opts.model, seed, opts.latency, opts.odom_drift)
    }
    if clash:
        raise EvalError(
            f"{out} holds results of {suite.name}/{opts.perception} seed {seed} made with another configuration "
            f"(run {', '.join(sorted(clash))}: another suite file, speed or parameters); use another --out"
        )
    if mine and not opts.resume:
        raise EvalError(f"{out} already holds {len(mine)} episode(s) of run {run_id}; --resume finishes it")
    todo = [(k, ep) for k, ep in enumerate(episodes) if k not in mine and (opts.only is None or k in opts.only)]
    session = time.strftime("%Y%m%dT%H%M%S")
    session_t0 = time.time()  # wall time: the session's throughput
    run = {
        "rtf": opts.rtf,
        "fast": opts.fast,
        "video": opts.video,
        "plots": opts.plots,
        "bag": opts.bag,
        "episodes_dir": str(out / "episodes"),
    }
    cluster = None
    own_session = None
    if opts.ray is not None and todo and not stop.event.is_set():
        if ray_session is None:
            from go2vlm.apps.episodes.cluster import RaySession

            ray_session = own_session = RaySession(opts.ray, opts.workers, opts.interface, opts.log_level)
        cluster = ray_session.episodes()  # a UsageError if it cannot
    write_json(out / "runs" / f"{run_id}.json", config)
    errors: list[str] = []
    done = 0
    interrupted = False
    bar = _bar(opts, len(episodes), len(mine), suite.name)
    wins = sum(bool(line["metrics"]["success"]) for line in lines if line["config"]["run_id"] == run_id)

    def finished(k: int, ep: Episode, r: dict[str, Any]) -> None:
        nonlocal done, wins
        line = {
            "config": config,
            "index": k,
            "episode": ep.to_dict(),
            "metrics": r["metrics"],
            "session": session,
            "session_started_at": session_t0,
            "started_at": r["started_at"],
            "finished_at": r["finished_at"],
            "worker": r["worker"],
            "workers": opts.workers,
            **({"ray": opts.ray} if opts.ray is not None else {}),
        }
        append_jsonl(results, line)
        done += 1
        wins += bool(r["metrics"]["success"])
        _tick(bar, opts, ep, r, len(mine) + done, len(episodes), wins)

    def failed(k: int, ep: Episode, why: str) -> None:
        errors.append(f"{ep.id}: {why}")
        append_jsonl(out / "errors.jsonl", {"run_id": run_id, "index": k, "episode": ep.id, "error": why,
                                            "session": session, "at": time.time()})  # fmt: skip

    with stop.hold("the results"):
        if todo and not stop.event.is_set():
            if cluster is not None:
                try:
                    interrupted = cluster.run(todo, run, stop, finished, failed, prep.exclude)
                finally:
                    if own_session is not None:
                        own_session.close()
            else:
                interrupted = _run_pool(todo, run, opts, stop, finished, failed, prep.exclude)
        interrupted = interrupted or stop.event.is_set()
        if bar is not None:
            bar.close()
        summary = write_report(out)
    return EvalOutcome(run_id, len(episodes), len(mine), done, interrupted, errors, summary, time.time() - session_t0)


def _run_pool(
    todo: list[tuple[int, Episode]],
    run: dict[str, Any],
    opts: EvalOptions,
    stop: ShutdownRequested,
    finished: Any,
    failed: Any,
    exclude: tuple[int, ...],
) -> bool:
    """The episodes in worker processes; True if interrupted. The first error stops the rest."""
    import multiprocessing

    ctx = multiprocessing.get_context("spawn")  # a fresh interpreter: no DDS or GL state inherited
    stop_ev = ctx.Event()
    interrupted = False
    errors = False
    with ProcessPoolExecutor(
        max_workers=min(opts.workers, len(todo)),
        mp_context=ctx,
        initializer=worker_init,
        initargs=(stop_ev, opts.interface, opts.domain_id, opts.log_level, exclude, worker_threads(opts.workers)),
    ) as pool:
        futs: dict[Future[dict[str, Any]], tuple[int, Episode]] = {
            pool.submit(worker_run, k, ep.to_dict(), run): (k, ep) for k, ep in todo
        }
        pending = set(futs)
        while pending:
            done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            if (stop.event.is_set() or errors) and not stop_ev.is_set():
                stop_ev.set()  # running episodes end now; queued ones never start
                for f in pending:
                    f.cancel()
            for f in done:
                if f.cancelled():
                    continue
                k, ep = futs[f]
                exc = f.exception()
                if exc is not None:
                    errors = True
                    failed(k, ep, f"{type(exc).__name__}: {exc}")
                    continue
                r = f.result()
                if r["interrupted"]:
                    interrupted = True
                    continue
                finished(k, ep, r)
    return interrupted


def _bar(opts: EvalOptions, total: int, initial: int, name: str) -> Any:
    if not opts.progress:
        return None
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        unit="episode",
        desc=f"eval {name}/{opts.perception}",
        file=sys.stderr,
        disable=None,  # a line per episode instead when stderr is not a terminal
        smoothing=0.1,
    )


def _tick(bar: Any, opts: EvalOptions, ep: Episode, r: dict[str, Any], n: int, total: int, wins: int) -> None:
    m = r["metrics"]
    if bar is not None and not bar.disable:
        bar.update(1)
        bar.set_postfix_str(f"success {wins}/{n}")
    elif opts.progress:
        verdict = "success" if m["success"] else "FAIL"
        print(
            f"eval: {n}/{total} {ep.id} {ep.goal!r}: {verdict} ({m['sim_s']:.1f} s sim, {m['wall_s']:.1f} s wall)",
            file=sys.stderr,
            flush=True,
        )
