"""ROS 2 message definitions (.msg text) and type hashes generated from our IDL structs.

What rosbag2 writes into a bag for every topic type, so that `ros2 bag`, Foxglove and rosbags can
decode our bytes without our code:

- `msgdef(cls)`: the ros2msg schema text, the type's own fields followed by every type it uses,
  each after a line of 80 `=` and `MSG: pkg/Type` (rosbag2's and rosbags' layout).
- `rihs01(cls)`: the REP-2011 type description hash (`RIHS01_<sha256>`) of ROS 2 Iron and later.

Field types come from the cyclonedds annotations: `float` is float64, `bytes` is uint8[] and
`types.byte` is uint8 (we declare uint8 as byte for Cyclone 0.10 peers, see msgs/_base.py). The few
fields whose .msg type differs from that reading are listed in `FIELD_OVERRIDES`.
"""

from __future__ import annotations

import dataclasses
import json
import typing
from hashlib import sha256
from typing import Any

from cyclonedds.idl import IdlStruct
from cyclonedds.idl._type_normalize import get_extended_type_hints
from cyclonedds.idl.types import array, bounded_str, sequence, typedef

__all__ = ["FIELD_OVERRIDES", "FieldType", "fields", "msgdef", "ros_type", "rihs01", "short_name"]

# (ROS type, field) -> .msg base type, where the .msg file says something other than our IDL reading.
FIELD_OVERRIDES: dict[tuple[str, str], str] = {
    ("rmw_dds_common/msg/Gid", "data"): "char",  # char[16] data
    ("unitree_go/msg/IMUState", "temperature"): "int8",  # unitree_ros2's IMUState.msg
    ("unitree_go/msg/MotorState", "temperature"): "int8",  # ... MotorState.msg
    ("unitree_go/msg/BmsState", "bq_ntc"): "int8",  # ... BmsState.msg
    ("unitree_go/msg/BmsState", "mcu_ntc"): "int8",
    ("unitree_go/msg/LowState", "temperature_ntc1"): "int8",  # ... LowState.msg
    ("unitree_go/msg/LowState", "temperature_ntc2"): "int8",
    ("rcl_interfaces/msg/ParameterValue", "byte_array_value"): "byte",  # byte[] byte_array_value
}

# rosidl gives a constants-only message this member; the .msg text has only the constants.
_PLACEHOLDER = "structure_needs_at_least_one_member"

_BASE_NAMES = {
    "float": "float64",
    "float64": "float64",
    "float32": "float32",
    "int8": "int8",
    "int16": "int16",
    "int32": "int32",
    "int64": "int64",
    "uint8": "uint8",
    "uint16": "uint16",
    "uint32": "uint32",
    "uint64": "uint64",
    "byte": "uint8",
    "char": "char",
    "bool": "bool",
    "str": "string",
}

# REP-2011 field type ids (rosidl_runtime_c/type_description/field_type).
_TYPE_IDS = {
    "int8": 2,
    "uint8": 3,
    "int16": 4,
    "uint16": 5,
    "int32": 6,
    "uint32": 7,
    "int64": 8,
    "uint64": 9,
    "float32": 10,
    "float64": 11,
    "char": 13,
    "bool": 15,
    "byte": 16,
    "string": 17,
    "bounded_string": 21,
}


@dataclasses.dataclass(frozen=True)
class FieldType:
    """One field: `base` is a .msg primitive or a ROS type name (`std_msgs/msg/Header`)."""

    base: str
    nested: bool = False  # base is a message type
    kind: str = "single"  # single | array | sequence
    length: int = 0  # array length, sequence bound (0: unbounded)
    string_bound: int = 0

    def msg_text(self) -> str:
        base = short_name(self.base) if self.nested else self.base
        if self.string_bound:
            base = f"string<={self.string_bound}"
        if self.kind == "array":
            return f"{base}[{self.length}]"
        if self.kind == "sequence":
            return f"{base}[<={self.length}]" if self.length else f"{base}[]"
        return base


def ros_type(cls: type[IdlStruct]) -> str:
    """`sensor_msgs::msg::dds_::Image_` -> `sensor_msgs/msg/Image`."""
    pkg, kind, _, name = cls.__idl_typename__.split("::")
    return f"{pkg}/{kind}/{name.removesuffix('_')}"


def short_name(ros: str) -> str:
    """`std_msgs/msg/Header` -> `std_msgs/Header`, as .msg files and `MSG:` lines spell it."""
    pkg, _, name = ros.split("/")
    return f"{pkg}/{name}"


def _unwrap(tp: Any) -> Any:
    """Typedefs resolved; `Annotated[int, 'uint32']` (a cyclonedds primitive) -> 'uint32'."""
    while True:
        if isinstance(tp, typedef):
            tp = tp.subtype
        elif typing.get_origin(tp) is typing.Annotated:
            tp = tp.__metadata__[0]  # a primitive's name, or an array/sequence descriptor
        else:
            return tp


