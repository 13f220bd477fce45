"""Messages <-> plain dicts, for `go2vlm topic echo/pub`, JSON output and YAML input."""

from __future__ import annotations

import base64
import dataclasses
import math
import typing
from typing import Any

from cyclonedds.idl import IdlStruct
from cyclonedds.idl._type_normalize import get_extended_type_hints
from cyclonedds.idl.types import ValidUnionHolder, array, byte, sequence, typedef

_INT_TYPES = {"int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64", "byte", "char"}


def to_dict(msg: Any, *, bytes_mode: str = "summary") -> Any:
    """Nested dict of a message. `bytes_mode`: "summary" (`"<N bytes>"`), "base64" or "list"."""
    if dataclasses.is_dataclass(msg):
        return {f.name: to_dict(getattr(msg, f.name), bytes_mode=bytes_mode) for f in dataclasses.fields(msg)}
    if isinstance(msg, (bytes, bytearray)):
        if bytes_mode == "base64":
            return base64.b64encode(bytes(msg)).decode()
        if bytes_mode == "list":
            return list(msg)
        return f"<{len(msg)} bytes>"
    if isinstance(msg, (list, tuple)):
        return [to_dict(v, bytes_mode=bytes_mode) for v in msg]
    if isinstance(msg, float) and not math.isfinite(msg):
        return str(msg)
    return msg


def from_dict(cls: type[IdlStruct], data: Any, where: str = "") -> Any:
    """Build a message of type `cls` from a (partial) dict; missing fields keep their defaults."""
    where = where or cls.__name__
    if data is None:
        return cls()
    if not isinstance(data, dict):
        raise ValueError(f"{where}: expected a mapping of fields, got {data!r}")
    hints = get_extended_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]  # an IdlStruct is a dataclass
    unknown = sorted(set(data) - names)
    if unknown:
        raise ValueError(f"{where}: unknown field(s) {', '.join(unknown)}; fields are {', '.join(sorted(names))}")
    kwargs = {name: _value(hints[name], value, f"{where}.{name}") for name, value in data.items()}
    return cls(**kwargs)


def _value(tp: Any, value: Any, where: str) -> Any:
    if isinstance(tp, typedef):
        tp = tp.subtype
    if isinstance(tp, type) and issubclass(tp, IdlStruct):
        return from_dict(tp, value, where)
    if isinstance(tp, (sequence, array)):
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"{where}: expected a list, got {value!r}")
        items = [_value(tp.subtype, v, f"{where}[{i}]") for i, v in enumerate(value)]
        if isinstance(tp, array) and len(items) != tp.length:
            raise ValueError(f"{where}: expected {tp.length} items, got {len(items)}")
        return items
    if tp is bytes:
        if isinstance(value, str):
            return base64.b64decode(value)
        if isinstance(value, (list, tuple)):
            return bytes(int(v) for v in value)
        raise ValueError(f"{where}: expected base64 text or a list of byte values, got {value!r}")
    if tp is bool:
        if not isinstance(value, bool):
            raise ValueError(f"{where}: expected true or false, got {value!r}")
        return value
    if tp is str:
        return str(value)
    if tp is float or getattr(tp, "__name__", "") in ("float32", "float64"):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"{where}: expected a number, got {value!r}")
        return float(value)
    if tp is int or _type_label(tp) in _INT_TYPES or tp is byte:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{where}: expected an integer, got {value!r}")
        return value
    if isinstance(tp, ValidUnionHolder) or typing.get_origin(tp) is not None:
        return value
    return value


def _type_label(tp: Any) -> str:
    return str(getattr(tp, "__name__", tp)).lower()


def to_yaml_text(msg: Any) -> str:
    """ros2-topic-echo-like text of one message."""
    lines: list[str] = []

    def emit(value: Any, indent: int, key: str | None) -> None:
        pad = "  " * indent
        if isinstance(value, dict):
            if key is not None:
                lines.append(f"{pad}{key}:")
                indent += 1
            for k, v in value.items():
                emit(v, indent, k)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            lines.append(f"{pad}{key}:")
            for item in value:
                sub: list[str] = []
                lines_before = len(lines)
                emit(item, indent + 1, None)
                sub = lines[lines_before:]
                del lines[lines_before:]
                for i, line in enumerate(sub):
                    stripped = line[2 * (indent + 1) :]
                    lines.append(f"{pad}- {stripped}" if i == 0 else f"{pad}  {stripped}")
        else:
            text = _scalar(value)
            lines.append(f"{pad}{key}: {text}" if key is not None else f"{pad}{text}")

    emit(to_dict(msg), 0, None)
    return "\n".join(lines)


def _scalar(value: Any) -> str:
    if isinstance(value, str):
        return repr(value) if value == "" or value.strip() != value or ":" in value else value
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return "[" + ", ".join(_scalar(v) for v in value) + "]"
    return str(value)
