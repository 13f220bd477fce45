"""The Unitree types put the same bytes on the wire as unitree_sdk2 / unitree_ros2, and none of them
describes a uint8 as TK_UINT8 (which crashes the Go2's Cyclone 0.10.x on discovery)."""

# No `from __future__ import annotations`: the IDL struct declared below must keep real annotations.

import dataclasses
import typing
from functools import cache
from typing import Any

import numpy as np
import pytest
from busutil import rosbags_typestore
from cyclonedds.idl import IdlStruct, types
from cyclonedds.idl._type_normalize import get_extended_type_hints
from cyclonedds.idl._typesupport.DDS import XTypes as xt
from cyclonedds.idl._xt_builder import XTBuilder

from go2vlm.msgs import get_type, ros_name
from go2vlm.msgs import unitree as u

# unitree_ros2's .msg definitions (cyclonedds_ws/unitree/unitree_api, unitree_go), the reference spec.
UNITREE_MSGS = {
    "unitree_api/msg/RequestIdentity": "int64 id\nint64 api_id\n",
    "unitree_api/msg/RequestLease": "int64 id\n",
    "unitree_api/msg/RequestPolicy": "int32 priority\nbool noreply\n",
    "unitree_api/msg/RequestHeader": (
        "unitree_api/RequestIdentity identity\nunitree_api/RequestLease lease\nunitree_api/RequestPolicy policy\n"
    ),
    "unitree_api/msg/Request": "unitree_api/RequestHeader header\nstring parameter\nuint8[] binary\n",
    "unitree_api/msg/ResponseStatus": "int32 code\n",
    "unitree_api/msg/ResponseHeader": "unitree_api/RequestIdentity identity\nunitree_api/ResponseStatus status\n",
    "unitree_api/msg/Response": "unitree_api/ResponseHeader header\nstring data\nuint8[] binary\n",
    "unitree_go/msg/TimeSpec": "int32 sec\nuint32 nanosec\n",
    "unitree_go/msg/IMUState": (
        "float32[4] quaternion\nfloat32[3] gyroscope\nfloat32[3] accelerometer\nfloat32[3] rpy\nuint8 temperature\n"
    ),
    "unitree_go/msg/PathPoint": (
        "float32 t_from_start\nfloat32 x\nfloat32 y\nfloat32 yaw\nfloat32 vx\nfloat32 vy\nfloat32 vyaw\n"
    ),
    "unitree_go/msg/SportModeState": (
        "unitree_go/TimeSpec stamp\nuint32 error_code\nunitree_go/IMUState imu_state\nuint8 mode\n"
        "float32 progress\nuint8 gait_type\nfloat32 foot_raise_height\nfloat32[3] position\nfloat32 body_height\n"
        "float32[3] velocity\nfloat32 yaw_speed\nfloat32[4] range_obstacle\nint16[4] foot_force\n"
        "float32[12] foot_position_body\nfloat32[12] foot_speed_body\nunitree_go/PathPoint[10] path_point\n"
    ),
    "unitree_go/msg/MotorState": (
        "uint8 mode\nfloat32 q\nfloat32 dq\nfloat32 ddq\nfloat32 tau_est\nfloat32 q_raw\n"
        "float32 dq_raw\nfloat32 ddq_raw\nuint8 temperature\nuint32 lost\nuint32[2] reserve\n"
    ),
    "unitree_go/msg/BmsState": (
        "uint8 version_high\nuint8 version_low\nuint8 status\nuint8 soc\nint32 current\nuint16 cycle\n"
        "uint8[2] bq_ntc\nuint8[2] mcu_ntc\nuint16[15] cell_vol\n"
    ),
    "unitree_go/msg/LowState": (
        "uint8[2] head\nuint8 level_flag\nuint8 frame_reserve\nuint32[2] sn\nuint32[2] version\n"
        "uint16 bandwidth\nunitree_go/IMUState imu_state\nunitree_go/MotorState[20] motor_state\n"
        "unitree_go/BmsState bms_state\nint16[4] foot_force\nint16[4] foot_force_est\nuint32 tick\n"
        "uint8[40] wireless_remote\nuint8 bit_flag\nfloat32 adc_reel\nuint8 temperature_ntc1\n"
        "uint8 temperature_ntc2\nfloat32 power_v\nfloat32 power_a\nuint16[4] fan_frequency\n"
        "uint32 reserve\nuint32 crc\n"
    ),
}


