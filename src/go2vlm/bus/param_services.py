"""ROS 2 parameters at runtime: every Node serves rclcpp's parameter services over DDS, and
`ParameterClient` calls them (`go2vlm param`, tests).

Services of a node `/follower` (rcl_interfaces/srv, on the wire as rmw_cyclonedds_cpp puts them, see
bus/service.py): `~/list_parameters`, `~/get_parameters`, `~/set_parameters`,
`~/set_parameters_atomically`, `~/describe_parameters`, `~/get_parameter_types`; every accepted
change is also published on `/parameter_events` (rcl_interfaces/msg/ParameterEvent), as rclcpp does.

The parameters are the node's Config fields plus the base parameters (`use_sim_time`). Types map
onto ROS parameter types: bool, int, float, str, bytes and lists of one of bool/int/float/str are
ROS booleans, integers, doubles, strings, byte arrays and arrays (Optional ones read "not set" when
None); anything else (a list of mappings such as the safety gate's `inputs`, a mapping, nested
lists) is a string holding YAML text, which `--param` and `--params-file` accept as well.

A change goes through the same rules as start-up: the value must have the parameter's type (an
integer is accepted for a double), then `build_config` checks the whole new Config (types,
choices, min/max, the Config's validate()), then a safety limit (`param(..., bound="max" | "min")`)
that would loosen is refused, one rule for every node (`params.loosened`), then the node's
`check_params` may refuse it. Only parameters declared `param(..., live=True)` may change; the rest,
and `use_sim_time`, are read-only (DescribeParameters reports read_only). A refused change leaves the
node as it was and says why in SetParametersResult.reason. An accepted one replaces `node.config`
with the new Config object in one assignment (worker threads see the old or the new one, never a
mix), then the node's `on_params_changed` rebuilds what it derived from them. Requests are handled
on the node's executor thread, between its callbacks, so node code needs no locks for this either.
"""

from __future__ import annotations

import builtins
import dataclasses
import math
import typing
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import yaml

from go2vlm.bus import domain
from go2vlm.bus.endpoints import Publisher
from go2vlm.bus.log import Logger
from go2vlm.bus.params import (
    NodeParams,
    ParamError,
    _is_optional,
    _type_name,
    build_config,
    loosened,
    loosening_refused,
)
from go2vlm.bus.qos import QOS_PARAMETERS, QosProfile
from go2vlm.bus.service import Service, ServiceClient, ServiceError, SrvType
from go2vlm.msgs import rcl_interfaces as rcl
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.rcl_interfaces import (
    PARAMETER_BOOL,
    PARAMETER_BOOL_ARRAY,
    PARAMETER_BYTE_ARRAY,
    PARAMETER_DOUBLE,
    PARAMETER_DOUBLE_ARRAY,
    PARAMETER_INTEGER,
    PARAMETER_INTEGER_ARRAY,
    PARAMETER_NOT_SET,
    PARAMETER_STRING,
    PARAMETER_STRING_ARRAY,
    TYPE_NAMES,
    Parameter,
    ParameterDescriptor,
    ParameterEvent,
    ParameterValue,
    SetParametersResult,
)

if TYPE_CHECKING:
    from cyclonedds.domain import DomainParticipant

M = TypeVar("M")

__all__ = [
    "ParameterClient",
    "ParameterServer",
    "describe",
    "from_value",
    "param_kind",
    "parse_value",
    "python_to_value",
    "to_value",
    "value_of",
]

_SCALARS = {bool: PARAMETER_BOOL, int: PARAMETER_INTEGER, float: PARAMETER_DOUBLE, str: PARAMETER_STRING}
_ARRAYS = {
    bool: PARAMETER_BOOL_ARRAY,
    int: PARAMETER_INTEGER_ARRAY,
    float: PARAMETER_DOUBLE_ARRAY,
    str: PARAMETER_STRING_ARRAY,
}
# A value of the second type is accepted for a parameter of the first (an integer for a double).
_WIDENS = {(PARAMETER_DOUBLE, PARAMETER_INTEGER), (PARAMETER_DOUBLE_ARRAY, PARAMETER_INTEGER_ARRAY)}
_INT64 = (-(2**63), 2**63 - 1)


