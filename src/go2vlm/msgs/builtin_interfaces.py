"""builtin_interfaces/msg: Time, Duration.

Message modules avoid `from __future__ import annotations`: cyclonedds resolves field annotations at
runtime and mistakes the string `types.uint32` for the standard library module `types`.
"""

from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, register


@register
@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: types.int32 = 0
    nanosec: types.uint32 = 0

    @classmethod
    def from_sec(cls, t: float) -> "Time":
        ns = int(round(t * 1e9))
        return cls(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def to_sec(self) -> float:
        return self.sec + self.nanosec * 1e-9


@register
@dataclass
class Duration(IdlStruct, typename="builtin_interfaces::msg::dds_::Duration_"):
    sec: types.int32 = 0
    nanosec: types.uint32 = 0
