"""Argument types shared by the verbs: a bad value is argparse's usage error (exit 2), not a hang."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

__all__ = ["add_dds_args", "add_node_params", "house_note", "non_negative", "node_params", "positive"]


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def positive(text: str) -> float:
    """A finite number > 0 (a duration, a rate)."""
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text} must be positive")
    return value


def non_negative(text: str) -> float:
    """A finite number >= 0 (a wait)."""
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text} must not be negative")
    return value


def add_dds_args(
    p: argparse.ArgumentParser,
    *,
    interface: str | None = None,
    interface_help: str = "network interface, e.g. lo or enp3s0 (env GO2VLM_IFACE)",
    domain_help: str = "DDS domain (default: ROS_DOMAIN_ID or 0)",
) -> None:
    """`--interface` and `--domain`, the DDS options every verb that joins the bus has (bus/domain.py)."""
    p.add_argument("--interface", default=interface, help=interface_help)
    p.add_argument("--domain", type=int, default=None, help=domain_help)


def add_node_params(p: argparse.ArgumentParser, help: str) -> None:
    """`--param/-p NODE.NAME=VALUE`, repeatable (demo, eval, launch); `node_params` reads them."""
    p.add_argument("--param", "-p", action="append", default=[], metavar="NODE.NAME=VALUE", help=help)


def node_params(items: list[str]) -> dict[str, dict[str, Any]]:
    """{node: {name: value}} from NODE.NAME=VALUE items; ParamError (exit 2) for a malformed one."""
    from go2vlm.bus import ParamError, parse_overrides

    out: dict[str, dict[str, Any]] = {}
    for item in items:
        name, sep, value = item.partition("=")
        node, dot, pname = name.partition(".")
        if not sep or not dot or not node or not pname:
            raise ParamError(f"--param {item!r}: expected NODE.NAME=VALUE, e.g. follower.kp_angular=1.0")
        out.setdefault(node.strip(), {}).update(parse_overrides([f"{pname}={value}"]))
    return out


def house_note(world: str, verb: str) -> None:
    """A generated house (`house:SEED`): made now (HouseError, exit 2, when it cannot be), and a line
    on stderr when its seed failed the check and the next seed's house is used."""
    from go2vlm.sim.houses import house_file, is_house

    if is_house(world):
        note = house_file(world)[1].note()
        if note:
            print(f"go2vlm {verb}: {note}", file=sys.stderr)
