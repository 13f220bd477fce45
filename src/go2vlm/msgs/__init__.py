"""ROS 2 message types as cyclonedds IDL structs, named as ROS 2 names them on the wire.

Import the package modules (`from go2vlm.msgs.sensor_msgs import Image`) or look a type up by its
ROS name with `get_type("sensor_msgs/msg/Image")` or its DDS name.
"""

from __future__ import annotations

from go2vlm.msgs import (
    builtin_interfaces,
    geometry_msgs,
    go2vlm_msgs,
    nav_msgs,
    rcl_interfaces,
    rosgraph_msgs,
    sensor_msgs,
    std_msgs,
    tf2_msgs,
    vision_msgs,
    visualization_msgs,
)
from go2vlm.msgs._base import REGISTRY, IdlStruct, ros_typename

__all__ = [
    "REGISTRY",
    "builtin_interfaces",
    "geometry_msgs",
    "get_type",
    "go2vlm_msgs",
    "nav_msgs",
    "rcl_interfaces",
    "ros_name",
    "rosgraph_msgs",
    "sensor_msgs",
    "std_msgs",
    "tf2_msgs",
    "vision_msgs",
    "visualization_msgs",
]


def ros_name(cls: type[IdlStruct]) -> str:
    """`sensor_msgs::msg::dds_::Image_` -> `sensor_msgs/msg/Image`."""
    pkg, kind, _, name = cls.__idl_typename__.split("::")
    return f"{pkg}/{kind}/{name.rstrip('_')}"


def get_type(name: str) -> type[IdlStruct]:
    """Find a message class by ROS name (`sensor_msgs/msg/Image`, `sensor_msgs/Image`) or DDS name."""
    _load_optional()
    if "::" not in name:
        parts = name.split("/")
        if len(parts) == 2:
            parts = [parts[0], "msg", parts[1]]
        if len(parts) != 3 or not all(p.isidentifier() for p in parts):
            raise ValueError(f"{name!r} is not a message type; give one like std_msgs/msg/Bool")
        name = ros_typename("/".join(parts))
    try:
        return REGISTRY[name]
    except KeyError:
        known = ", ".join(sorted(ros_name(c) for c in REGISTRY.values()))
        raise ValueError(f"unknown message type {name!r}; known types: {known}") from None


def _load_optional() -> None:
    # Unitree and graph types register themselves on import; load them lazily for lookups.
    import importlib

    for mod in ("go2vlm.msgs.rmw_dds_common", "go2vlm.msgs.unitree"):
        try:
            importlib.import_module(mod)
        except ImportError:
            pass
