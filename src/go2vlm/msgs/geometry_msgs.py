"""geometry_msgs/msg: Vector3, Point, Quaternion, Pose, Twist, Transform and their stamped and
covariance forms."""

from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.std_msgs import Header


@register
@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0


@register
@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0


@register
@dataclass
class PointStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PointStamped_"):
    header: Header = default(Header)
    point: Point = default(Point)


@register
@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    w: float = 1.0


@register
@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = default(Point)
    orientation: Quaternion = default(Quaternion)


@register
@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header = default(Header)
    pose: Pose = default(Pose)


@register
@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose = default(Pose)
    covariance: types.array[float, 36] = default(lambda: [0.0] * 36)


@register
@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = default(Vector3)
    angular: Vector3 = default(Vector3)


@register
@dataclass
class TwistStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TwistStamped_"):
    header: Header = default(Header)
    twist: Twist = default(Twist)


@register
@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist = default(Twist)
    covariance: types.array[float, 36] = default(lambda: [0.0] * 36)


@register
@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = default(Vector3)
    rotation: Quaternion = default(Quaternion)


@register
@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header = default(Header)
    child_frame_id: str = ""
    transform: Transform = default(Transform)
