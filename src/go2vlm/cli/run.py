"""`go2vlm run NODE [--param name=value ...] [--params-file F] [--remap from:=to ...]`."""

from __future__ import annotations

import argparse
import sys
import textwrap

from go2vlm.bus import describe_params, exit_code, parse_overrides, spin
from go2vlm.bus.runtime import stop_with_parent
from go2vlm.cli.args import add_dds_args, positive
from go2vlm.cli.view import add_foxglove_args, foxglove_params, make_view
from go2vlm.errors import ConfigError, UsageError
from go2vlm.launch.registry import NODES, make_node, node_class


def parse_remaps(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items:
        src, sep, dst = item.partition(":=")
        if not sep or not src or not dst:
            raise UsageError(f"--remap {item!r}: expected /from:=/to")
        out[src if src.startswith("/") else "/" + src] = dst if dst.startswith("/") else "/" + dst
    return out


def nodes_help() -> str:
    lines = ["nodes:"]
    for name in NODES:
        try:
            cls = node_class(name)
        except Exception as exc:  # a node whose optional extra is missing still gets listed
            lines.append(f"  {name}  (unavailable: {exc})")
            continue
        module_doc = sys.modules[cls.__module__].__doc__ or cls.__doc__ or ""
        lines.append(f"\n  {name}  ({cls.__module__}.{cls.__name__})")
        for line in textwrap.dedent(module_doc).strip().splitlines():
            lines.append("    " + line)
        rows = describe_params(cls.Config, base=True)
        if rows:
            lines.append("    parameters (name: type = default  help):")
            for pname, ptype, pdefault, phelp in rows:
                lines.append(f"      {pname}: {ptype} = {pdefault}  {phelp}".rstrip())
    return "\n".join(lines)


class _NodesHelp(argparse.RawDescriptionHelpFormatter):
    pass


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "run",
        help="run one node",
        description="Run one node by name. `go2vlm run --help` lists the nodes with topics and parameters.",
        formatter_class=_NodesHelp,
    )
    add_node_args(p)
    add_foxglove_args(p)
    p.add_argument("node", help=f"one of: {', '.join(NODES)}")
    p.set_defaults(func=run)
    # The node list imports every node module; build it only when help is asked for.
    p.format_help = lambda: argparse.ArgumentParser.format_help(p) + "\n" + nodes_help()  # type: ignore[method-assign]


def add_node_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--param", "-p", action="append", default=[], metavar="NAME=VALUE", help="set a parameter")
    p.add_argument("--params-file", default=None, help="ROS 2 params YAML file")
    p.add_argument("--remap", "-r", action="append", default=[], metavar="FROM:=TO", help="remap a topic")
    p.add_argument("--name", default=None, help="node name (default: the node kind)")
    add_dds_args(p)
    p.add_argument("--duration", type=positive, default=None, help="stop after this many seconds")


def run(args: argparse.Namespace) -> int:
    stop_with_parent()  # first: a node never outlives the launcher that started it
    try:
        node_class(args.node)
    except ValueError as exc:  # unknown node name: a message, not a traceback
        raise UsageError(str(exc)) from None
    except ImportError as exc:
        raise ConfigError(f"node {args.node!r} cannot be loaded: {exc}") from None
    node = make_node(
        args.node,
        params=parse_overrides(args.param),
        params_file=args.params_file,
        node_name=args.name,
        remap=parse_remaps(args.remap),
        domain_id=args.domain,
        interface=args.interface,
    )
    node.log.info(f"running (params: {node.params()})")
    nodes = [node]
    view = foxglove_params(args)
    if view is not None and args.node != "view":
        nodes.append(make_view(view, domain_id=args.domain, interface=args.interface))
    return exit_code(spin(nodes, duration_s=args.duration))