# -- values ----------------------------------------------------------------------------------------
def param_kind(tp: Any) -> tuple[int, bool]:
    """(ROS ParameterType code, is YAML text) for a Config field's annotated type."""
    _, inner = _is_optional(tp)
    if inner in _SCALARS:
        return _SCALARS[inner], False
    if inner is bytes:
        return PARAMETER_BYTE_ARRAY, False
    if typing.get_origin(inner) in (list, tuple):
        items = {a for a in typing.get_args(inner) if a is not Ellipsis}
        if len(items) == 1:
            item = items.pop()
            if item in _ARRAYS:
                return _ARRAYS[item], False
    return PARAMETER_STRING, True


def yaml_text(value: Any) -> str:
    """One line of YAML flow text for a structured value (what a YAML-text parameter holds)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = dataclasses.asdict(value)
    if isinstance(value, tuple):
        value = list(value)
    return yaml.safe_dump(value, default_flow_style=True, width=1 << 30, allow_unicode=True).strip()


def _a(noun: str) -> str:
    return ("an " if noun[:1] in "aeiou" else "a ") + noun


def _yaml_type_name(tp: Any) -> str:
    return str(tp).replace("typing.", "") if typing.get_origin(tp) else _type_name(tp)


def to_value(value: Any, tp: Any) -> ParameterValue:
    """A Config value as a ParameterValue of its declared type."""
    kind, is_yaml = param_kind(tp)
    if value is None:
        return ParameterValue(type=PARAMETER_NOT_SET)
    if is_yaml:
        return ParameterValue(type=PARAMETER_STRING, string_value=yaml_text(value))
    return _make_value(kind, value)


def _make_value(kind: int, value: Any) -> ParameterValue:
    if kind == PARAMETER_BOOL:
        return ParameterValue(type=kind, bool_value=bool(value))
    if kind == PARAMETER_INTEGER:
        return ParameterValue(type=kind, integer_value=int(value))
    if kind == PARAMETER_DOUBLE:
        return ParameterValue(type=kind, double_value=float(value))
    if kind == PARAMETER_STRING:
        return ParameterValue(type=kind, string_value=str(value))
    if kind == PARAMETER_BYTE_ARRAY:
        return ParameterValue(type=kind, byte_array_value=bytes(value))
    if kind == PARAMETER_BOOL_ARRAY:
        return ParameterValue(type=kind, bool_array_value=[bool(v) for v in value])
    if kind == PARAMETER_INTEGER_ARRAY:
        return ParameterValue(type=kind, integer_array_value=[int(v) for v in value])
    if kind == PARAMETER_DOUBLE_ARRAY:
        return ParameterValue(type=kind, double_array_value=[float(v) for v in value])
    if kind == PARAMETER_STRING_ARRAY:
        return ParameterValue(type=kind, string_array_value=[str(v) for v in value])
    return ParameterValue(type=PARAMETER_NOT_SET)


def value_of(pv: ParameterValue) -> Any:
    """The Python value a ParameterValue carries (None when not set)."""
    return {
        PARAMETER_BOOL: lambda: pv.bool_value,
        PARAMETER_INTEGER: lambda: pv.integer_value,
        PARAMETER_DOUBLE: lambda: pv.double_value,
        PARAMETER_STRING: lambda: pv.string_value,
        PARAMETER_BYTE_ARRAY: lambda: bytes(pv.byte_array_value),
        PARAMETER_BOOL_ARRAY: lambda: list(pv.bool_array_value),
        PARAMETER_INTEGER_ARRAY: lambda: list(pv.integer_array_value),
        PARAMETER_DOUBLE_ARRAY: lambda: list(pv.double_array_value),
        PARAMETER_STRING_ARRAY: lambda: list(pv.string_array_value),
    }.get(pv.type, lambda: None)()


def from_value(pv: ParameterValue, tp: Any, name: str) -> Any:
    """The value a SetParameters request carries for a field of type `tp`; ParamError if its ROS type
    is not the parameter's. The result still goes through build_config (coercion and limits)."""
    kind, is_yaml = param_kind(tp)
    if pv.type == PARAMETER_NOT_SET:
        if _is_optional(tp)[0]:
            return None
        raise ParamError(f"parameter {name!r} cannot be unset: it is {_a(TYPE_NAMES[kind])}")
    if pv.type != kind and (kind, pv.type) not in _WIDENS:
        what = TYPE_NAMES.get(pv.type, f"type {pv.type}")
        text = f" (YAML text of a {_yaml_type_name(tp)})" if is_yaml else ""
        raise ParamError(
            f"wrong parameter type: {name!r} is {_a(TYPE_NAMES[kind])}{text}, setting it to {_a(what)} is not allowed"
        )
    return value_of(pv)