def _field_type(tp: Any, owner: str, name: str) -> FieldType:
    tp = _unwrap(tp)
    override = FIELD_OVERRIDES.get((owner, name))
    if tp is bytes:
        return FieldType(override or "uint8", kind="sequence")
    if isinstance(tp, (array, sequence)):
        inner = _field_type(tp.subtype, owner, name)
        if _unwrap(tp.subtype) is bytes or inner.kind != "single":
            raise TypeError(f"{owner}.{name}: nested arrays have no .msg form")
        kind = "array" if isinstance(tp, array) else "sequence"
        length = tp.length if isinstance(tp, array) else (tp.max_length or 0)
        return dataclasses.replace(inner, kind=kind, length=length)
    if isinstance(tp, bounded_str):
        return FieldType("string", string_bound=tp.max_length)
    if isinstance(tp, type) and issubclass(tp, IdlStruct):
        return FieldType(ros_type(tp), nested=True)
    label = tp if isinstance(tp, str) else getattr(tp, "__name__", None) or str(tp)
    if label not in _BASE_NAMES:
        raise TypeError(f"{owner}.{name}: no .msg type for {tp!r}")
    return FieldType(override or _BASE_NAMES[label])


def fields(cls: type[IdlStruct]) -> list[tuple[str, FieldType, type[IdlStruct] | None]]:
    """(name, type, nested class or None) for every field, in wire order."""
    hints = get_extended_type_hints(cls)
    owner = ros_type(cls)
    out = []
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]  # an IdlStruct is a dataclass
        tp = hints[f.name]
        ft = _field_type(tp, owner, f.name)
        out.append((f.name, ft, _nested_class(tp) if ft.nested else None))
    return out


def _nested_class(tp: Any) -> type[IdlStruct]:
    tp = _unwrap(tp)
    while isinstance(tp, (array, sequence)):
        tp = _unwrap(tp.subtype)
    return tp


def _own_text(cls: type[IdlStruct]) -> str:
    """Constants first (a class's `__ros_constants__`: (type, name, value) rows), then the fields."""
    consts = "".join(f"{typ} {name}={value}\n" for typ, name, value in getattr(cls, "__ros_constants__", ()))
    return consts + "".join(f"{ft.msg_text()} {name}\n" for name, ft, _ in fields(cls) if name != _PLACEHOLDER)


def _dependencies(cls: type[IdlStruct], seen: dict[str, type[IdlStruct]]) -> None:
    """Every nested type, depth first, in order of first use (rosbag2's and rosbags' order)."""
    for _, ft, sub in fields(cls):
        if sub is not None and ft.base not in seen:
            seen[ft.base] = sub
            _dependencies(sub, seen)


def msgdef(cls: type[IdlStruct]) -> str:
    """The ros2msg schema text of `cls` with its dependencies, as in a rosbag2 MCAP schema record."""
    deps: dict[str, type[IdlStruct]] = {}
    _dependencies(cls, deps)
    parts = [_own_text(cls)]
    parts += [f"{'=' * 80}\nMSG: {short_name(name)}\n{_own_text(sub)}" for name, sub in deps.items()]
    return "".join(parts)


def rihs01(cls: type[IdlStruct]) -> str:
    """The REP-2011 type hash, `RIHS01_` + sha256 of the canonical JSON type description."""
    structs: dict[str, dict[str, Any]] = {}

    def describe(c: type[IdlStruct]) -> dict[str, Any]:
        name = ros_type(c)
        if name not in structs:
            structs[name] = {}  # reserve: recursion through nested types
            structs[name] = {"type_name": name, "fields": [field(n, ft, sub) for n, ft, sub in fields(c)]}
        return structs[name]

    def field(name: str, ft: FieldType, sub: type[IdlStruct] | None) -> dict[str, Any]:
        if ft.kind == "array":
            increment, capacity = 48, ft.length
        elif ft.kind == "sequence":
            increment, capacity = (96, ft.length) if ft.length else (144, 0)
        else:
            increment, capacity = 0, 0
        if sub is not None:
            tid, nested = 1, ft.base
            describe(sub)
        else:
            tid, nested = _TYPE_IDS["bounded_string" if ft.string_bound else ft.base], ""
        return {
            "name": name,
            "type": {
                "type_id": increment + tid,
                "capacity": capacity,
                "string_capacity": ft.string_bound,
                "nested_type_name": nested,
            },
        }

    top = describe(cls)
    name = ros_type(cls)
    doc = {
        "type_description": top,
        "referenced_type_descriptions": [v for k, v in sorted(structs.items()) if k != name],
    }
    return "RIHS01_" + sha256(json.dumps(doc).encode()).hexdigest()
