"""sensor_msgs/msg: Image, CompressedImage, CameraInfo, RegionOfInterest, Imu, JointState.

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
