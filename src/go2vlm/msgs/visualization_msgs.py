"""visualization_msgs/msg (ROS 2 Jazzy): Marker, MarkerArray and the two types a Marker carries
(UVCoordinate, MeshFile), for rviz2 and Foxglove's 3D panel."""

from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.builtin_interfaces import Duration
from go2vlm.msgs.geometry_msgs import Point, Pose, Vector3
from go2vlm.msgs.sensor_msgs import CompressedImage
from go2vlm.msgs.std_msgs import ColorRGBA, Header

__all__ = ["Marker", "MarkerArray", "MeshFile", "UVCoordinate"]


@register
@dataclass
class UVCoordinate(IdlStruct, typename="visualization_msgs::msg::dds_::UVCoordinate_"):
    u: types.float32 = 0.0
    v: types.float32 = 0.0


@register
@dataclass
class MeshFile(IdlStruct, typename="visualization_msgs::msg::dds_::MeshFile_"):
    filename: str = ""
    data: bytes = b""  # uint8[]


@register
@dataclass
class Marker(IdlStruct, typename="visualization_msgs::msg::dds_::Marker_"):
    header: Header = default(Header)
    ns: str = ""
    id: types.int32 = 0
    type: types.int32 = 0
    action: types.int32 = 0
    pose: Pose = default(Pose)
    scale: Vector3 = default(Vector3)
    color: ColorRGBA = default(ColorRGBA)
    lifetime: Duration = default(Duration)
    frame_locked: bool = False
    points: types.sequence[Point] = default(list)
    colors: types.sequence[ColorRGBA] = default(list)
    texture_resource: str = ""
    texture: CompressedImage = default(CompressedImage)
    uv_coordinates: types.sequence[UVCoordinate] = default(list)
    text: str = ""
    mesh_resource: str = ""
    mesh_file: MeshFile = default(MeshFile)
    mesh_use_embedded_materials: bool = False

    # type
    ARROW, CUBE, SPHERE, CYLINDER, LINE_STRIP, LINE_LIST, CUBE_LIST, SPHERE_LIST, POINTS = range(9)
    TEXT_VIEW_FACING, MESH_RESOURCE, TRIANGLE_LIST, ARROW_STRIP = 9, 10, 11, 12
    # action
    ADD, MODIFY, DELETE, DELETEALL = 0, 0, 2, 3


# The .msg text lists the constants (msgs/msgdef.py reads `__ros_constants__`), in the .msg's order.
Marker.__ros_constants__ = tuple(  # type: ignore[attr-defined]
    ("int32", name, value)
    for name, value in (
        ("ARROW", 0), ("CUBE", 1), ("SPHERE", 2), ("CYLINDER", 3), ("LINE_STRIP", 4), ("LINE_LIST", 5),
        ("CUBE_LIST", 6), ("SPHERE_LIST", 7), ("POINTS", 8), ("TEXT_VIEW_FACING", 9), ("MESH_RESOURCE", 10),
        ("TRIANGLE_LIST", 11), ("ARROW_STRIP", 12), ("ADD", 0), ("MODIFY", 0), ("DELETE", 2), ("DELETEALL", 3),
    )
)  # fmt: skip


@register
@dataclass
class MarkerArray(IdlStruct, typename="visualization_msgs::msg::dds_::MarkerArray_"):
    markers: types.sequence[Marker] = default(list)
