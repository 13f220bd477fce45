"""Typed node parameters: a dataclass per node, filled from defaults, a ROS 2 params file and
`--param name=value` overrides, validated at start-up, and again by the same rules (build_config)
for every change at runtime (bus/param_services.py; only parameters declared `live=True` change).

    @dataclass
    class FollowerConfig:
        kp_angular: float = param(0.8, help="P gain on the horizontal error", min=0.0)

A bad value is a `ParamError` naming the node, the parameter, the value and what was expected.

A node over a pure core takes each setting the core declares (go2vlm/declare.py: default, help,
bounds, live, written once on the core's field) with `from_core`, and builds the core's params from its
config with `core_params`:

    @dataclass
    class TargetTrackerConfig:
        min_shape_score: float = from_core(TrackingParams, "min_shape_score")

        def tracking_params(self) -> TrackingParams:
            return core_params(TrackingParams, self, camera_height_m=profile(self.robot).head_camera_height)
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import yaml

from go2vlm.declare import CORE, from_core, param
from go2vlm.errors import ConfigError

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

__all__ = [
    "BASE_PARAMS",
    "NodeParams",
    "ParamError",
    "build_config",
    "build_node_config",
    "core_params",
    "core_values",
    "describe_params",
    "from_core",
    "load_params_file",
    "loosened",
    "param",
    "parse_overrides",
]


T = TypeVar("T")


class ParamError(ConfigError):
    """A parameter value that is missing, of the wrong type or out of range."""


def _parse_scalar(text: str) -> Any:
    try:
        return yaml.safe_load(text) if text.strip() else ""
    except yaml.YAMLError:
        return text


def _is_optional(tp: Any) -> tuple[bool, Any]:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return True, args[0]
    return False, tp


def coerce(value: Any, tp: Any, where: str) -> Any:
    """Convert `value` to the annotated type `tp` or raise ParamError."""
    optional, inner = _is_optional(tp)
    if value is None:
        if optional:
            return None
        raise ParamError(f"{where}: null is not allowed (expected {_type_name(tp)})")
    tp = inner
    origin = typing.get_origin(tp)
    if origin in (list, tuple):
        (item_tp, *_) = typing.get_args(tp) or (Any,)
        if isinstance(value, str):
            parsed = _parse_scalar(value)
            value = parsed if isinstance(parsed, list) else [v.strip() for v in value.split(",") if v.strip()]
        if not isinstance(value, (list, tuple)):
            raise ParamError(f"{where}: {value!r} is not a list (expected {_type_name(tp)})")
        items = [coerce(v, item_tp, f"{where}[{i}]") for i, v in enumerate(value)]
        return items if origin is list else tuple(items)
    if origin is dict or tp is dict:
        if isinstance(value, str):
            value = _parse_scalar(value)
        if not isinstance(value, dict):
            raise ParamError(f"{where}: {value!r} is not a mapping")
        return dict(value)
    if tp is Any:
        return value
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        if isinstance(value, tp):
            return value
        if isinstance(value, str):
            value = _parse_scalar(value)
        if not isinstance(value, Mapping):
            raise ParamError(f"{where}: {value!r} is not a mapping of {tp.__name__} fields")
        return build_config(tp, value, node=where)
    if tp is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.strip().lower() in ("true", "false", "1", "0", "yes", "no", "on", "off"):
            return value.strip().lower() in ("true", "1", "yes", "on")
        if isinstance(value, int) and value in (0, 1):
            return bool(value)
        raise ParamError(f"{where}: {value!r} is not a bool (expected true or false)")
    if tp is int:
        if isinstance(value, bool):
            raise ParamError(f"{where}: {value!r} is not an int")
        if isinstance(value, str):
            value = _parse_scalar(value)
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if not isinstance(value, int) or isinstance(value, bool):
            raise ParamError(f"{where}: {value!r} is not an int")
        return value
    if tp is float:
        if isinstance(value, str):
            parsed = _parse_scalar(value)
            value = parsed if isinstance(parsed, (int, float)) else value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError(f"{where}: {value!r} is not a number")
        value = float(value)
        if not math.isfinite(value):
            raise ParamError(f"{where}: {value!r} is not a finite number")
        return value
    if tp is str:
        if isinstance(value, (dict, list)):
            raise ParamError(f"{where}: {value!r} is not a string")
        return value if isinstance(value, str) else str(value)  # keeps str subclasses (a masked Secret)
    raise ParamError(f"{where}: unsupported parameter type {_type_name(tp)}")


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")


def _validate(field: dataclasses.Field[Any], value: Any, where: str) -> None:
    meta = field.metadata
    choices, lo, hi = meta.get("choices"), meta.get("min"), meta.get("max")
    if choices is not None and value is not None and value not in choices:
        raise ParamError(f"{where}: {value!r} is not one of {list(choices)}")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if lo is not None and value < lo:
            raise ParamError(f"{where}: {value!r} is below the minimum {lo}")
        if hi is not None and value > hi:
            raise ParamError(f"{where}: {value!r} is above the maximum {hi}")


def build_config(
    config_cls: type, values: Mapping[str, Any], node: str = "node", also_known: Iterable[str] = ()
) -> Any:
    """Instantiate `config_cls` from raw values (strings or YAML types), validating every field.
    `also_known`: names accepted elsewhere (the base parameters), listed when a name is unknown."""
    if not dataclasses.is_dataclass(config_cls):
        raise TypeError(f"{config_cls!r} is not a dataclass")
    hints = typing.get_type_hints(config_cls)
    fields = {f.name: f for f in dataclasses.fields(config_cls)}
    unknown = sorted(set(values) - set(fields))
    if unknown:
        known = sorted({*fields, *also_known})
        raise ParamError(f"node {node!r}: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(known)}")
    kwargs = {}
    for name, raw in values.items():
        kwargs[name] = coerce(raw, hints[name], f"node {node!r}: parameter {name!r}")
    try:
        cfg = config_cls(**kwargs)
    except ParamError:
        raise
    except (TypeError, ValueError) as exc:
        raise ParamError(f"node {node!r}: {exc}") from None
    for name, field in fields.items():
        _validate(field, getattr(cfg, name), f"node {node!r}: parameter {name!r}")
    check: Callable[[], None] | None = getattr(cfg, "validate", None)
    if check is not None:
        try:
            check()
        except ParamError:
            raise
        except ValueError as exc:
            raise ParamError(f"node {node!r}: {exc}") from None
    return cfg


def loosened(old: DataclassInstance, new: DataclassInstance, names: Iterable[str]) -> list[str]:
    """The safety limits among `names` that `new` loosens against `old` ("max_goal_s 900 -> 3600"):
    a `bound="max"` parameter raised, a `bound="min"` one lowered. The one rule for limits at runtime:
    they only tighten while a node runs (bus/param_services.py refuses the change otherwise)."""
    fields = {f.name: f for f in dataclasses.fields(old)}
    out = []
    for name in names:
        bound = fields[name].metadata.get("bound") if name in fields else None
        before, after = getattr(old, name), getattr(new, name)
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (before, after)):
            continue
        if (bound == "max" and after > before) or (bound == "min" and after < before):
            out.append(f"{name} {before:g} -> {after:g}")
    return out


def loosening_refused(node: str, loose: list[str]) -> str:
    """The reason a change that loosens limits is refused (see `loosened`)."""
    return (
        f"loosening a safety limit at runtime is refused ({', '.join(loose)}): a limit only tightens while "
        f"node {node!r} runs; loosening it takes a restart"
    )


@dataclasses.dataclass
class NodeParams:
    """Parameters every node has, whatever its own Config declares (as ROS 2 declares use_sim_time on
    every node). `build_node_config` splits them off; `Node` takes them as keyword arguments."""

    use_sim_time: bool = param(
        False, help="run on /clock (rosgraph_msgs/Clock) instead of the wall clock: stamps, timers, timeouts"
    )


BASE_PARAMS = frozenset(f.name for f in dataclasses.fields(NodeParams))


def build_node_config(config_cls: type, values: Mapping[str, Any], node: str = "node") -> tuple[Any, NodeParams]:
    """A node's own Config and its base parameters (`NodeParams`) from one mapping of raw values."""
    clash = BASE_PARAMS & {f.name for f in dataclasses.fields(config_cls)}
    if clash:
        raise TypeError(f"{config_cls.__name__} declares base parameter(s) {sorted(clash)}; Node handles them")
    own = {k: v for k, v in values.items() if k not in BASE_PARAMS}
    base = {k: v for k, v in values.items() if k in BASE_PARAMS}
    return build_config(config_cls, own, node, also_known=BASE_PARAMS), build_config(NodeParams, base, node)


