"""tf2_msgs/msg: TFMessage."""

from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.geometry_msgs import TransformStamped


@register
@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: types.sequence[TransformStamped] = default(list)
