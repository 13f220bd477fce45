"""How a parameter is declared, once.

`param(default, help=..., min=..., max=..., choices=..., live=...)` declares a dataclass field with
what a node needs to know of it. A pure core declares its own settings this way (a frozen params
dataclass), and a node's config takes each of them over with `from_core(Core, "field")`: the same
default, help, bounds and live flag, and a link back that `bus.core_params` follows to build the
core's params from the config. So a setting that a core and its node share is written once, on the
core; the node adds only what is its own (topics, rates, the robot).

    @dataclass(frozen=True)
    class GuardConfig:
        margin: float = param(0.3, help="guard: stop this far (m) short of any obstacle", min=0.0, max=3.0)

    @dataclass
    class SafetyGateConfig:
        margin: float = from_core(GuardConfig, "margin")

Imports nothing of the project: cores on any floor may use it without pulling in the bus.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any

__all__ = ["BOUNDS", "CORE", "from_core", "param"]

CORE = "core"  # metadata key of a node parameter taken over from a core: (core class, its field name)
# `bound=`: "max", a ceiling (a speed, a time, a distance) that may only go down while the node runs;
# "min", a floor (a margin) that may only go up. bus/params.py `loosened` is the rule.
BOUNDS = ("max", "min")


def param(
    default: Any = dataclasses.MISSING,
    *,
    help: str = "",
    choices: Iterable[Any] | None = None,
    min: float | None = None,
    max: float | None = None,
    live: bool = False,
    bound: str | None = None,
) -> Any:
    """Declare a parameter. A factory default (`list`, `dict`, `tuple` or a dataclass) makes a fresh
    value for every config; a dataclass-typed parameter is set from a mapping of its fields.

    `live=True`: the parameter may change while the node runs (`go2vlm param set`, `ros2 param set`),
    because the node reads it from `self.config` each time or rebuilds what it derives from it in
    `on_params_changed`. Every other parameter is read-only at runtime (DescribeParameters says so and
    a change is refused): a value read once at start-up can never silently accept a new one.

    `bound="max"` (or "min"): the parameter is a safety limit. While the node runs it may only tighten
    (go down, or up for "min"); loosening it takes a restart, a deliberate act (bus/params.py)."""
    if bound not in (None, *BOUNDS):
        raise TypeError(f"bound={bound!r}: expected one of {BOUNDS} or None")
    meta = {
        "help": help,
        "choices": tuple(choices) if choices is not None else None,
        "min": min,
        "max": max,
        "live": live,
        "bound": bound,
    }
    if default in (list, dict, tuple) or (isinstance(default, type) and dataclasses.is_dataclass(default)):
        return dataclasses.field(default_factory=default, metadata=meta)
    if isinstance(default, (list, dict)):
        value = default
        return dataclasses.field(default_factory=lambda: type(value)(value), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def from_core(core: type, name: str, **changes: object) -> Any:
    """A node parameter that is `core`'s field `name`: its default, help, bounds and live flag, as the
    core declares them with `param`. `changes` overrides one of those (e.g. a node-side `live=True`)
    where the node's use differs; a link to the core's field goes with it (`CORE`)."""
    fields = {f.name: f for f in dataclasses.fields(core)}
    if name not in fields:
        raise TypeError(f"{core.__name__} has no field {name!r}")
    f = fields[name]
    if not f.metadata.get("help"):
        raise TypeError(f"{core.__name__}.{name} is not declared with param(..., help=...)")
    unknown = set(changes) - {"help", "choices", "min", "max", "live", "bound"}
    if unknown:
        raise TypeError(f"from_core: unknown change(s) {sorted(unknown)}")
    meta = {**f.metadata, **changes, CORE: (core, name)}
    if f.default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=f.default_factory, metadata=meta)
    return dataclasses.field(default=f.default, metadata=meta)
