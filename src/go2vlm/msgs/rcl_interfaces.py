"""rcl_interfaces (ROS 2 Jazzy): the parameter messages and the six parameter services every ROS 2 node
serves (`ros2 param list | get | set | describe | dump`).

Messages: ParameterType (constants), ParameterValue, Parameter, ParameterDescriptor,
FloatingPointRange, IntegerRange, SetParametersResult, ListParametersResult, ParameterEvent.
Services, each a class with `NAME`, `Request` and `Response` as in rclpy: ListParameters,
GetParameters, SetParameters, SetParametersAtomically, DescribeParameters, GetParameterTypes. A
request/response struct is named as rmw_cyclonedds_cpp names it on the wire
(`rcl_interfaces::srv::dds_::GetParameters_Request_`); the request header that rmw puts in front of
it is go2vlm.bus.service's business, not part of these types. uint8 fields are `types.byte` (see
_base.py); `byte[]` is `bytes`, one octet block.
"""

from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.builtin_interfaces import Time


@register
@dataclass
class ParameterType(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterType_"):
    """The `type` codes of ParameterValue and ParameterDescriptor (the message itself carries nothing)."""

    structure_needs_at_least_one_member: types.byte = 0


PARAMETER_NOT_SET = 0
PARAMETER_BOOL = 1
PARAMETER_INTEGER = 2
PARAMETER_DOUBLE = 3
PARAMETER_STRING = 4
PARAMETER_BYTE_ARRAY = 5
PARAMETER_BOOL_ARRAY = 6
PARAMETER_INTEGER_ARRAY = 7
PARAMETER_DOUBLE_ARRAY = 8
PARAMETER_STRING_ARRAY = 9
# Its .msg text lists these constants (msgs/msgdef.py reads `__ros_constants__`).
ParameterType.__ros_constants__ = (  # type: ignore[attr-defined]
    ("uint8", "PARAMETER_NOT_SET", PARAMETER_NOT_SET),
    ("uint8", "PARAMETER_BOOL", PARAMETER_BOOL),
    ("uint8", "PARAMETER_INTEGER", PARAMETER_INTEGER),
    ("uint8", "PARAMETER_DOUBLE", PARAMETER_DOUBLE),
    ("uint8", "PARAMETER_STRING", PARAMETER_STRING),
    ("uint8", "PARAMETER_BYTE_ARRAY", PARAMETER_BYTE_ARRAY),
    ("uint8", "PARAMETER_BOOL_ARRAY", PARAMETER_BOOL_ARRAY),
    ("uint8", "PARAMETER_INTEGER_ARRAY", PARAMETER_INTEGER_ARRAY),
    ("uint8", "PARAMETER_DOUBLE_ARRAY", PARAMETER_DOUBLE_ARRAY),
    ("uint8", "PARAMETER_STRING_ARRAY", PARAMETER_STRING_ARRAY),
)

# As `ros2 param describe` spells them.
TYPE_NAMES = {
    PARAMETER_NOT_SET: "not set",
    PARAMETER_BOOL: "boolean",
    PARAMETER_INTEGER: "integer",
    PARAMETER_DOUBLE: "double",
    PARAMETER_STRING: "string",
    PARAMETER_BYTE_ARRAY: "byte array",
    PARAMETER_BOOL_ARRAY: "boolean array",
    PARAMETER_INTEGER_ARRAY: "integer array",
    PARAMETER_DOUBLE_ARRAY: "double array",
    PARAMETER_STRING_ARRAY: "string array",
}


@register
@dataclass
class ParameterValue(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterValue_"):
    type: types.byte = PARAMETER_NOT_SET
    bool_value: bool = False
    integer_value: types.int64 = 0
    double_value: types.float64 = 0.0
    string_value: str = ""
    byte_array_value: bytes = b""
    bool_array_value: types.sequence[bool] = default(list)
    integer_array_value: types.sequence[types.int64] = default(list)
    double_array_value: types.sequence[types.float64] = default(list)
    string_array_value: types.sequence[str] = default(list)


@register
@dataclass
class Parameter(IdlStruct, typename="rcl_interfaces::msg::dds_::Parameter_"):
    name: str = ""
    value: ParameterValue = default(ParameterValue)


@register
@dataclass
class FloatingPointRange(IdlStruct, typename="rcl_interfaces::msg::dds_::FloatingPointRange_"):
    from_value: types.float64 = 0.0
    to_value: types.float64 = 0.0
    step: types.float64 = 0.0


@register
@dataclass
class IntegerRange(IdlStruct, typename="rcl_interfaces::msg::dds_::IntegerRange_"):
    from_value: types.int64 = 0
    to_value: types.int64 = 0
    step: types.uint64 = 0


@register
@dataclass
class ParameterDescriptor(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterDescriptor_"):
    name: str = ""
    type: types.byte = PARAMETER_NOT_SET
    description: str = ""
    additional_constraints: str = ""
    read_only: bool = False
    dynamic_typing: bool = False
    floating_point_range: types.sequence[FloatingPointRange, 1] = default(list)
    integer_range: types.sequence[IntegerRange, 1] = default(list)


@register
@dataclass
class SetParametersResult(IdlStruct, typename="rcl_interfaces::msg::dds_::SetParametersResult_"):
    successful: bool = False
    reason: str = ""


@register
@dataclass
class ListParametersResult(IdlStruct, typename="rcl_interfaces::msg::dds_::ListParametersResult_"):
    names: types.sequence[str] = default(list)
    prefixes: types.sequence[str] = default(list)


@register
@dataclass
class ParameterEvent(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterEvent_"):
    stamp: Time = default(Time)
    node: str = ""
    new_parameters: types.sequence[Parameter] = default(list)
    changed_parameters: types.sequence[Parameter] = default(list)
    deleted_parameters: types.sequence[Parameter] = default(list)


# -- services ------------------------------------------------------------------------------------
# Request/response structs are not registered as topic types: on the wire they only ever travel
# inside rmw_cyclonedds' request wrapper (go2vlm.bus.service).

DEPTH_RECURSIVE = 0  # ListParameters.Request.depth: all levels


@dataclass
class ListParameters_Request(IdlStruct, typename="rcl_interfaces::srv::dds_::ListParameters_Request_"):
    prefixes: types.sequence[str] = default(list)
    depth: types.uint64 = DEPTH_RECURSIVE


@dataclass
class ListParameters_Response(IdlStruct, typename="rcl_interfaces::srv::dds_::ListParameters_Response_"):
    result: ListParametersResult = default(ListParametersResult)


@dataclass
class GetParameters_Request(IdlStruct, typename="rcl_interfaces::srv::dds_::GetParameters_Request_"):
    names: types.sequence[str] = default(list)


@dataclass
class GetParameters_Response(IdlStruct, typename="rcl_interfaces::srv::dds_::GetParameters_Response_"):
    values: types.sequence[ParameterValue] = default(list)


@dataclass
class SetParameters_Request(IdlStruct, typename="rcl_interfaces::srv::dds_::SetParameters_Request_"):
    parameters: types.sequence[Parameter] = default(list)


@dataclass
class SetParameters_Response(IdlStruct, typename="rcl_interfaces::srv::dds_::SetParameters_Response_"):
    results: types.sequence[SetParametersResult] = default(list)


@dataclass
class SetParametersAtomically_Request(
    IdlStruct, typename="rcl_interfaces::srv::dds_::SetParametersAtomically_Request_"
):
    parameters: types.sequence[Parameter] = default(list)


@dataclass
class SetParametersAtomically_Response(
    IdlStruct, typename="rcl_interfaces::srv::dds_::SetParametersAtomically_Response_"
):
    result: SetParametersResult = default(SetParametersResult)


@dataclass
class DescribeParameters_Request(IdlStruct, typename="rcl_interfaces::srv::dds_::DescribeParameters_Request_"):
    names: types.sequence[str] = default(list)


@dataclass
class DescribeParameters_Response(IdlStruct, typename="rcl_interfaces::srv::dds_::DescribeParameters_Response_"):
    descriptors: types.sequence[ParameterDescriptor] = default(list)


@dataclass
class GetParameterTypes_Request(IdlStruct, typename="rcl_interfaces::srv::dds_::GetParameterTypes_Request_"):
    names: types.sequence[str] = default(list)


@dataclass
class GetParameterTypes_Response(IdlStruct, typename="rcl_interfaces::srv::dds_::GetParameterTypes_Response_"):
    types: bytes = b""  # uint8[]: one ParameterType code per name


class ListParameters:
    NAME = "rcl_interfaces/srv/ListParameters"
    Request = ListParameters_Request
    Response = ListParameters_Response


class GetParameters:
    NAME = "rcl_interfaces/srv/GetParameters"
    Request = GetParameters_Request
    Response = GetParameters_Response


class SetParameters:
    NAME = "rcl_interfaces/srv/SetParameters"
    Request = SetParameters_Request
    Response = SetParameters_Response


class SetParametersAtomically:
    NAME = "rcl_interfaces/srv/SetParametersAtomically"
    Request = SetParametersAtomically_Request
    Response = SetParametersAtomically_Response


class DescribeParameters:
    NAME = "rcl_interfaces/srv/DescribeParameters"
    Request = DescribeParameters_Request
    Response = DescribeParameters_Response


class GetParameterTypes:
    NAME = "rcl_interfaces/srv/GetParameterTypes"
    Request = GetParameterTypes_Request
    Response = GetParameterTypes_Response


# The services every ROS 2 node serves for its parameters: `~/<name>`, as rclcpp's ParameterService.
PARAMETER_SERVICES: dict[
    str,
    type[DescribeParameters]
    | type[GetParameterTypes]
    | type[GetParameters]
    | type[ListParameters]
    | type[SetParameters]
    | type[SetParametersAtomically],
] = {
    "describe_parameters": DescribeParameters,
    "get_parameter_types": GetParameterTypes,
    "get_parameters": GetParameters,
    "list_parameters": ListParameters,
    "set_parameters": SetParameters,
    "set_parameters_atomically": SetParametersAtomically,
}
