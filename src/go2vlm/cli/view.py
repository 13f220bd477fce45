"""`go2vlm view [--port P] [--host H] [--publish [--token-file F] [--allow-origin O]]`: a Foxglove
WebSocket server for what is on the bus; with --publish, clients holding the token may also engage
the e-stop, teleop and confirm (apps/view/view_node.py, apps/view/front.py)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from go2vlm.apps.view.front import TOKEN_ENV
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
            f"and load {LAYOUT}. Clients publish nothing unless --publish: then, with the token "
            f"(${TOKEN_ENV} or --token-file; ws://HOST:PORT/?token=TOKEN), they may engage the e-stop (never "
            "release it), teleop on /teleop/cmd_vel and answer /mcp/confirm."
        ),
    )
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"port (default {DEFAULT_PORT}; 0: any free)")
    p.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1: this machine only)")
    add_publish_args(p, "")
    p.add_argument("--param", "-p", action="append", default=[], metavar="NAME=VALUE", help="a view parameter")
    p.add_argument("--duration", type=positive, default=None, help="stop after S seconds")
    add_dds_args(p)
    p.set_defaults(func=run)


def add_publish_args(p: argparse.ArgumentParser, prefix: str) -> None:
    """`--publish`, `--token-file`, `--allow-origin` (`--foxglove-publish`, ... with prefix "foxglove-")."""
    p.add_argument(
        f"--{prefix}publish", action="store_true",
        help=f"let Foxglove clients with the token engage the e-stop, teleop and confirm (the token: ${TOKEN_ENV} "
        f"or --{prefix}token-file; connect to ws://HOST:PORT/?token=TOKEN)",
    )  # fmt: skip
    p.add_argument(f"--{prefix}token-file", metavar="FILE", default=None, help="a file holding the clients' token")
    p.add_argument(
        f"--{prefix}allow-origin", metavar="ORIGIN", action="append", default=None,
        help="a web page (Origin, e.g. https://app.foxglove.dev) that may connect with --publish (repeatable; "
        "replaces the default https://app.foxglove.dev)",
    )  # fmt: skip


def publish_params(args: argparse.Namespace, prefix: str = "") -> dict[str, bool | str | list[str]]:
    """The view's publishing parameters from add_publish_args' options ({} when publishing is off)."""
    attr = prefix.replace("-", "_")
    if not getattr(args, f"{attr}publish", False):
        return {}
    params: dict[str, bool | str | list[str]] = {"allow_client_publish": True}
    if (token_file := getattr(args, f"{attr}token_file", None)) is not None:
        params["token_file"] = token_file
    if (origins := getattr(args, f"{attr}allow_origin", None)) is not None:
        params["allowed_origins"] = origins
    return params


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
    add_publish_args(p, "foxglove-")


def foxglove_params(args: argparse.Namespace) -> dict[str, Any] | None:
    """The view node's parameters from --foxglove, or None when it was not asked for."""
    if getattr(args, "foxglove", None) is None:
        return None
    return {"port": args.foxglove, "host": args.foxglove_host, **publish_params(args, "foxglove-")}


def make_view(params: dict[str, Any], **kwargs: Any) -> Any:
    """The view node; a ConfigError when foxglove-sdk is missing (a taken port is a ParamError)."""
    from go2vlm.launch.registry import make_node

    try:
        return make_node("view", params=params, **kwargs)
    except ImportError as exc:
        raise ConfigError(f"the Foxglove view needs the `view` extra (pip install 'go2vlm[view]'): {exc}") from None


def run(args: argparse.Namespace) -> int:
    from go2vlm.bus import parse_overrides, spin

    params = {"port": args.port, "host": args.host, **publish_params(args), **parse_overrides(args.param)}
    node = make_view(params, domain_id=args.domain, interface=args.interface)
    publish = "clients with the token may publish (?token=...)" if node.config.allow_client_publish else "view only"
    print(
        f"go2vlm view: Foxglove WebSocket on ws://{node.config.host}:{node.port} ({publish}); layout: {LAYOUT}. "
        "Ctrl-C stops.",
        file=sys.stderr,
        flush=True,
    )
    spin([node], duration_s=args.duration)
    return 0
