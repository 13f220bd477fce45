"""vision_msgs/msg (ROS 2 Jazzy, vision_msgs 4.x): Point2D, Pose2D, BoundingBox2D, ObjectHypothesis,
ObjectHypothesisWithPose, Detection2D, Detection2DArray."""

from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.geometry_msgs import PoseWithCovariance
from go2vlm.msgs.std_msgs import Header


@register
@dataclass
class Point2D(IdlStruct, typename="vision_msgs::msg::dds_::Point2D_"):
    x: float = 0.0
    y: float = 0.0


@register
@dataclass
class Pose2D(IdlStruct, typename="vision_msgs::msg::dds_::Pose2D_"):
    position: Point2D = default(Point2D)
    theta: float = 0.0


@register
@dataclass
class BoundingBox2D(IdlStruct, typename="vision_msgs::msg::dds_::BoundingBox2D_"):
    center: Pose2D = default(Pose2D)
    size_x: float = 0.0
    size_y: float = 0.0


@register
@dataclass
class ObjectHypothesis(IdlStruct, typename="vision_msgs::msg::dds_::ObjectHypothesis_"):
    class_id: str = ""
    score: float = 0.0


@register
@dataclass
class ObjectHypothesisWithPose(IdlStruct, typename="vision_msgs::msg::dds_::ObjectHypothesisWithPose_"):
    hypothesis: ObjectHypothesis = default(ObjectHypothesis)
    pose: PoseWithCovariance = default(PoseWithCovariance)


@register
@dataclass
class Detection2D(IdlStruct, typename="vision_msgs::msg::dds_::Detection2D_"):
    header: Header = default(Header)
    results: types.sequence[ObjectHypothesisWithPose] = default(list)
    bbox: BoundingBox2D = default(BoundingBox2D)
    id: str = ""


@register
@dataclass
class Detection2DArray(IdlStruct, typename="vision_msgs::msg::dds_::Detection2DArray_"):
    header: Header = default(Header)
    detections: types.sequence[Detection2D] = default(list)
