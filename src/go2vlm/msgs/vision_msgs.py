"""vision_msgs/msg (ROS 2 Jazzy, vision_msgs 4.x): Point2D, Pose2D, BoundingBox2D, ObjectHypothesis,
ObjectHypothesisWithPose, Detection2D, Detection2DArray, BoundingBox3D, Detection3D, Detection3DArray
(objects in the world: the object memory's /objects); and the one conversion between pixel boxes
(label, (x1, y1, x2, y2), score) and a Detection2DArray, both ways."""

from collections.abc import Iterable
from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.geometry_msgs import Pose, PoseWithCovariance, Vector3
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


@register
@dataclass
class BoundingBox3D(IdlStruct, typename="vision_msgs::msg::dds_::BoundingBox3D_"):
    center: Pose = default(Pose)
    size: Vector3 = default(Vector3)


@register
@dataclass
class Detection3D(IdlStruct, typename="vision_msgs::msg::dds_::Detection3D_"):
    header: Header = default(Header)
    results: types.sequence[ObjectHypothesisWithPose] = default(list)
    bbox: BoundingBox3D = default(BoundingBox3D)
    id: str = ""


@register
@dataclass
class Detection3DArray(IdlStruct, typename="vision_msgs::msg::dds_::Detection3DArray_"):
    header: Header = default(Header)
    detections: types.sequence[Detection3D] = default(list)


PixelBox = tuple[str, tuple[float, float, float, float], float]  # label, (x1, y1, x2, y2), score


def detection_array(header: Header, boxes: Iterable[PixelBox]) -> Detection2DArray:
    """Labelled pixel boxes -> a Detection2DArray: class_id = the label, id = the index, every
    detection with the array's header (the source image's stamp and frame)."""
    dets = []
    for i, (label, (x1, y1, x2, y2), score) in enumerate(boxes):
        dets.append(
            Detection2D(
                header=Header(stamp=header.stamp, frame_id=header.frame_id),
                results=[ObjectHypothesisWithPose(hypothesis=ObjectHypothesis(class_id=label, score=float(score)))],
                bbox=BoundingBox2D(
                    center=Pose2D(position=Point2D(x=(x1 + x2) / 2.0, y=(y1 + y2) / 2.0), theta=0.0),
                    size_x=float(x2 - x1),
                    size_y=float(y2 - y1),
                ),
                id=str(i),
            )
        )
    return Detection2DArray(header=header, detections=dets)


def detection_boxes(msg: Detection2DArray) -> list[PixelBox]:
    """A Detection2DArray -> (label, (x1, y1, x2, y2), score) per detection (its best hypothesis)."""
    out: list[PixelBox] = []
    for d in msg.detections:
        best = max(d.results, key=lambda r: r.hypothesis.score, default=None)
        label, score = (best.hypothesis.class_id, best.hypothesis.score) if best is not None else ("", 0.0)
        cx, cy = d.bbox.center.position.x, d.bbox.center.position.y
        hw, hh = d.bbox.size_x / 2.0, d.bbox.size_y / 2.0
        out.append((label, (cx - hw, cy - hh, cx + hw, cy + hh), score))
    return out