# Every IDL struct the module defines, found by walking it (a type added later is checked too).
MODULE_TYPES = sorted(
    (v for v in vars(u).values() if isinstance(v, type) and issubclass(v, IdlStruct) and v.__module__ == u.__name__),
    key=lambda c: c.__idl_typename__,
)


@cache
def typestore() -> Any:
    return rosbags_typestore(UNITREE_MSGS)


def _sample(cls: type, rng: np.random.Generator) -> Any:
    """A message with every field set to a non-default value drawn from its IDL type."""
    kwargs = {}
    for name, tp in get_extended_type_hints(cls).items():
        kwargs[name] = _value(tp, rng)
    return cls(**kwargs)


def _value(tp: Any, rng: np.random.Generator) -> Any:
    if isinstance(tp, type) and issubclass(tp, IdlStruct):
        return _sample(tp, rng)
    if tp is bytes:
        return bytes(rng.integers(0, 256, int(rng.integers(0, 9)), dtype=np.uint8))
    if tp is str:
        return "".join(rng.choice(list('abc{}:"é ')) for _ in range(int(rng.integers(0, 9))))
    if tp is bool:
        return bool(rng.integers(0, 2))
    holder = typing.get_args(tp)[1] if typing.get_origin(tp) is typing.Annotated else tp
    if isinstance(holder, types.array):
        items = [_value(holder.subtype, rng) for _ in range(holder.length)]
        return bytes(items) if holder.subtype == types.byte else items  # a byte array decodes as bytes
    ranges = {"byte": (0, 255), "int16": (-32768, 32767), "uint16": (0, 65535), "uint32": (0, 2**32 - 1)}
    ranges["int32"] = (-(2**31), 2**31 - 1)
    ranges["int64"] = (-(2**63), 2**63 - 1)
    if isinstance(holder, str) and holder in ranges:
        lo, hi = ranges[holder]
        return int(rng.integers(lo, hi, endpoint=True))
    if holder == "float32":
        return float(np.float32(rng.normal() * 10))
    raise AssertionError(f"no sample for {tp!r}")


def _to_rosbags(msg: Any, typename: str) -> Any:
    ts = typestore()
    cls = ts.types[typename]
    kwargs = {name: _to_rosbags_value(getattr(msg, name), fdef) for name, fdef in ts.fielddefs[typename][1]}
    return cls(**kwargs)


def _to_rosbags_value(value: Any, fdef: Any) -> Any:
    if isinstance(value, IdlStruct):
        return _to_rosbags(value, ros_name(type(value)))
    if isinstance(value, bytes):
        return np.frombuffer(value, dtype=np.uint8).copy()
    if isinstance(value, list):
        if value and isinstance(value[0], IdlStruct):
            return [_to_rosbags(v, ros_name(type(v))) for v in value]
        (_, (element, _)), _ = fdef[1]  # an array's element type in the .msg, e.g. 'uint16'
        return np.array(value, dtype=np.dtype(element))
    return value


@pytest.mark.parametrize("cls", u.ALL_TYPES, ids=lambda c: ros_name(c))
def test_cdr_matches_rosbags(cls: type) -> None:
    rng = np.random.default_rng(5)
    ts = typestore()
    for _ in range(5):
        ours = _sample(cls, rng)
        ref = bytes(ts.serialize_cdr(_to_rosbags(ours, ros_name(cls)), ros_name(cls)))
        assert ours.serialize(use_version_2=False) == ref
        assert cls.deserialize(ref) == ours


def test_request_bytes_by_hand() -> None:
    req = u.Request(
        header=u.RequestHeader(identity=u.RequestIdentity(id=1, api_id=1008)), parameter="{}", binary=b"\x01\x02"
    )
    expected = bytes.fromhex(
        "00010000"  # encapsulation: CDR little endian
        "0100000000000000"  # identity.id (int64)
        "f003000000000000"  # identity.api_id = 1008
        "0000000000000000"  # lease.id
        "00000000"  # policy.priority
        "00000000"  # policy.noreply + 3 bytes padding
        "03000000"  # parameter length, with the NUL
        "7b7d0000"  # "{}", NUL, 1 byte padding
        "02000000"  # binary length
        "0102"  # binary
    )
    assert req.serialize(use_version_2=False) == expected


