"""The parameter services' requests and replies are byte for byte what ROS 2 Jazzy puts on the wire:
each Request/Response against rosbags (the rcl_interfaces .srv definitions, split as rosidl splits
them), and the request wrapper against rmw_cyclonedds_cpp's layout (serdata.hpp
`cdds_request_header_t {uint64_t guid; int64_t seq;}` written after the 4-byte encapsulation header
and before the message by `serialize_top_level`, CDR little-endian)."""

from __future__ import annotations

import struct
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosbagsutil import RCL_SRVS, fields_of, rosbags_cdr, strategy, to_ours

from go2vlm.bus.service import endpoint_id, reply_topic, request_topic, unwrap, wire_type, wrap
from go2vlm.msgs import rcl_interfaces as rcl

SRV_TYPES = sorted(RCL_SRVS)
BY_NAME = {s.NAME.rpartition("/")[2]: s for s in rcl.PARAMETER_SERVICES.values()}


def our_type(typename: str) -> type:
    srv, _, part = typename.rpartition("/")[2].partition("_")
    return getattr(BY_NAME[srv], part)


def test_every_parameter_service_is_covered() -> None:
    names = {s.NAME.rpartition("/")[2] for s in rcl.PARAMETER_SERVICES.values()}
    assert {f"rcl_interfaces/srv/{n}_{part}" for n in names for part in ("Request", "Response")} == set(SRV_TYPES)


@pytest.mark.parametrize("typename", SRV_TYPES)
def test_dds_type_names_are_rmw_cyclonedds(typename: str) -> None:
    name = typename.rpartition("/")[2]
    assert our_type(typename).__idl_typename__ == f"rcl_interfaces::srv::dds_::{name}_"
    assert wire_type(our_type(typename)).__idl_typename__ == f"rcl_interfaces::srv::dds_::{name}_"


@pytest.mark.parametrize("typename", SRV_TYPES)
def test_field_order_is_the_spec(typename: str) -> None:
    assert [f for f, _ in fields_of(typename)] == list(our_type(typename).__dataclass_fields__)


@pytest.mark.parametrize("typename", SRV_TYPES)
def test_cdr_equals_rosbags_and_the_wrapper_is_rmw_cyclonedds(typename: str) -> None:
    cls = our_type(typename)

    @settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
    @given(
        values=strategy(typename),
        guid=st.integers(0, 2**64 - 1),
        seq=st.integers(-(2**63), 2**63 - 1),
    )
    def run(values: dict[str, Any], guid: int, seq: int) -> None:
        ours = to_ours(cls, values)
        ref = rosbags_cdr(typename, values)
        assert ours.serialize() == ref
        assert cls.deserialize(ref) == ours
        # rmw_cyclonedds: encapsulation header, then guid and seq (native little-endian), then the message.
        wire = ref[:4] + struct.pack("<Qq", guid, seq) + ref[4:]
        assert wrap(ours, guid, seq).serialize() == wire
        assert unwrap(wire_type(cls).deserialize(wire), cls) == (guid, seq, ours)

    run()


def test_header_bytes_spelled_out() -> None:
    raw = wrap(rcl.GetParameters_Request(names=["kp"]), 0x0102030405060708, 5).serialize()
    assert raw == bytes.fromhex(
        "00010000"  # CDR little-endian, options 0
        "0807060504030201"  # guid: the client's request writer instance handle
        "0500000000000000"  # seq
        "01000000" + "03000000" + "6b7000"  # names: 1 string "kp\0"
    )


def test_service_topic_names() -> None:
    # rmw_cyclonedds make_fqtopic(ROS_SERVICE_REQUESTER_PREFIX "rq", name, "Request") and "rr" ... "Reply".
    assert request_topic("/follower/get_parameters") == "rq/follower/get_parametersRequest"
    assert reply_topic("/follower/get_parameters") == "rr/follower/get_parametersReply"
    with pytest.raises(ValueError):
        request_topic("/bad name")


def test_endpoint_id_is_prefix_plus_counter() -> None:
    from go2vlm.bus import domain

    dp = domain.participant()
    a, b = endpoint_id(dp), endpoint_id(dp)
    prefix = dp.guid.bytes[:12]
    parts = [int(x, 16) for x in a.split(".")]
    assert len(parts) == 16 and bytes(parts[:12]) == prefix
    n = int.from_bytes(bytes(parts[12:]), "big")
    assert [int(x, 16) for x in b.split(".")][12:] == list((n + 1).to_bytes(4, "big"))
    assert a.split(".")[1] == f"{prefix[1]:x}"  # not zero-padded after the first byte, as csid_to_string
