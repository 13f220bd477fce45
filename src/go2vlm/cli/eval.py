"""`go2vlm eval`: a suite of seeded episodes for one perception variant; results a user can compare."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from go2vlm.behavior.strategies.explore_params import FRONTIER_CHOICES
from go2vlm.cli.args import add_dds_args, add_node_params, node_params


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "eval",
        help="run a suite of seeded sim episodes and report success, SPL and grounding with confidence intervals",
        description=(
            "Run the episodes of a suite (packaged: smoke, goals, follow, distractors, obstacles, household, "
            "household_cross, referring, rooms, rooms_narrow, houses; or a path to a "
            "suite YAML) with one perception variant (oracle: the sim's ground-truth boxes; color: the colour-shape "
            "grounder; vlm: a vision-language model, local or OpenAI-compatible) and write results.jsonl (one line "
            "per episode, with its exact configuration), summary.json, report.md and plots to --out. Several "
            "variants can share one --out; the report compares them. Ctrl-C keeps every finished episode; "
            "--resume finishes the run. See docs/eval.md."
        ),
    )
    p.add_argument("--suite", default=None, help="suite name or YAML path (see --list)")
    p.add_argument("--perception", choices=("oracle", "color", "vlm"), default=None, help="the perception variant")
    p.add_argument("--model", default=None, help="vlm: checkpoint dir, hub id, or the served model's name")
    p.add_argument("--base-url", default=None, help="vlm: an OpenAI-compatible server, e.g. http://gpu-box:8000/v1")
    p.add_argument("--episodes", type=int, default=None, help="how many episodes (default: the suite's)")
    p.add_argument(
        "--only",
        default=None,
        metavar="K,K,...",
        help="run only these episodes (indices from 0, as in results.jsonl), e.g. 28,32; the run id stays the "
        "suite's, so --resume later finishes the rest",
    )
    p.add_argument("--seed", type=int, default=None, help="seed of the spawns and draws (default: the suite's)")
    p.add_argument("--workers", type=int, default=1, help="episodes in parallel, one process and DDS domain each")
    p.add_argument(
        "--ray",
        nargs="?",
        const="local",
        default=None,
        metavar="ADDRESS",
        help="run each episode as a Ray task: alone, a local Ray on this machine (--workers tasks at once); "
        "'auto' or HOST:PORT joins a running cluster (pip install 'go2vlm[cluster]')",
    )
    p.add_argument(
        "--latency",
        default=None,
        metavar="L1,L2,...",
        help="run the suite once per added answer latency in sim seconds, e.g. 0,1,2.5,5 (oracle: the ground "
        "truth delivered late; vlm: the model's answers held back)",
    )
    p.add_argument(
        "--drift",
        type=float,
        nargs="?",
        const=1.0,
        default=None,
        metavar="GAIN",
        help="the sim's leg odometry drifts (/odom, /tf) as a Go2's does (GAIN 1, the default; 2 twice as much): "
        "the drift variant, a row of its own in the report",
    )
    p.add_argument(
        "--frontier",
        choices=FRONTIER_CHOICES,
        default=None,
        help="the commander's frontier_choice while exploring (default: its own, gain); vlm asks which way "
        "leads to the object (oracle: answered from the ground truth): a run of its own (its parameters differ)",
    )
    p.add_argument("--out", type=Path, default=None, help="the eval folder (results.jsonl, summary.json, report.md)")
    p.add_argument("--resume", action="store_true", help="finish an interrupted run in --out, skipping done episodes")
    speed = p.add_mutually_exclusive_group()
    speed.add_argument("--rtf", type=float, default=1.0, help="target real-time factor (default 1.0)")
    speed.add_argument("--fast", action="store_true", help="as fast as the host allows (fine for oracle/color)")
    p.add_argument("--mode", choices=("kinematic", "dynamic"), default=None, help="sim physics (default: the suite's)")
    p.add_argument("--video", action="store_true", help="also write each episode's run folder with video.mp4")
    p.add_argument(
        "--plots",
        action="store_true",
        help="also write each episode's run folder with plot.png and series.json (the commander's reasons), no video",
    )
    p.add_argument("--bag", action="store_true", help="also record each episode's topics into its run folder's bag/")
    add_node_params(p, "a node parameter for every episode")
    add_dds_args(
        p,
        interface="lo",
        interface_help="network interface of the workers' DDS (default lo)",
        domain_help="a fixed DDS domain (--workers 1); default: a free one",
    )
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    p.add_argument("--list", action="store_true", help="list the packaged suites and exit")
    p.add_argument("--report", action="store_true", help="only rewrite summary.json and report.md of --out")
    p.set_defaults(func=run)


def parse_latencies(text: str) -> list[float]:
    """ "0,1,2.5,5" -> [0.0, 1.0, 2.5, 5.0]; ValueError naming the bad value."""
    import math

    out: list[float] = []
    for part in text.split(","):
        try:
            v = float(part.strip())
        except ValueError:
            raise ValueError(f"--latency: {part.strip()!r} is not a number of seconds (e.g. 0,1,2.5,5)") from None
        if not (math.isfinite(v) and 0 <= v <= 60):
            raise ValueError(f"--latency: {part.strip()} s is not in 0..60")
        if v in out:
            raise ValueError(f"--latency: {part.strip()} is given twice")
        out.append(v)
    return out


def run(args: argparse.Namespace) -> int:
    import dataclasses

    from go2vlm.apps.episodes.evaluate import EvalOptions, prepare, run_eval
    from go2vlm.apps.episodes.suites import available_suites, load_suite
    from go2vlm.bus import ShutdownRequested
    from go2vlm.errors import UsageError

    if args.list:
        for name in available_suites():
            s = load_suite(name)
            print(f"{name:12s} {s.episodes:3d} episodes  {s.description}")
        return 0
    if args.out is None:
        print("go2vlm eval: give --out DIR (the eval folder)", file=sys.stderr)
        return 2
    if args.report:
        from go2vlm.apps.episodes.report import write_report

        if not (args.out / "results.jsonl").is_file():
            print(f"go2vlm eval: {args.out} has no results.jsonl", file=sys.stderr)
            return 2
        write_report(args.out)
        print(f"wrote {args.out / 'summary.json'} and {args.out / 'report.md'}")
        return 0
    if not args.suite or not args.perception:
        print(
            "go2vlm eval: give --suite NAME and --perception {oracle,color,vlm} (--list shows the suites)",
            file=sys.stderr,
        )
        return 2
    if args.episodes is not None and args.episodes < 1:
        print("go2vlm eval: --episodes must be at least 1", file=sys.stderr)
        return 2
    if not args.fast and args.rtf <= 0:
        print("go2vlm eval: --rtf must be positive", file=sys.stderr)
        return 2
    try:
        only = None if args.only is None else tuple(sorted({int(k) for k in args.only.split(",") if k.strip()}))
    except ValueError:
        print(f"go2vlm eval: --only takes episode indices such as 28,32, not {args.only!r}", file=sys.stderr)
        return 2
    try:
        latencies: list[float | None] = [None] if args.latency is None else list(parse_latencies(args.latency))
    except ValueError as exc:
        print(f"go2vlm eval: {exc}", file=sys.stderr)
        return 2
    base = EvalOptions(
        suite=args.suite,
        perception=args.perception,
        out=args.out,
        model=args.model,
        base_url=args.base_url,
        episodes=args.episodes,
        only=only,
        seed=args.seed,
        workers=args.workers,
        resume=args.resume,
        fast=args.fast,
        rtf=args.rtf,
        mode=args.mode,
        video=args.video,
        plots=args.plots,
        bag=args.bag,
        params=_with_frontier(node_params(args.param), args.frontier),
        interface=args.interface,
        domain_id=args.domain,
        progress=args.progress,
        log_level=args.log_level or "error",
        ray=args.ray,
        odom_drift=args.drift,
    )
    runs = [dataclasses.replace(base, latency=lat) for lat in latencies]
    try:  # every latency's suite, episodes and graphs are checked before the first episode runs
        prepared = [prepare(opts) for opts in runs]
    except UsageError as exc:
        print(f"go2vlm eval: {exc}", file=sys.stderr)
        return 2
    stop = ShutdownRequested()
    stop.install()
    session = None
    if base.ray is not None:  # one Ray for every run of the command, started when the first needs it
        from go2vlm.apps.episodes.cluster import RaySession

        session = RaySession(base.ray, base.workers, base.interface, base.log_level)
    code = 0
    try:
        for opts, prep in zip(runs, prepared, strict=True):
            code = max(code, _run_one(args, opts, prep, stop, run_eval, session))
            if stop.event.is_set() or code == 2:
                break
    finally:
        if session is not None:
            session.close()
    return code


def _run_one(args: argparse.Namespace, opts: Any, prep: Any, stop: Any, run_eval: Any, session: Any) -> int:
    from go2vlm.errors import UsageError

    try:
        outcome = run_eval(opts, stop, prep, session)
    except UsageError as exc:  # RobotLatched too
        print(f"go2vlm eval: {exc}", file=sys.stderr)
        return 2
    except RuntimeError as exc:
        print(f"go2vlm eval: {exc}", file=sys.stderr)
        return 1
    rate = 3600 * outcome.done / outcome.wall_s if outcome.wall_s > 0 else 0.0
    how = f"{args.workers} worker(s)" if opts.ray is None else f"Ray ({opts.ray})"
    lat = "" if opts.latency is None else f", answers {opts.latency:g} s late"
    lat += "" if opts.odom_drift is None else f", odometry drift {opts.odom_drift:g}"
    lat += "" if args.frontier is None else f", frontier {args.frontier}"
    print(
        f"go2vlm eval: run {outcome.run_id}: {outcome.done_before + outcome.done}/{outcome.total} episodes "
        f"({outcome.done} now, {rate:.0f} per hour with {how}{lat})"
    )
    group = outcome.group
    if group is not None:
        ci = group["success_rate_ci95"] or [0, 0]
        spl = "" if group["spl_mean"] is None else f", SPL {group['spl_mean']:.3f}"
        print(
            f"  success {group['success']}/{group['episodes']} = {100 * group['success_rate']:.1f} % "
            f"[95 % CI {100 * ci[0]:.1f}, {100 * ci[1]:.1f}]{spl}"
        )
    print(f"  wrote {args.out / 'results.jsonl'}, {args.out / 'summary.json'}, {args.out / 'report.md'}")
    for err in outcome.errors:
        print(f"go2vlm eval: episode failed: {err}", file=sys.stderr)
    if outcome.interrupted:
        print("go2vlm eval: interrupted; `--resume` with the same options finishes the run", file=sys.stderr)
        return stop.exit_code or 130
    return 1 if outcome.errors else 0


def _with_frontier(params: dict[str, dict[str, Any]], frontier: str | None) -> dict[str, dict[str, Any]]:
    """`--frontier` as the commander's frontier_choice (an explicit --param commander.frontier_choice wins)."""
    if frontier is not None:
        params.setdefault("commander", {}).setdefault("frontier_choice", frontier)
    return params
