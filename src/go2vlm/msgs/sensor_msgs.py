"""sensor_msgs/msg: Image, CompressedImage, CameraInfo, RegionOfInterest, Imu, JointState, PointField,
PointCloud2, LaserScan.

Octet payloads are declared `bytes`: cyclonedds then reads and writes them as one block instead
of one Python call per byte (about 2 ms instead of 40 ms for a 640x480 bgr8 frame).
"""

from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.geometry_msgs import Quaternion, Vector3
from go2vlm.msgs.std_msgs import Header


@register
@dataclass
class Image(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    header: Header = default(Header)
    height: types.uint32 = 0
    width: types.uint32 = 0
    encoding: str = ""
    is_bigendian: types.byte = 0
    step: types.uint32 = 0
    data: bytes = b""


@register
@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs::msg::dds_::CompressedImage_"):
    header: Header = default(Header)
    format: str = ""
    data: bytes = b""


@register
@dataclass
class RegionOfInterest(IdlStruct, typename="sensor_msgs::msg::dds_::RegionOfInterest_"):
    x_offset: types.uint32 = 0
    y_offset: types.uint32 = 0
    height: types.uint32 = 0
    width: types.uint32 = 0
    do_rectify: bool = False


@register
@dataclass
class CameraInfo(IdlStruct, typename="sensor_msgs::msg::dds_::CameraInfo_"):
    header: Header = default(Header)
    height: types.uint32 = 0
    width: types.uint32 = 0
    distortion_model: str = ""
    d: types.sequence[float] = default(list)
    k: types.array[float, 9] = default(lambda: [0.0] * 9)
    r: types.array[float, 9] = default(lambda: [0.0] * 9)
    p: types.array[float, 12] = default(lambda: [0.0] * 12)
    binning_x: types.uint32 = 0
    binning_y: types.uint32 = 0
    roi: RegionOfInterest = default(RegionOfInterest)


@register
@dataclass
class Imu(IdlStruct, typename="sensor_msgs::msg::dds_::Imu_"):
    header: Header = default(Header)
    orientation: Quaternion = default(Quaternion)
    orientation_covariance: types.array[float, 9] = default(lambda: [0.0] * 9)
    angular_velocity: Vector3 = default(Vector3)
    angular_velocity_covariance: types.array[float, 9] = default(lambda: [0.0] * 9)
    linear_acceleration: Vector3 = default(Vector3)
    linear_acceleration_covariance: types.array[float, 9] = default(lambda: [0.0] * 9)


@register
@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header = default(Header)
    name: types.sequence[str] = default(list)
    position: types.sequence[float] = default(list)
    velocity: types.sequence[float] = default(list)
    effort: types.sequence[float] = default(list)


# PointField.datatype values (sensor_msgs/msg/PointField constants).
INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64 = range(1, 9)
_DATATYPES = ("INT8", "UINT8", "INT16", "UINT16", "INT32", "UINT32", "FLOAT32", "FLOAT64")


@register
@dataclass
class PointField(IdlStruct, typename="sensor_msgs::msg::dds_::PointField_"):
    name: str = ""
    offset: types.uint32 = 0
    datatype: types.byte = 0
    count: types.uint32 = 0


# The .msg text lists the datatype constants (msgs/msgdef.py reads `__ros_constants__`).
PointField.__ros_constants__ = tuple(("uint8", n, i) for i, n in enumerate(_DATATYPES, 1))  # type: ignore[attr-defined]


@register
@dataclass
class PointCloud2(IdlStruct, typename="sensor_msgs::msg::dds_::PointCloud2_"):
    header: Header = default(Header)
    height: types.uint32 = 0
    width: types.uint32 = 0
    fields: types.sequence[PointField] = default(list)
    is_bigendian: bool = False
    point_step: types.uint32 = 0
    row_step: types.uint32 = 0
    data: bytes = b""
    is_dense: bool = False


@register
@dataclass
class LaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    header: Header = default(Header)
    angle_min: types.float32 = 0.0
    angle_max: types.float32 = 0.0
    angle_increment: types.float32 = 0.0
    time_increment: types.float32 = 0.0
    scan_time: types.float32 = 0.0
    range_min: types.float32 = 0.0
    range_max: types.float32 = 0.0
    ranges: types.sequence[types.float32] = default(list)
    intensities: types.sequence[types.float32] = default(list)