def python_to_value(value: Any) -> ParameterValue:
    """A ParameterValue for a plain value, its ROS type inferred as `ros2 param set` infers it from
    YAML; a value no ROS type holds (a mapping, nested lists) becomes YAML text."""
    if value is None:
        return ParameterValue(type=PARAMETER_NOT_SET)
    for py, kind in _SCALARS.items():
        if type(value) is py:
            return _make_value(kind, value)
    if isinstance(value, (bytes, bytearray)):
        return _make_value(PARAMETER_BYTE_ARRAY, value)
    if isinstance(value, (list, tuple)) and value:
        kinds = {type(v) for v in value}
        if kinds in ({bool}, {int}, {str}):
            return _make_value(_ARRAYS[kinds.pop()], value)
        if kinds <= {int, float}:
            return _make_value(PARAMETER_DOUBLE_ARRAY, value)
    return ParameterValue(type=PARAMETER_STRING, string_value=yaml_text(value))


def parse_value(text: str, declared: int) -> ParameterValue:
    """Command-line text as a ParameterValue for a parameter of ROS type `declared`: YAML, as
    `ros2 param set` reads it, except that text for a string parameter stays text (`123`, or the YAML
    of a structured parameter) and a whole number for a double is a double."""
    try:
        parsed = yaml.safe_load(text) if text.strip() else ""
    except yaml.YAMLError:
        parsed = text
    if declared == PARAMETER_STRING:
        return ParameterValue(type=PARAMETER_STRING, string_value=parsed if isinstance(parsed, str) else text)
    if declared == PARAMETER_DOUBLE and type(parsed) is int:
        return _make_value(PARAMETER_DOUBLE, parsed)
    if declared == PARAMETER_DOUBLE_ARRAY and isinstance(parsed, list) and {type(v) for v in parsed} <= {int, float}:
        return _make_value(PARAMETER_DOUBLE_ARRAY, parsed)
    return python_to_value(parsed)


def describe(field: dataclasses.Field[Any], tp: Any, read_only: bool) -> ParameterDescriptor:
    kind, is_yaml = param_kind(tp)
    meta = field.metadata
    notes = []
    if meta.get("choices"):
        notes.append("one of: " + ", ".join(map(str, meta["choices"])))
    if is_yaml:
        notes.append(f"YAML text of a {_yaml_type_name(tp)}")
    if read_only:
        notes.append("read-only at runtime: the node reads it at start-up; restart it to change it")
    d = ParameterDescriptor(
        name=field.name,
        type=kind,
        description=meta.get("help", ""),
        additional_constraints="; ".join(notes),
        read_only=read_only,
    )
    lo, hi = meta.get("min"), meta.get("max")
    if (lo is not None or hi is not None) and kind == PARAMETER_DOUBLE:
        lo_f = -math.inf if lo is None else float(lo)
        hi_f = math.inf if hi is None else float(hi)
        d.floating_point_range = [rcl.FloatingPointRange(from_value=lo_f, to_value=hi_f, step=0.0)]
    elif (lo is not None or hi is not None) and kind == PARAMETER_INTEGER:
        lo_i = _INT64[0] if lo is None else math.ceil(lo)
        hi_i = _INT64[1] if hi is None else math.floor(hi)
        d.integer_range = [rcl.IntegerRange(from_value=lo_i, to_value=hi_i, step=0)]
    return d


def node_service(node: str, service: str) -> str:
    """`follower`, `get_parameters` -> `/follower/get_parameters`."""
    return "/" + node.strip().strip("/") + "/" + service


# -- the server ------------------------------------------------------------------------------------
class ParamHost(Protocol):
    """What the parameter services need of their node (a Node, bus/node.py)."""

    config: Any
    node_name: str
    log: Logger

    @property
    def fully_qualified_name(self) -> str: ...
    def count(self, name: str, n: int = 1) -> int: ...
    def params(self) -> dict[str, Any]: ...
    def check_params(self, new: Any, changed: frozenset[str]) -> None: ...
    def on_params_changed(self, old: Any, changed: frozenset[str]) -> None: ...
    def stamp(self, t: float | None = None) -> Time: ...
    def create_publisher(self, msg_type: type[M], topic: str, qos: QosProfile = ...) -> Publisher[M]: ...
    def create_service(
        self, srv_type: SrvType[Any, Any], name: str, handler: Callable[[Any], Any], qos: QosProfile = ...
    ) -> Service[Any, Any]: ...


