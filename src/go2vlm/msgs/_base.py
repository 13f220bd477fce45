"""Shared helpers for declaring ROS 2 messages as cyclonedds IDL structs.

ROS 2 maps `pkg/msg/Name` to the DDS type `pkg::msg::dds_::Name_`; every struct here declares that
name explicitly so that rmw_cyclonedds_cpp and rmw_fastrtps_cpp peers match our topics.
uint8 fields are declared as `types.byte` (or `bytes` for uint8[]): a cyclonedds-11 `uint8` type
object makes Cyclone 0.10.x peers, the Go2's own DDS stack among them, segfault on discovery.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import field
from typing import Any

from cyclonedds.idl import IdlStruct, types
from cyclonedds.idl._xt_builder import XTBuilder

__all__ = ["IdlStruct", "default", "ros_typename", "REGISTRY", "register"]

# DDS type name -> class, so tools can find a type from discovery data.
REGISTRY: dict[str, type[IdlStruct]] = {}


def _describe_bytes_as_octet_sequence() -> None:
    """cyclonedds 11 (de)serializes a `bytes` field as one block, but its XTypes builder cannot
    describe `bytes`, so creating a topic of such a type fails. On the wire `bytes` is exactly a
    sequence<octet>; describe it as one."""
    original = XTBuilder._xt_type_identifier.__func__  # type: ignore[attr-defined]
    if getattr(original, "_go2vlm_bytes", False):
        return

    octets = types.sequence[types.byte].__metadata__[0]  # the bare `sequence` descriptor

    def type_identifier(cls: Any, name: str, entity: Any, minimal: bool) -> Any:
        return original(cls, name, octets if entity is bytes else entity, minimal)

    type_identifier._go2vlm_bytes = True  # type: ignore[attr-defined]
    XTBuilder._xt_type_identifier = classmethod(type_identifier)  # type: ignore[assignment]


_describe_bytes_as_octet_sequence()


def _pack_byte_sequences_in_one_block() -> None:
    """A sequence of 1-byte numbers (nav_msgs/OccupancyGrid's int8[] data: 1.44 M cells at the map's
    cap) is (de)serialized by cyclonedds 11 with one struct call whose arguments are the whole list: a
    tuple of every value, 55 MB of transient memory for one map. Its bytes on the wire are the
    numbers themselves, so write and read them as one block (array.array), the same bytes."""
    from array import array

    from cyclonedds.idl._machinery import PlainCdrV2SequenceOfPrimitiveMachine as Seq
    from cyclonedds.idl._support import Buffer

    if getattr(Seq.serialize, "_go2vlm_block", False):
        return
    serialize, deserialize = Seq.serialize, Seq.deserialize

    def block_serialize(self: Seq, buffer: Buffer, value: Sequence[int], *args: object, **kwargs: object) -> None:
        if self.size != 1 or self.code not in ("b", "B"):
            return serialize(self, buffer, value, *args, **kwargs)
        assert self.max_length is None or len(value) <= self.max_length
        buffer.align(4)
        buffer.write("I", 4, len(value))
        if len(value):
            buffer.write_bytes(array(self.code, value).tobytes())
        return None

    def block_deserialize(self: Seq, buffer: Buffer, *args: object, **kwargs: object) -> object:
        if self.size != 1 or self.code not in ("b", "B"):
            return deserialize(self, buffer, *args, **kwargs)
        buffer.align(4)
        length = buffer.read("I", 4)
        return array(self.code, buffer.read_bytes(length)).tolist() if length else []

    block_serialize._go2vlm_block = True  # type: ignore[attr-defined]
    Seq.serialize = block_serialize  # type: ignore[method-assign]
    Seq.deserialize = block_deserialize  # type: ignore[method-assign]


_pack_byte_sequences_in_one_block()


def ros_typename(ros_type: str) -> str:
    """`sensor_msgs/msg/Image` -> `sensor_msgs::msg::dds_::Image_`."""
    pkg, kind, name = ros_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def register(cls: type[IdlStruct]) -> type[IdlStruct]:
    REGISTRY[cls.__idl_typename__] = cls
    return cls


def default(factory: Any) -> Any:
    """A dataclass field whose default is a fresh `factory()` (nested structs, lists)."""
    return field(default_factory=factory)
