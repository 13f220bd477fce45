"""nav_msgs/msg: Odometry."""

from dataclasses import dataclass

from ._base import IdlStruct, default, register
from .geometry_msgs import PoseWithCovariance, TwistWithCovariance
from .std_msgs import Header


@register
@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header = default(Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = default(PoseWithCovariance)
    twist: TwistWithCovariance = default(TwistWithCovariance)
