"""nav_msgs/msg: Odometry."""

from dataclasses import dataclass

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.geometry_msgs import PoseWithCovariance, TwistWithCovariance
from go2vlm.msgs.std_msgs import Header


@register
@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header = default(Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = default(PoseWithCovariance)
    twist: TwistWithCovariance = default(TwistWithCovariance)
