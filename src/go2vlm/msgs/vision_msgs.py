"""vision_msgs/msg (ROS 2 Jazzy, vision_msgs 4.x): Point2D, Pose2D, BoundingBox2D, ObjectHypothesis,
ObjectHypothesisWithPose, Detection2D, Detection2DArray, BoundingBox3D, Detection3D, Detection3DArray
(objects in the world: the object memory's /objects); and the one conversion between pixel boxes
(label, (x1, y1, x2, y2), score) and a Detection2DArray, both ways:

- `bbox_2d` / `box_corners`: corners (x1, y1, x2, y2) <-> a BoundingBox2D (centre and size);
- `best_hypothesis`: which of a detection's hypotheses counts (the best-scoring one, the first of
  equals). Every reader of a detection's label takes it from here, so that the robot and the metrics
  read one message alike;
- `detection_array` / `detection_boxes`: labelled pixel boxes <-> a Detection2DArray."""

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


Corners = tuple[float, float, float, float]  # x1, y1, x2, y2 in pixels
PixelBox = tuple[str, Corners, float]  # label, (x1, y1, x2, y2), score


def bbox_2d(box: Corners) -> BoundingBox2D:
    """Pixel corners -> a BoundingBox2D (centre and size)."""
    x1, y1, x2, y2 = box
    return BoundingBox2D(
        center=Pose2D(position=Point2D(x=(x1 + x2) / 2.0, y=(y1 + y2) / 2.0), theta=0.0),
        size_x=float(x2 - x1),
        size_y=float(y2 - y1),
    )


def box_corners(b: BoundingBox2D) -> Corners:
    """A BoundingBox2D -> its pixel corners (x1, y1, x2, y2)."""
    cx, cy, hw, hh = b.center.position.x, b.center.position.y, b.size_x / 2.0, b.size_y / 2.0
    return cx - hw, cy - hh, cx + hw, cy + hh


def best_hypothesis(results: Iterable[ObjectHypothesisWithPose]) -> ObjectHypothesis | None:
    """The hypothesis of a detection that counts: the best-scoring one (the first of equals); None: none."""
    best = max(results, key=lambda r: r.hypothesis.score, default=None)
    return None if best is None else best.hypothesis


def detection_array(header: Header, boxes: Iterable[PixelBox]) -> Detection2DArray:
    """Labelled pixel boxes -> a Detection2DArray: class_id = the label, id = the index, every
    detection with the array's header (the source image's stamp and frame)."""
    dets = [
        Detection2D(
            header=Header(stamp=header.stamp, frame_id=header.frame_id),
            results=[ObjectHypothesisWithPose(hypothesis=ObjectHypothesis(class_id=label, score=float(score)))],
            bbox=bbox_2d(box),
            id=str(i),
        )
        for i, (label, box, score) in enumerate(boxes)
    ]
    return Detection2DArray(header=header, detections=dets)


def detection_boxes(msg: Detection2DArray) -> list[PixelBox]:
    """A Detection2DArray -> (label, (x1, y1, x2, y2), score) per detection (its best hypothesis;
    none: label '' and score 0)."""
    out: list[PixelBox] = []
    for d in msg.detections:
        h = best_hypothesis(d.results)
        out.append(("", box_corners(d.bbox), 0.0) if h is None else (h.class_id, box_corners(d.bbox), h.score))
    return out
