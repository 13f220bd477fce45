"""Unitree's own DDS types (unitree_api/msg, unitree_go/msg), wire-compatible with unitree_sdk2.

The Go2 publishes these WITHOUT ROS naming conventions for the type (`unitree_api::msg::dds_::Request_`
is the IDL type name, exactly as here) but on `rt/...` topics, so our bus reaches them as ROS topics
(`/api/sport/request` -> DDS `rt/api/sport/request`).

Every uint8 is `types.byte` (uint8[] as `bytes`, uint8[N] as `types.array[types.byte, N]`): a
cyclonedds-11 TK_UINT8 type object crashes the Go2's Cyclone 0.10.x processes on discovery.
All structs are final (@final in Unitree's IDL), which is also cyclonedds-python's default.
"""

from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register

# -- unitree_api/msg: the request/response envelope of every Unitree RPC service --------------


@register
@dataclass
class RequestIdentity(IdlStruct, typename="unitree_api::msg::dds_::RequestIdentity_"):
    id: types.int64 = 0
    api_id: types.int64 = 0


@register
@dataclass
class RequestLease(IdlStruct, typename="unitree_api::msg::dds_::RequestLease_"):
    id: types.int64 = 0


@register
@dataclass
class RequestPolicy(IdlStruct, typename="unitree_api::msg::dds_::RequestPolicy_"):
    priority: types.int32 = 0
    noreply: bool = False


@register
@dataclass
class RequestHeader(IdlStruct, typename="unitree_api::msg::dds_::RequestHeader_"):
    identity: RequestIdentity = default(RequestIdentity)
    lease: RequestLease = default(RequestLease)
    policy: RequestPolicy = default(RequestPolicy)


@register
@dataclass
class Request(IdlStruct, typename="unitree_api::msg::dds_::Request_"):
    header: RequestHeader = default(RequestHeader)
    parameter: str = ""
    binary: bytes = b""


@register
@dataclass
class ResponseStatus(IdlStruct, typename="unitree_api::msg::dds_::ResponseStatus_"):
    code: types.int32 = 0


@register
@dataclass
class ResponseHeader(IdlStruct, typename="unitree_api::msg::dds_::ResponseHeader_"):
    identity: RequestIdentity = default(RequestIdentity)
    status: ResponseStatus = default(ResponseStatus)


@register
@dataclass
class Response(IdlStruct, typename="unitree_api::msg::dds_::Response_"):
    header: ResponseHeader = default(ResponseHeader)
    data: str = ""
    binary: bytes = b""


# -- unitree_go/msg: sport-mode state ------------------------------------------------------------


@register
@dataclass
class TimeSpec(IdlStruct, typename="unitree_go::msg::dds_::TimeSpec_"):
    sec: types.int32 = 0
    nanosec: types.uint32 = 0


@register
@dataclass
class IMUState(IdlStruct, typename="unitree_go::msg::dds_::IMUState_"):
    quaternion: types.array[types.float32, 4] = default(lambda: [1.0, 0.0, 0.0, 0.0])  # w, x, y, z
    gyroscope: types.array[types.float32, 3] = default(lambda: [0.0] * 3)
    accelerometer: types.array[types.float32, 3] = default(lambda: [0.0] * 3)
    rpy: types.array[types.float32, 3] = default(lambda: [0.0] * 3)
    temperature: types.byte = 0


@register
@dataclass
class PathPoint(IdlStruct, typename="unitree_go::msg::dds_::PathPoint_"):
    t_from_start: types.float32 = 0.0
    x: types.float32 = 0.0
    y: types.float32 = 0.0
    yaw: types.float32 = 0.0
    vx: types.float32 = 0.0
    vy: types.float32 = 0.0
    vyaw: types.float32 = 0.0


