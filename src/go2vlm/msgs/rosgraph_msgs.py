"""rosgraph_msgs/msg: Clock."""

from dataclasses import dataclass

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.builtin_interfaces import Time


@register
@dataclass
class Clock(IdlStruct, typename="rosgraph_msgs::msg::dds_::Clock_"):
    clock: Time = default(Time)
