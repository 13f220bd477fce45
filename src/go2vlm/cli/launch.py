"""`go2vlm launch FILE [--processes] [--duration S]`: start a set of nodes from a YAML launch file."""

from __future__ import annotations

import argparse
import os
import sys

from go2vlm.cli.args import add_dds_args, add_node_params, node_params, positive
from go2vlm.cli.view import add_foxglove_args, foxglove_params


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "launch",
        help="start a set of nodes from a launch file",
        description=(
            "Start the nodes of a YAML launch file (a path, or a packaged name such as follow_test_pattern). "
            "One process by default, each node on its own thread; --processes runs each node as its own "
            "`go2vlm run` child. Ctrl-C or SIGTERM stops everything."
        ),
    )
    p.add_argument("file", nargs="?", help="launch file path or packaged name")
    p.add_argument("--processes", action="store_true", help="one child process per node")
    p.add_argument("--duration", type=positive, default=None, help="stop after this many seconds")
    p.add_argument("--list", action="store_true", help="list the packaged launch files and exit")
    add_node_params(p, "override a node's parameter, e.g. -p vlm.base_url=http://gpu-box:8000/v1 (repeatable)")
    add_dds_args(
        p,
        interface_help="network interface for every node, e.g. lo or enp3s0",
        domain_help="DDS domain for every node (default: ROS_DOMAIN_ID)",
    )
    add_foxglove_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from go2vlm.launch.launcher import LaunchError, available, load_launch, run_in_process, run_processes

    # Through the environment, so in-process nodes and `--processes` children agree.
    if args.interface:
        os.environ["GO2VLM_IFACE"] = args.interface
    if args.domain is not None:
        os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    if args.list:
        for name in available():
            print(name)
        return 0
    if not args.file:
        print(f"go2vlm launch: give a launch file; packaged: {', '.join(available())}", file=sys.stderr)
        return 2
    from go2vlm.bus import ParamError
    from go2vlm.launch.launcher import with_overrides

    try:
        path, entries = load_launch(args.file)
        if args.param:
            entries = with_overrides(entries, node_params(args.param))
    except (LaunchError, ParamError) as exc:
        print(f"go2vlm launch: {exc}", file=sys.stderr)
        return 2
    view = foxglove_params(args)
    if view is not None:
        from go2vlm.launch.launcher import LaunchEntry

        entries.append(LaunchEntry("view", "foxglove_view", view))
    print(f"[launch] {path}: {', '.join(f'{e.name} ({e.kind})' for e in entries)}", flush=True)
    try:
        if args.processes:
            return run_processes(entries, args.duration, log_level=args.log_level)
        return run_in_process(entries, args.duration)
    except ImportError as exc:  # a node whose optional extra (sim, vlm) is not installed
        print(f"go2vlm launch: a node cannot be loaded: {exc}", file=sys.stderr)
        return 2
