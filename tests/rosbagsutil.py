"""rosbags as the reference CDR implementation: its Jazzy type store (plus vision_msgs 4.x and the
rcl_interfaces services, which the store lacks, and go2vlm_msgs from the project's own .msg files)
and converters between plain value trees, rosbags messages and our messages.

A value tree is generated from rosbags' field definitions (the spec), then built into both a rosbags
message and one of ours, so that a wrong field name, order or width in go2vlm.msgs shows up as a
construction error or a byte difference.
"""

from __future__ import annotations

import dataclasses
from functools import cache
from typing import Any

import numpy as np
from busutil import rosbags_typestore
from cyclonedds.idl._type_normalize import get_extended_type_hints
from hypothesis import strategies as st
from rosbags.typesys.base import Nodetype

# vision_msgs 4.x (Humble, Jazzy) message definitions.
VISION_MSGS = {
    "vision_msgs/msg/Point2D": "float64 x\nfloat64 y\n",
    "vision_msgs/msg/Pose2D": "vision_msgs/Point2D position\nfloat64 theta\n",
    "vision_msgs/msg/BoundingBox2D": "vision_msgs/Pose2D center\nfloat64 size_x\nfloat64 size_y\n",
    "vision_msgs/msg/ObjectHypothesis": "string class_id\nfloat64 score\n",
    "vision_msgs/msg/ObjectHypothesisWithPose": (
        "vision_msgs/ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n"
    ),
    "vision_msgs/msg/Detection2D": (
        "std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n"
        "vision_msgs/BoundingBox2D bbox\nstring id\n"
    ),
    "vision_msgs/msg/Detection2DArray": "std_msgs/Header header\nvision_msgs/Detection2D[] detections\n",
    "vision_msgs/msg/BoundingBox3D": "geometry_msgs/Pose center\ngeometry_msgs/Vector3 size\n",
    "vision_msgs/msg/Detection3D": (
        "std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n"
        "vision_msgs/BoundingBox3D bbox\nstring id\n"
    ),
    "vision_msgs/msg/Detection3DArray": "std_msgs/Header header\nvision_msgs/Detection3D[] detections\n",
}

# rcl_interfaces/srv (Jazzy) as rosidl splits each service: <Name>_Request and <Name>_Response
# messages. The store has rcl_interfaces' messages but not its services.
RCL_SRVS = {
    "rcl_interfaces/srv/ListParameters_Request": "uint64 DEPTH_RECURSIVE=0\nstring[] prefixes\nuint64 depth\n",
    "rcl_interfaces/srv/ListParameters_Response": "rcl_interfaces/ListParametersResult result\n",
    "rcl_interfaces/srv/GetParameters_Request": "string[] names\n",
    "rcl_interfaces/srv/GetParameters_Response": "rcl_interfaces/ParameterValue[] values\n",
    "rcl_interfaces/srv/SetParameters_Request": "rcl_interfaces/Parameter[] parameters\n",
    "rcl_interfaces/srv/SetParameters_Response": "rcl_interfaces/SetParametersResult[] results\n",
    "rcl_interfaces/srv/SetParametersAtomically_Request": "rcl_interfaces/Parameter[] parameters\n",
    "rcl_interfaces/srv/SetParametersAtomically_Response": "rcl_interfaces/SetParametersResult result\n",
    "rcl_interfaces/srv/DescribeParameters_Request": "string[] names\n",
    "rcl_interfaces/srv/DescribeParameters_Response": "rcl_interfaces/ParameterDescriptor[] descriptors\n",
    "rcl_interfaces/srv/GetParameterTypes_Request": "string[] names\n",
    "rcl_interfaces/srv/GetParameterTypes_Response": "uint8[] types\n",
}

_INT_RANGES = {
    "bool": None,
    "byte": (0, 255),
    "char": (0, 255),
    "uint8": (0, 255),
    "int8": (-128, 127),
    "uint16": (0, 2**16 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint32": (0, 2**32 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint64": (0, 2**64 - 1),
    "int64": (-(2**63), 2**63 - 1),
}
_NP_DTYPES = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "uint8": np.uint8,
    "int8": np.int8,
    "uint16": np.uint16,
    "int16": np.int16,
    "uint32": np.uint32,
    "int32": np.int32,
    "uint64": np.uint64,
    "int64": np.int64,
    "float32": np.float32,
    "float64": np.float64,
}
_OCTETS = ("byte", "char", "uint8")