@register
@dataclass
class SportModeState(IdlStruct, typename="unitree_go::msg::dds_::SportModeState_"):
    stamp: TimeSpec = default(TimeSpec)
    error_code: types.uint32 = 0
    imu_state: IMUState = default(IMUState)
    mode: types.byte = 0
    progress: types.float32 = 0.0
    gait_type: types.byte = 0
    foot_raise_height: types.float32 = 0.0
    position: types.array[types.float32, 3] = default(lambda: [0.0] * 3)
    body_height: types.float32 = 0.0
    velocity: types.array[types.float32, 3] = default(lambda: [0.0] * 3)
    yaw_speed: types.float32 = 0.0
    range_obstacle: types.array[types.float32, 4] = default(lambda: [0.0] * 4)
    foot_force: types.array[types.int16, 4] = default(lambda: [0] * 4)
    foot_position_body: types.array[types.float32, 12] = default(lambda: [0.0] * 12)
    foot_speed_body: types.array[types.float32, 12] = default(lambda: [0.0] * 12)
    path_point: types.array[PathPoint, 10] = default(lambda: [PathPoint() for _ in range(10)])


# -- unitree_go/msg: low-level state (rt/lowstate, ~500 Hz on a Go2): motors, battery, IMU -----------
# Field for field as unitree_sdk2's LowState_/MotorState_/BmsState_ IDL; unitree_ros2's .msg files
# write some of these uint8s as int8 (temperatures), see msgs/msgdef.py FIELD_OVERRIDES.

GO2_MOTORS = 20  # motor_state slots; a Go2 uses the first 12 (FR, FL, RR, RL x hip, thigh, calf)


@register
@dataclass
class MotorState(IdlStruct, typename="unitree_go::msg::dds_::MotorState_"):
    mode: types.byte = 0
    q: types.float32 = 0.0
    dq: types.float32 = 0.0
    ddq: types.float32 = 0.0
    tau_est: types.float32 = 0.0
    q_raw: types.float32 = 0.0
    dq_raw: types.float32 = 0.0
    ddq_raw: types.float32 = 0.0
    temperature: types.byte = 0  # deg C
    lost: types.uint32 = 0
    reserve: types.array[types.uint32, 2] = default(lambda: [0, 0])


@register
@dataclass
class BmsState(IdlStruct, typename="unitree_go::msg::dds_::BmsState_"):
    version_high: types.byte = 0
    version_low: types.byte = 0
    status: types.byte = 0
    soc: types.byte = 0  # state of charge, percent
    current: types.int32 = 0  # mA, negative while discharging
    cycle: types.uint16 = 0
    bq_ntc: types.array[types.byte, 2] = bytes(2)  # deg C
    mcu_ntc: types.array[types.byte, 2] = bytes(2)  # deg C
    cell_vol: types.array[types.uint16, 15] = default(lambda: [0] * 15)  # mV


@register
@dataclass
class LowState(IdlStruct, typename="unitree_go::msg::dds_::LowState_"):
    head: types.array[types.byte, 2] = b"\xfe\xef"
    level_flag: types.byte = 0
    frame_reserve: types.byte = 0
    sn: types.array[types.uint32, 2] = default(lambda: [0, 0])
    version: types.array[types.uint32, 2] = default(lambda: [0, 0])
    bandwidth: types.uint16 = 0
    imu_state: IMUState = default(IMUState)
    motor_state: types.array[MotorState, 20] = default(lambda: [MotorState() for _ in range(GO2_MOTORS)])
    bms_state: BmsState = default(BmsState)
    foot_force: types.array[types.int16, 4] = default(lambda: [0] * 4)
    foot_force_est: types.array[types.int16, 4] = default(lambda: [0] * 4)
    tick: types.uint32 = 0  # ms
    wireless_remote: types.array[types.byte, 40] = bytes(40)
    bit_flag: types.byte = 0
    adc_reel: types.float32 = 0.0
    temperature_ntc1: types.byte = 0
    temperature_ntc2: types.byte = 0
    power_v: types.float32 = 0.0  # battery voltage
    power_a: types.float32 = 0.0
    fan_frequency: types.array[types.uint16, 4] = default(lambda: [0] * 4)
    reserve: types.uint32 = 0
    crc: types.uint32 = 0


ALL_TYPES: tuple[type[IdlStruct], ...] = (
    RequestIdentity,
    RequestLease,
    RequestPolicy,
    RequestHeader,
    Request,
    ResponseStatus,
    ResponseHeader,
    Response,
    TimeSpec,
    IMUState,
    PathPoint,
    SportModeState,
    MotorState,
    BmsState,
    LowState,
)