def test_sport_mode_state_layout() -> None:
    s = u.SportModeState(mode=7, gait_type=1, foot_force=[1, -2, 3, -4])
    raw = s.serialize(use_version_2=False)
    assert len(raw) == 4 + 512
    body = raw[4:]
    assert body[64] == 30 or body[64] == 0  # IMU temperature (uint8)
    assert body[65] == 7 and body[72] == 1  # mode, gait_type
    assert np.frombuffer(body[128:136], dtype="<i2").tolist() == [1, -2, 3, -4]


def test_types_resolve_by_name() -> None:
    assert get_type("unitree_api/msg/Request") is u.Request
    assert get_type("unitree_go/msg/SportModeState") is u.SportModeState
    assert u.Request.__idl_typename__ == "unitree_api::msg::dds_::Request_"


# -- no uint8 anywhere ------------------------------------------------------------------------


def _annotation_kinds(cls: type, seen: set[type] | None = None) -> list[str]:
    seen = seen if seen is not None else set()
    seen.add(cls)
    out = []
    for name, tp in get_extended_type_hints(cls).items():
        out.append(f"{cls.__name__}.{name}: {tp!r}")
        for inner in _inner_types(tp):
            if isinstance(inner, type) and issubclass(inner, IdlStruct) and inner not in seen:
                out += _annotation_kinds(inner, seen)
    return out


def _inner_types(tp: Any) -> list[Any]:
    if typing.get_origin(tp) is typing.Annotated:
        holder = typing.get_args(tp)[1]
        sub = getattr(holder, "subtype", None)
        return [tp] if sub is None else [tp, *_inner_types(sub)]
    return [tp]


def _type_kinds(obj: Any, out: set[int], depth: int = 0) -> set[int]:
    """Every TypeIdentifier discriminator in an XTypes object tree."""
    assert depth < 60
    if isinstance(obj, xt.TypeIdentifier):
        out.add(int(obj.discriminator))
    if isinstance(obj, (list, tuple)):
        for v in obj:
            _type_kinds(v, out, depth + 1)
    elif dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            _type_kinds(getattr(obj, f.name), out, depth + 1)
    elif hasattr(obj, "discriminator") and hasattr(obj, "value"):
        _type_kinds(obj.value, out, depth + 1)
    return out


def _xtypes_kinds(cls: type) -> set[int]:
    info, mapping = XTBuilder.process_type(cls)
    kinds: set[int] = set()
    _type_kinds(mapping, kinds)
    _type_kinds(info, kinds)
    return kinds


def test_all_types_listed() -> None:
    assert set(MODULE_TYPES) == set(u.ALL_TYPES)


@pytest.mark.parametrize("cls", MODULE_TYPES, ids=lambda c: ros_name(c))
def test_no_uint8_in_annotations(cls: type) -> None:
    bad = [a for a in _annotation_kinds(cls) if "uint8" in a]
    assert not bad, f"uint8 fields crash the Go2's DDS; use types.byte: {bad}"


@pytest.mark.parametrize("cls", MODULE_TYPES, ids=lambda c: ros_name(c))
def test_no_tk_uint8_in_type_object(cls: type) -> None:
    assert xt.TK_UINT8 not in _xtypes_kinds(cls)


def test_type_object_walk_sees_bytes_and_uint8() -> None:
    # The walker is meaningful: it finds TK_BYTE in our types and would find a TK_UINT8.
    assert xt.TK_BYTE in _xtypes_kinds(u.SportModeState)
    assert xt.TK_BYTE in _xtypes_kinds(u.Request)  # binary: sequence<octet>

    @dataclasses.dataclass
    class Bad(IdlStruct, typename="go2vlm_test::Bad_"):
        a: types.uint8 = 0

    assert xt.TK_UINT8 in _xtypes_kinds(Bad)
