"""`go2vlm view [--port P] [--host H]`: a Foxglove WebSocket server for what is on the bus."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from go2vlm.cli.args import add_dds_args, positive
from go2vlm.errors import ConfigError

DEFAULT_PORT = 8765
LAYOUT = "docs/foxglove/go2vlm_layout.json"


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "view",
        help="show the robot live in Foxglove (WebSocket server, foxglove-sdk)",
        description=(
            "Serve what is on the bus to Foxglove (or Lichtblick): camera images as JPEG, detections as image "
            "annotations, /tf, /odom, /cmd_vel, statuses. Connect with 'Open connection -> Foxglove WebSocket' "
            f"and load {LAYOUT}. Clients may publish only the e-stop, its release and /teleop/cmd_vel."
        ),
    )
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"port (default {DEFAULT_PORT}; 0: any free)")
    p.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1: this machine only)")
    p.add_argument("--param", "-p", action="append", default=[], metavar="NAME=VALUE", help="a view parameter")
    p.add_argument("--duration", type=positive, default=None, help="stop after S seconds")
    add_dds_args(p)
    p.set_defaults(func=run)


def add_foxglove_args(p: argparse.ArgumentParser) -> None:
    """`--foxglove [PORT]` and `--foxglove-host` for launch, run and sim."""
    p.add_argument(
        "--foxglove",
        nargs="?",
        type=int,
        const=DEFAULT_PORT,
        default=None,
        metavar="PORT",
        help=f"also serve Foxglove on PORT (default {DEFAULT_PORT}); see `go2vlm view`",
    )
    p.add_argument(
        "--foxglove-host", default="127.0.0.1", help="address for --foxglove (default 127.0.0.1: this machine only)"
    )


def foxglove_params(args: argparse.Namespace) -> dict[str, Any] | None:
    """The view node's parameters from --foxglove, or None when it was not asked for."""
    if getattr(args, "foxglove", None) is None:
        return None
    return {"port": args.foxglove, "host": args.foxglove_host}


def make_view(params: dict[str, Any], **kwargs: Any) -> Any:
    """The view node; a ConfigError when foxglove-sdk is missing (a taken port is a ParamError)."""
    from go2vlm.launch.registry import make_node

    try:
        return make_node("view", params=params, **kwargs)
    except ImportError as exc:
        raise ConfigError(f"the Foxglove view needs the `view` extra (pip install 'go2vlm[view]'): {exc}") from None


def run(args: argparse.Namespace) -> int:
    from go2vlm.bus import parse_overrides, spin

    params = {"port": args.port, "host": args.host, **parse_overrides(args.param)}
    node = make_view(params, domain_id=args.domain, interface=args.interface)
    print(
        f"go2vlm view: Foxglove WebSocket on ws://{node.config.host}:{node.port}; layout: {LAYOUT}. Ctrl-C stops.",
        file=sys.stderr,
        flush=True,
    )
    spin([node], duration_s=args.duration)
    return 0