class ParameterServer:
    """A node's parameter services (made by Node.__init__ unless parameter_services=False)."""

    def __init__(self, node: ParamHost) -> None:
        self.node = node
        cfg_cls = type(node.config)
        own = dataclasses.fields(cfg_cls) if dataclasses.is_dataclass(cfg_cls) else ()
        hints = typing.get_type_hints(cfg_cls) if own else {}
        base_hints = typing.get_type_hints(NodeParams)
        # name -> (field, annotated type, is a base parameter)
        self.fields: dict[str, tuple[dataclasses.Field[Any], Any, bool]] = {
            f.name: (f, hints[f.name], False) for f in own
        }
        for f in dataclasses.fields(NodeParams):
            self.fields[f.name] = (f, base_hints[f.name], True)
        self.events = node.create_publisher(ParameterEvent, "/parameter_events", QOS_PARAMETERS)
        for name, srv in rcl.PARAMETER_SERVICES.items():
            node.create_service(srv, f"~/{name}", getattr(self, name), QOS_PARAMETERS)

    def read_only(self, name: str) -> bool:
        field, _, base = self.fields[name]
        return base or not field.metadata.get("live", False)

    def _value(self, name: str, values: dict[str, Any]) -> ParameterValue:
        return to_value(values[name], self.fields[name][1])

    # Unknown names make the whole answer empty, as rclcpp's ParameterService answers.
    def get_parameters(self, req: rcl.GetParameters_Request) -> rcl.GetParameters_Response:
        if not set(req.names) <= set(self.fields):
            return rcl.GetParameters_Response()
        values = self.node.params()
        return rcl.GetParameters_Response(values=[self._value(n, values) for n in req.names])

    def get_parameter_types(self, req: rcl.GetParameterTypes_Request) -> rcl.GetParameterTypes_Response:
        if not set(req.names) <= set(self.fields):
            return rcl.GetParameterTypes_Response()
        return rcl.GetParameterTypes_Response(types=bytes(param_kind(self.fields[n][1])[0] for n in req.names))

    def describe_parameters(self, req: rcl.DescribeParameters_Request) -> rcl.DescribeParameters_Response:
        if not set(req.names) <= set(self.fields):
            return rcl.DescribeParameters_Response()
        return rcl.DescribeParameters_Response(
            descriptors=[describe(self.fields[n][0], self.fields[n][1], self.read_only(n)) for n in req.names]
        )

    def list_parameters(self, req: rcl.ListParameters_Request) -> rcl.ListParameters_Response:
        # rclcpp's rule: names under each prefix ("a.b" is under "a"), `depth` levels deep (0 = all).
        out = rcl.ListParametersResult()
        depth = req.depth

        def shallow(rest: str) -> bool:
            return depth == rcl.DEPTH_RECURSIVE or rest.count(".") < depth

        for name in sorted(self.fields):
            everything = not req.prefixes and shallow(name)
            under = any(name == p or (name.startswith(p + ".") and shallow(name[len(p) + 1 :])) for p in req.prefixes)
            if everything or under:
                out.names.append(name)
                prefix = name.rpartition(".")[0]
                if prefix and prefix not in out.prefixes:
                    out.prefixes.append(prefix)
        return rcl.ListParameters_Response(result=out)

    def set_parameters(self, req: rcl.SetParameters_Request) -> rcl.SetParameters_Response:
        """Each parameter on its own, in order, as rclcpp does."""
        return rcl.SetParameters_Response(results=[self.apply({p.name: p.value}) for p in req.parameters])

    def set_parameters_atomically(
        self, req: rcl.SetParametersAtomically_Request
    ) -> rcl.SetParametersAtomically_Response:
        """All or none."""
        return rcl.SetParametersAtomically_Response(result=self.apply({p.name: p.value for p in req.parameters}))

    def apply(self, changes: dict[str, ParameterValue]) -> SetParametersResult:
        """Validate `changes` together and apply them, or apply nothing and say why."""
        node = self.node

        def refuse(reason: str) -> SetParametersResult:
            node.count("parameter_changes_refused")
            node.log.warning(f"parameter change refused: {reason}")
            return SetParametersResult(successful=False, reason=reason)

        values: dict[str, Any] = {}
        for name, pv in changes.items():
            if name not in self.fields:
                return refuse(f"parameter {name!r} is not declared by node {node.node_name!r}")
            if self.read_only(name):
                return refuse(
                    f"parameter {name!r} is read-only: node {node.node_name!r} reads it at start-up; "
                    "restart the node to change it"
                )
            try:
                values[name] = from_value(pv, self.fields[name][1], name)
            except ParamError as exc:
                return refuse(str(exc))
        old = node.config
        current = {f.name: getattr(old, f.name) for f in dataclasses.fields(old)}
        try:
            new = build_config(type(old), {**current, **values}, node=node.node_name)
        except ParamError as exc:
            return refuse(str(exc))
        changed = frozenset(n for n in values if getattr(new, n) != getattr(old, n))
        if not changed:
            return SetParametersResult(successful=True)
        if loose := loosened(old, new, changed):
            return refuse(loosening_refused(node.node_name, loose))
        try:
            node.check_params(new, changed)
        except ValueError as exc:
            return refuse(str(exc))
        node.config = new
        try:
            node.on_params_changed(old, changed)
        except Exception as exc:  # put the old values back, and what the node derived from them
            node.config = old
            try:
                node.on_params_changed(new, changed)
            except Exception as again:
                node.log.error(f"restoring parameters after a failed change failed too: {again}")
            return refuse(f"node {node.node_name!r} could not apply {sorted(changed)}: {type(exc).__name__}: {exc}")
        node.count("parameter_changes")
        for n in sorted(changed):
            node.log.info(f"parameter {n}: {getattr(old, n)!r} -> {getattr(new, n)!r}")
        self.events.publish(
            ParameterEvent(
                stamp=node.stamp(),
                node=node.fully_qualified_name,
                changed_parameters=[
                    Parameter(name=n, value=to_value(getattr(new, n), self.fields[n][1])) for n in sorted(changed)
                ],
            )
        )
        return SetParametersResult(successful=True)


