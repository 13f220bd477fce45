"""The object memory on the wire: a remembered object <-> a vision_msgs/Detection3D, both ways, and
its markers. The one conversion the node, `go2vlm objects`, the commander and the episode recorder use.

A Detection3D per object: `id` = the stable object id; `results[0].hypothesis` class_id = the label,
score = the confidence 0..1; `results[0].pose` = its position with the position covariance (x, y;
z 0.01 m^2); `bbox.center.position` = world x, y, z (the centre's height); `bbox.size` = width,
depth, height (m); `header` = the world frame and the stamp of the frame it was last seen in.
The Detection3DArray's header stamp is the stamp of the newest answer the memory has taken in (its
frame's), so a reader knows which frames the memory has heard about.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.geometry_msgs import Point, Pose, PoseWithCovariance, Vector3
from go2vlm.msgs.std_msgs import ColorRGBA, Header
from go2vlm.msgs.vision_msgs import (
    BoundingBox3D,
    Detection3D,
    Detection3DArray,
    ObjectHypothesis,
    ObjectHypothesisWithPose,
)
from go2vlm.msgs.visualization_msgs import Marker, MarkerArray
from go2vlm.vocabulary.words import COLOR_RGB, parse_label
from go2vlm.world.memory import MemoryObject

__all__ = ["Remembered", "detection_of", "markers_of", "objects_array", "remembered"]

Z_VAR = 0.01  # m^2: the centre's height is half the seen height, roughly


@dataclass(frozen=True)
class Remembered:
    """What a reader of /objects learns about one object."""

    id: str
    label: str
    x: float
    y: float
    z: float
    size: tuple[float, float, float]
    confidence: float
    last_seen: float  # stamp
    cov: tuple[float, float, float]  # xx, xy, yy

    @property
    def radius(self) -> float:
        return max(self.size[0], self.size[1]) / 2.0


def detection_of(o: MemoryObject, frame_id: str) -> Detection3D:
    cov = [0.0] * 36
    cov[0], cov[1], cov[6], cov[7], cov[14] = o.cov[0], o.cov[1], o.cov[1], o.cov[2], Z_VAR
    centre = Point(x=float(o.x), y=float(o.y), z=float(o.z))
    return Detection3D(
        header=Header(stamp=Time.from_sec(max(0.0, o.last_seen)), frame_id=frame_id),
        results=[
            ObjectHypothesisWithPose(
                hypothesis=ObjectHypothesis(class_id=o.label, score=float(o.confidence)),
                pose=PoseWithCovariance(pose=Pose(position=centre), covariance=cov),
            )
        ],
        bbox=BoundingBox3D(center=Pose(position=centre), size=Vector3(x=o.size[0], y=o.size[1], z=o.size[2])),
        id=o.id,
    )


def objects_array(objects: Iterable[MemoryObject], frame_id: str, stamp: float) -> Detection3DArray:
    return Detection3DArray(
        header=Header(stamp=Time.from_sec(max(0.0, stamp)), frame_id=frame_id),
        detections=[detection_of(o, frame_id) for o in objects],
    )


def remembered(d: Detection3D) -> Remembered | None:
    """A Detection3D -> what it says about one object; None when it says nothing usable (no
    hypothesis, a non-finite place)."""
    if not d.results:
        return None
    h = d.results[0].hypothesis
    p, s = d.bbox.center.position, d.bbox.size
    c = d.results[0].pose.covariance
    vals = (p.x, p.y, p.z, s.x, s.y, s.z, h.score)
    if not all(math.isfinite(v) for v in vals):
        return None
    return Remembered(d.id, h.class_id, p.x, p.y, p.z, (s.x, s.y, s.z), h.score, d.header.stamp.to_sec(),
                      (c[0], c[1], c[7]))  # fmt: skip


_MARKER_SHAPES = {"ball": Marker.SPHERE, "box": Marker.CUBE, "cylinder": Marker.CYLINDER}  # a test checks: all SHAPES


def _shape(label: str) -> int:
    shape = parse_label(label).shape
    return _MARKER_SHAPES[shape] if shape is not None else Marker.CUBE


def markers_of(objects: Iterable[MemoryObject], frame_id: str, stamp: float) -> MarkerArray:
    """One marker per object (its shape, size and colour; as opaque as it is confident) and its label
    above it, after a DELETEALL, so that forgotten objects vanish from rviz2 and Foxglove."""
    header = Header(stamp=Time.from_sec(max(0.0, stamp)), frame_id=frame_id)
    out = [Marker(header=header, ns="objects", action=Marker.DELETEALL)]
    for k, o in enumerate(objects):
        r, g, b = next((COLOR_RGB[w] for w in o.label.split() if w in COLOR_RGB), (0.6, 0.6, 0.6))
        centre = Pose(position=Point(x=o.x, y=o.y, z=o.z))
        out.append(
            Marker(
                header=header,
                ns="objects",
                id=2 * k,
                type=_shape(o.label),
                pose=centre,
                scale=Vector3(x=max(0.05, o.size[0]), y=max(0.05, o.size[1]), z=max(0.05, o.size[2])),
                color=ColorRGBA(r=r, g=g, b=b, a=0.2 + 0.7 * o.confidence),
            )  # fmt: skip
        )
        above = Pose(position=Point(x=o.x, y=o.y, z=o.size[2] + 0.25))
        out.append(
            Marker(
                header=header,
                ns="objects",
                id=2 * k + 1,
                type=Marker.TEXT_VIEW_FACING,
                pose=above,
                scale=Vector3(z=0.2),
                color=ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0),
                text=f"{o.label} {o.confidence:.2f}",
            )  # fmt: skip
        )
    return MarkerArray(markers=out)