def core_values(core_cls: type, config: Any) -> dict[str, Any]:
    """The values of a pure core's fields in a node's config, by the core's names: every config field
    taken over from the core (`from_core`, under its own name or another), and every other field of
    the core that the config has under the same name."""
    own = {f.name for f in dataclasses.fields(config)}
    values = {f.name: getattr(config, f.name) for f in dataclasses.fields(core_cls) if f.init and f.name in own}
    for f in dataclasses.fields(config):
        link = f.metadata.get(CORE)
        if link is not None and link[0] is core_cls:
            values[link[1]] = getattr(config, f.name)
    return values


def core_params(core_cls: type[T], config: Any, **given: Any) -> T:
    """An instance of a pure core's params dataclass from a node's config: its `core_values`, then
    `given` (what the node derives differently)."""
    return core_cls(**{**core_values(core_cls, config), **given})


def load_params_file(path: str | Path, node: str) -> dict[str, Any]:
    """Parameters for `node` from a ROS 2 params file (`node: {ros__parameters: {...}}`, `/**` too)."""
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text()) or {}
    except FileNotFoundError:
        raise ParamError(f"params file {str(p)!r} does not exist") from None
    except yaml.YAMLError as exc:
        raise ParamError(f"params file {str(p)!r} is not valid YAML: {exc}") from None
    if not isinstance(doc, dict):
        raise ParamError(f"params file {str(p)!r}: top level must be a mapping of node names")
    out: dict[str, Any] = {}
    for key in ("/**", "**", node, "/" + node):
        section = doc.get(key)
        if section is None:
            continue
        if not isinstance(section, dict) or not isinstance(section.get("ros__parameters", {}), dict):
            raise ParamError(f"params file {str(p)!r}: section {key!r} must hold 'ros__parameters: {{...}}'")
        out.update(section.get("ros__parameters", {}))
    return out