# -- the client ------------------------------------------------------------------------------------
class ParameterClient:
    """Calls one node's parameter services (ours or a ROS 2 node's with rmw_cyclonedds_cpp).

    Wall time: `timeout_s` bounds DDS discovery and each reply."""

    def __init__(self, node: str, participant: DomainParticipant | None = None, timeout_s: float = 5.0) -> None:
        self.node = "/" + node.strip().strip("/")
        self.timeout_s = timeout_s
        self._dp = participant or domain.participant()
        self._clients: dict[str, ServiceClient[Any, Any]] = {}

    def _call(self, service: str, request: Any) -> Any:
        client = self._clients.get(service)
        if client is None:
            srv = rcl.PARAMETER_SERVICES[service]
            name = node_service(self.node, service)
            client = self._clients[service] = ServiceClient(srv, name, self._dp, QOS_PARAMETERS)
        try:
            return client.call(request, self.timeout_s)
        except ServiceError as exc:
            hint = "is the node running, on this domain and network interface?"
            raise ServiceError(f"node {self.node}: {exc} ({hint})") from None

    def list(self) -> builtins.list[str]:
        return list(self._call("list_parameters", rcl.ListParameters_Request()).result.names)

    def _known(self, names: builtins.list[str], got: builtins.list[Any]) -> builtins.list[Any]:
        if len(got) != len(names):  # an unknown name empties the whole answer (rclcpp does the same)
            declared = set(self.list())
            missing = [n for n in names if n not in declared] or names
            raise ParamError(f"node {self.node} does not declare parameter(s) {', '.join(map(repr, missing))}")
        return got

    def get(self, names: builtins.list[str]) -> builtins.list[ParameterValue]:
        return self._known(names, list(self._call("get_parameters", rcl.GetParameters_Request(names=names)).values))

    def describe(self, names: builtins.list[str]) -> builtins.list[ParameterDescriptor]:
        resp = self._call("describe_parameters", rcl.DescribeParameters_Request(names=names))
        return self._known(names, list(resp.descriptors))

    def types(self, names: builtins.list[str]) -> builtins.list[int]:
        resp = self._call("get_parameter_types", rcl.GetParameterTypes_Request(names=names))
        return self._known(names, list(resp.types))

    def set(self, values: dict[str, ParameterValue]) -> builtins.list[SetParametersResult]:
        params = [Parameter(name=n, value=v) for n, v in values.items()]
        return list(self._call("set_parameters", rcl.SetParameters_Request(parameters=params)).results)

    def set_atomically(self, values: dict[str, ParameterValue]) -> SetParametersResult:
        params = [Parameter(name=n, value=v) for n, v in values.items()]
        return self._call("set_parameters_atomically", rcl.SetParametersAtomically_Request(parameters=params)).result

    def close(self) -> None:
        for client in self._clients.values():
            client.close()
        self._clients.clear()

    def __enter__(self) -> ParameterClient:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()