# CDR strings are NUL-terminated UTF-8: no NUL, no lone surrogates.
TEXT = st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=12)


def go2vlm_msgs() -> dict[str, str]:
    """go2vlm's own .msg files, read from the ROS package the project ships (the spec ROS users build)."""
    from go2vlm.msgs.go2vlm_msgs import MSG_DIR

    return {f"go2vlm_msgs/msg/{f.stem}": f.read_text() for f in sorted(MSG_DIR.glob("*.msg"))}


def go2vlm_srvs() -> dict[str, str]:
    """go2vlm's own .srv files, split as rosidl splits a service: <Name>_Request and <Name>_Response."""
    from go2vlm.msgs.go2vlm_msgs import SRV_DIR

    out = {}
    for f in sorted(SRV_DIR.glob("*.srv")):
        request, response = f.read_text().split("\n---\n")
        out[f"go2vlm_msgs/srv/{f.stem}_Request"] = request
        out[f"go2vlm_msgs/srv/{f.stem}_Response"] = response
    return out


@cache
def typestore() -> Any:
    return rosbags_typestore({**VISION_MSGS, **RCL_SRVS, **go2vlm_msgs(), **go2vlm_srvs()})


def fields_of(typename: str) -> list[tuple[str, Any]]:
    return list(typestore().fielddefs[typename][1])


def strategy(typename: str, max_seq: int = 3) -> st.SearchStrategy[dict[str, Any]]:
    """Value trees for a ROS message type, following rosbags' definition of it."""
    return st.fixed_dictionaries({name: _field_strategy(desc, max_seq) for name, desc in fields_of(typename)})


def _base_strategy(base: str, bound: int) -> st.SearchStrategy[Any]:
    if base == "bool":
        return st.booleans()
    if base in _INT_RANGES:
        lo, hi = _INT_RANGES[base]  # type: ignore[misc]
        return st.integers(lo, hi)
    if base == "float32":
        return st.floats(allow_nan=False, width=32)
    if base == "float64":
        return st.floats(allow_nan=False)
    if base == "string":
        return (
            TEXT if not bound else st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), max_size=bound)
        )
    raise NotImplementedError(base)


def _field_strategy(desc: Any, max_seq: int) -> st.SearchStrategy[Any]:
    kind, rest = desc
    if kind == Nodetype.BASE:
        return _base_strategy(*rest)
    if kind == Nodetype.NAME:
        return st.deferred(lambda: strategy(rest, max_seq))
    sub, n = rest
    item = _field_strategy(sub, max_seq)
    if kind == Nodetype.ARRAY:
        return st.lists(item, min_size=n, max_size=n)
    if sub[0] == Nodetype.BASE and sub[1][0] in _OCTETS:
        return st.lists(item, max_size=11)  # odd lengths of octet data
    return st.lists(item, max_size=n or max_seq)


def to_rosbags(typename: str, values: dict[str, Any]) -> Any:
    ts = typestore()
    kwargs = {name: _to_rosbags_value(desc, values[name]) for name, desc in fields_of(typename)}
    return ts.types[typename](**kwargs)


def _to_rosbags_value(desc: Any, value: Any) -> Any:
    kind, rest = desc
    if kind == Nodetype.BASE:
        return value
    if kind == Nodetype.NAME:
        return to_rosbags(rest, value)
    sub, _n = rest
    if sub[0] == Nodetype.BASE and sub[1][0] != "string":
        return np.array(value, dtype=_NP_DTYPES[sub[1][0]])
    return [_to_rosbags_value(sub, v) for v in value]


def to_ours(cls: type, values: dict[str, Any]) -> Any:
    """Our message from a value tree; field names must match the spec exactly."""
    hints = get_extended_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    assert sorted(names) == sorted(values), f"{cls.__name__} fields {names} != spec {sorted(values)}"
    return cls(**{name: _to_ours_value(hints[name], values[name]) for name in names})


def _to_ours_value(tp: Any, value: Any) -> Any:
    if isinstance(value, dict):
        return to_ours(tp, value)
    if tp is bytes or "array[byte," in repr(tp):  # cyclonedds decodes octet arrays as bytes
        return bytes(value)
    if isinstance(value, list):
        sub = getattr(tp, "subtype", None)
        return [_to_ours_value(sub, v) for v in value]
    return value


def rosbags_cdr(typename: str, values: dict[str, Any]) -> bytes:
    return bytes(typestore().serialize_cdr(to_rosbags(typename, values), typename))
