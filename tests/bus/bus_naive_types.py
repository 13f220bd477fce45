"""A textbook declaration of sensor_msgs/Image (data as `sequence<octet>`), for comparison with ours.

No `from __future__ import annotations` here: cyclonedds resolves field annotations at runtime.
"""

from dataclasses import dataclass, field

from cyclonedds.idl import IdlStruct, types

from go2vlm.msgs.std_msgs import Header


@dataclass
class NaiveImage(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    header: Header = field(default_factory=Header)
    height: types.uint32 = 0
    width: types.uint32 = 0
    encoding: str = ""
    is_bigendian: types.byte = 0
    step: types.uint32 = 0
    data: types.sequence[types.byte] = field(default_factory=list)
