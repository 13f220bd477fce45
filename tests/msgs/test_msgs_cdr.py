"""Our messages put exactly the bytes on the wire that ROS 2 does (rosbags as the reference CDR)."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosbagsutil import fields_of, rosbags_cdr, strategy, to_ours

from go2vlm.msgs import get_type, ros_name

TYPES = [
    "builtin_interfaces/msg/Time",
    "builtin_interfaces/msg/Duration",
    "std_msgs/msg/Header",
    "std_msgs/msg/String",
    "std_msgs/msg/Bool",
    "std_msgs/msg/Float32",
    "geometry_msgs/msg/Vector3",
    "geometry_msgs/msg/Point",
    "geometry_msgs/msg/PointStamped",
    "geometry_msgs/msg/Quaternion",
    "geometry_msgs/msg/Pose",
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovariance",
    "geometry_msgs/msg/Twist",
    "geometry_msgs/msg/TwistStamped",
    "geometry_msgs/msg/TwistWithCovariance",
    "geometry_msgs/msg/Transform",
    "geometry_msgs/msg/TransformStamped",
    "sensor_msgs/msg/Image",
    "sensor_msgs/msg/CompressedImage",
    "sensor_msgs/msg/RegionOfInterest",
    "sensor_msgs/msg/CameraInfo",
    "sensor_msgs/msg/Imu",
    "sensor_msgs/msg/JointState",
    "sensor_msgs/msg/PointField",
    "sensor_msgs/msg/PointCloud2",
    "sensor_msgs/msg/LaserScan",
    "nav_msgs/msg/Odometry",
    "nav_msgs/msg/Path",
    "nav_msgs/msg/MapMetaData",
    "nav_msgs/msg/OccupancyGrid",
    "vision_msgs/msg/Point2D",
    "vision_msgs/msg/Pose2D",
    "vision_msgs/msg/BoundingBox2D",
    "vision_msgs/msg/ObjectHypothesis",
    "vision_msgs/msg/ObjectHypothesisWithPose",
    "vision_msgs/msg/Detection2D",
    "vision_msgs/msg/Detection2DArray",
    "vision_msgs/msg/BoundingBox3D",
    "vision_msgs/msg/Detection3D",
    "vision_msgs/msg/Detection3DArray",
    "std_msgs/msg/ColorRGBA",
    "visualization_msgs/msg/UVCoordinate",
    "visualization_msgs/msg/MeshFile",
    "visualization_msgs/msg/Marker",
    "visualization_msgs/msg/MarkerArray",
    "go2vlm_msgs/msg/TrackedTarget",
    "tf2_msgs/msg/TFMessage",
    "rosgraph_msgs/msg/Clock",
    "rmw_dds_common/msg/Gid",
    "rmw_dds_common/msg/NodeEntitiesInfo",
    "rmw_dds_common/msg/ParticipantEntitiesInfo",
    "rcl_interfaces/msg/ParameterType",
    "rcl_interfaces/msg/ParameterValue",
    "rcl_interfaces/msg/Parameter",
    "rcl_interfaces/msg/FloatingPointRange",
    "rcl_interfaces/msg/IntegerRange",
    "rcl_interfaces/msg/ParameterDescriptor",
    "rcl_interfaces/msg/SetParametersResult",
    "rcl_interfaces/msg/ListParametersResult",
    "rcl_interfaces/msg/ParameterEvent",
]


def check(typename: str, values: dict[str, Any]) -> None:
    cls = get_type(typename)
    ours = to_ours(cls, values)
    ref = rosbags_cdr(typename, values)
    assert ours.serialize() == ref, f"{typename}: CDR differs from rosbags"
    assert cls.deserialize(ref) == ours, f"{typename}: decoding rosbags' bytes gives a different message"


@pytest.mark.parametrize("typename", TYPES)
def test_type_names_match_ros(typename: str) -> None:
    cls = get_type(typename)
    assert ros_name(cls) == typename
    pkg, _, name = typename.split("/")
    assert cls.__idl_typename__ == f"{pkg}::msg::dds_::{name}_"


@pytest.mark.parametrize("typename", TYPES)
def test_cdr_equals_rosbags(typename: str) -> None:
    @settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
    @given(values=strategy(typename))
    def run(values: dict[str, Any]) -> None:
        check(typename, values)

    run()


# Explicit alignment cases: strings of 0..8 bytes (UTF-8) before 8-byte doubles, odd octet payloads.
@pytest.mark.parametrize("frame_id", ["", "a", "ab", "abc", "abcd", "abcde", "abcdef", "abcdefg", "é", "相机", "🐕"])
def test_string_before_doubles(frame_id: str) -> None:
    header = {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": frame_id}
    pose = {"position": {"x": 1.5, "y": -2.0, "z": 3.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}
    check("geometry_msgs/msg/PoseStamped", {"header": header, "pose": pose})
    tf = {"translation": {"x": 1.0, "y": 2.0, "z": 3.0}, "rotation": pose["orientation"]}
    check(
        "geometry_msgs/msg/TransformStamped",
        {"header": header, "child_frame_id": frame_id[::-1], "transform": tf},
    )


@pytest.mark.parametrize("n", [0, 1, 2, 3, 5, 7, 9])
def test_odd_octet_lengths(n: int) -> None:
    header = {"stamp": {"sec": -5, "nanosec": 999_999_999}, "frame_id": "cam"}
    data = list(range(n))
    check(
        "sensor_msgs/msg/Image",
        {
            "header": header,
            "height": 1,
            "width": n,
            "encoding": "mono8",
            "is_bigendian": 0,
            "step": n,
            "data": data,
        },
    )
    check("sensor_msgs/msg/CompressedImage", {"header": header, "format": "jpeg", "data": data})


def test_empty_sequences() -> None:
    header = {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""}
    check("sensor_msgs/msg/JointState", {"header": header, "name": [], "position": [], "velocity": [], "effort": []})
    check("tf2_msgs/msg/TFMessage", {"transforms": []})
    check("vision_msgs/msg/Detection2DArray", {"header": header, "detections": []})
    check("vision_msgs/msg/Detection3DArray", {"header": header, "detections": []})


@given(st.data())
@settings(max_examples=20, deadline=None)
def test_detections_with_unicode_labels(data: st.DataObject) -> None:
    values = data.draw(strategy("vision_msgs/msg/Detection2DArray", max_seq=4))
    check("vision_msgs/msg/Detection2DArray", values)


def test_every_registered_type_is_covered() -> None:
    from go2vlm.msgs import REGISTRY

    get_type("std_msgs/msg/String")  # loads the optional modules
    ours = {ros_name(c) for c in REGISTRY.values() if not ros_name(c).startswith("unitree")}
    assert ours <= set(TYPES), f"types without a CDR test: {sorted(ours - set(TYPES))}"


def test_spec_field_order_is_ours() -> None:
    for typename in TYPES:
        cls = get_type(typename)
        assert [f for f, _ in fields_of(typename)] == list(cls.__dataclass_fields__), typename


def test_tracked_target_constants_are_the_msg_files() -> None:
    """The state numbers in go2vlm.msgs.go2vlm_msgs are the constants of the shipped .msg file."""
    from rosbagsutil import typestore

    from go2vlm.msgs import go2vlm_msgs as g

    consts = dict((name, value) for name, _, value in typestore().fielddefs["go2vlm_msgs/msg/TrackedTarget"][0])
    assert consts == {name.upper(): state for state, name in g.STATE_NAMES.items()}
    assert consts == {"IDLE": g.IDLE, "SEARCHING": g.SEARCHING, "TRACKING": g.TRACKING, "LOST": g.LOST,
                      "UNGROUNDABLE": g.UNGROUNDABLE}  # fmt: skip


def test_marker_constants_are_jazzys() -> None:
    """Marker's type and action numbers are the ones in ROS 2 Jazzy's Marker.msg (rosbags' store)."""
    from rosbagsutil import typestore

    from go2vlm.msgs.visualization_msgs import Marker

    consts = [(name, typ, value) for name, typ, value in typestore().fielddefs["visualization_msgs/msg/Marker"][0]]
    assert [(n, t, v) for t, n, v in Marker.__ros_constants__] == consts  # type: ignore[attr-defined]
    assert (Marker.CYLINDER, Marker.TEXT_VIEW_FACING, Marker.DELETEALL) == (3, 9, 3)


@pytest.mark.parametrize("n", [0, 1, 3, 7, 1201])
def test_occupancy_grid_of_every_cell_value(n: int) -> None:
    """A map's int8 cells (-1 unknown, 0 free, 1..100 occupied) in odd lengths, after a float32."""
    info = {
        "map_load_time": {"sec": 3, "nanosec": 4},
        "resolution": 0.0625,  # exact in float32
        "width": n,
        "height": 1,
        "origin": {
            "position": {"x": -30.0, "y": -0.5, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
        },
    }
    data = [(i % 102) - 1 for i in range(n)]  # -1 .. 100
    check("nav_msgs/msg/OccupancyGrid", {"header": {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": "odom"},
                                         "info": info, "data": data})  # fmt: skip
