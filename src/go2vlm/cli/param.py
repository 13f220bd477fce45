"""`go2vlm param list | get | set | describe | dump NODE ...`: a node's parameters at runtime, like
`ros2 param`, through the ROS 2 parameter services over DDS (bus/param_services.py). It works on any
node that serves them: ours, and a ROS 2 node with rmw_cyclonedds_cpp.

    go2vlm param list follower
    go2vlm param get follower kp_angular
    go2vlm param set follower kp_angular 0.4
    go2vlm param set video_source width 640 height 480 --atomic
    go2vlm param describe safety max_vx_forward
    go2vlm param dump follower > follower.yaml        # then: go2vlm run follower --params-file follower.yaml

Exit status: 0; 2 for a parameter the node does not declare or a change it refuses (the reason is
printed); 1 when the node does not answer. Time here is wall time: `--timeout` bounds discovery and
each reply, for the person at the terminal.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import yaml

from go2vlm.cli.args import add_dds_args, positive


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("param", help="get and set a running node's parameters (like `ros2 param`)")
    verbs = p.add_subparsers(dest="verb", metavar="VERB", required=True)

    def verb(name: str, help_text: str) -> argparse.ArgumentParser:
        v = verbs.add_parser(name, help=help_text)
        v.add_argument("node", help="node name, e.g. follower or /follower")
        v.add_argument("--timeout", type=positive, default=5.0, help="seconds to wait for the node (default 5)")
        add_dds_args(v)
        return v

    ls = verb("list", "the node's parameter names")
    ls.add_argument("-t", "--param-type", action="store_true", help="also show each parameter's type")
    ls.set_defaults(func=cmd_list)
    get = verb("get", "a parameter's value")
    get.add_argument("name")
    get.add_argument("--hide-type", action="store_true", help="print only the value")
    get.set_defaults(func=cmd_get)
    st = verb("set", "set parameters: NAME VALUE [NAME VALUE ...] (VALUE as YAML: 0.4, true, [1, 2], text)")
    st.add_argument("pairs", nargs="+", metavar="NAME VALUE")
    st.add_argument("--atomic", action="store_true", help="all or none (SetParametersAtomically)")
    st.set_defaults(func=cmd_set)
    de = verb("describe", "type, description, range and whether it can change at runtime")
    de.add_argument("names", nargs="+", metavar="NAME")
    de.set_defaults(func=cmd_describe)
    du = verb("dump", "all parameters as a ROS 2 params file (what --params-file takes)")
    du.set_defaults(func=cmd_dump)


def _client(args: argparse.Namespace) -> Any:
    from go2vlm.bus import domain
    from go2vlm.bus.param_services import ParameterClient

    return ParameterClient(args.node, domain.participant(args.domain, args.interface), timeout_s=args.timeout)


def _run(args: argparse.Namespace, action: Any) -> int:
    from go2vlm.bus.service import ServiceError

    try:
        with _client(args) as client:
            return int(action(client) or 0)
    except ServiceError as exc:
        print(f"go2vlm: {exc}", file=sys.stderr)
        return 1


def cmd_list(args: argparse.Namespace) -> int:
    from go2vlm.msgs.rcl_interfaces import TYPE_NAMES

    def action(client: Any) -> None:
        names = client.list()
        kinds = client.types(names) if args.param_type and names else []
        for i, name in enumerate(names):
            print(f"  {name}" + (f" (type: {TYPE_NAMES.get(kinds[i], '?')})" if kinds else ""))

    return _run(args, action)


def cmd_get(args: argparse.Namespace) -> int:
    from go2vlm.bus.param_services import value_of
    from go2vlm.msgs.rcl_interfaces import PARAMETER_NOT_SET, TYPE_NAMES

    def action(client: Any) -> None:
        (pv,) = client.get([args.name])
        value = value_of(pv)
        if args.hide_type:
            print(value)
        elif pv.type == PARAMETER_NOT_SET:
            print("Parameter not set.")
        elif isinstance(value, list):
            print(f"{TYPE_NAMES[pv.type].replace(' array', '').capitalize()} values are: {value}")
        else:
            print(f"{TYPE_NAMES[pv.type].capitalize()} value is: {value}")

    return _run(args, action)


def cmd_set(args: argparse.Namespace) -> int:
    from go2vlm.bus.param_services import parse_value

    if len(args.pairs) % 2:
        print("go2vlm: param set: expected NAME VALUE pairs", file=sys.stderr)
        return 2
    pairs = dict(zip(args.pairs[::2], args.pairs[1::2], strict=True))

    def action(client: Any) -> int:
        # The declared types first, so that `0` for a double or `123` for a string mean what they say.
        declared = client.describe(list(pairs))
        values = {n: parse_value(text, d.type) for (n, text), d in zip(pairs.items(), declared, strict=True)}
        if args.atomic:
            results = [client.set_atomically(values)]
            names = [", ".join(values)]
        else:
            results, names = client.set(values), list(values)
        failed = 0
        for name, result in zip(names, results, strict=True):
            if result.successful:
                print(f"Set parameter {name} successful")
            else:
                failed += 1
                print(f"go2vlm: setting parameter {name} failed: {result.reason}", file=sys.stderr)
        return 2 if failed else 0

    return _run(args, action)


def cmd_describe(args: argparse.Namespace) -> int:
    from go2vlm.msgs.rcl_interfaces import TYPE_NAMES

    def action(client: Any) -> None:
        for d in client.describe(args.names):
            print(f"Parameter name: {d.name}")
            print(f"  Type: {TYPE_NAMES.get(d.type, '?')}")
            if d.description:
                print(f"  Description: {d.description}")
            print("  Constraints:")
            print(f"    Read only: {str(d.read_only).lower()}")
            for r in (*d.floating_point_range, *d.integer_range):
                print(f"    Min value: {r.from_value}")
                print(f"    Max value: {r.to_value}")
            if d.additional_constraints:
                print(f"    {d.additional_constraints}")

    return _run(args, action)


def cmd_dump(args: argparse.Namespace) -> int:
    from go2vlm.bus.param_services import value_of

    def action(client: Any) -> None:
        names = client.list()
        values = {}
        for name, pv in zip(names, client.get(names) if names else [], strict=True):
            value = value_of(pv)
            values[name] = list(value) if isinstance(value, bytes) else value
        doc = {client.node: {"ros__parameters": values}}
        sys.stdout.write(
            yaml.safe_dump(doc, default_flow_style=False, sort_keys=True, allow_unicode=True, width=1 << 30)
        )

    return _run(args, action)