def parse_overrides(items: Iterable[str]) -> dict[str, Any]:
    """`["kp=0.5", "labels=[a, b]"]` -> {"kp": 0.5, "labels": ["a", "b"]}."""
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise ParamError(f"--param {item!r}: expected name=value")
        name, _, raw = item.partition("=")
        name = name.strip()
        if not name.isidentifier():
            raise ParamError(f"--param {item!r}: {name!r} is not a parameter name")
        out[name] = _parse_scalar(raw)
    return out


def describe_params(config_cls: type, base: bool = False) -> list[tuple[str, str, str, str]]:
    """(name, type, default, help) rows for `--help` and docs; `base` appends the `NodeParams` rows.
    The help of a parameter that may change at runtime ends with `(live: ...)`."""
    hints = typing.get_type_hints(config_cls)
    rows = []
    for f in dataclasses.fields(config_cls):
        if f.default is not dataclasses.MISSING:
            default = repr(f.default)
        elif f.default_factory is not dataclasses.MISSING:
            default = repr(f.default_factory())
        else:
            default = "(required)"
        help_text = f.metadata.get("help", "")
        if f.metadata.get("choices"):
            help_text += f" [{'|'.join(map(str, f.metadata['choices']))}]"
        if f.metadata.get("live"):
            help_text += {"max": " (live, lowered only)", "min": " (live, raised only)"}.get(
                f.metadata.get("bound") or "", " (live)"
            )
        rows.append((f.name, _type_name(hints[f.name]), default, help_text))
    return rows + (describe_params(NodeParams) if base else [])
