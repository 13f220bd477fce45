"""go2vlm's own services (the object memory's WhereIs and MemoryFile) are byte for byte what a ROS 2
Jazzy peer built from the shipped .srv files puts on the wire: each Request/Response against rosbags
with those very files registered (split as rosidl splits a service)."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from rosbagsutil import fields_of, go2vlm_srvs, rosbags_cdr, strategy, to_ours

from go2vlm.bus.service import wire_type
from go2vlm.msgs import go2vlm_msgs as g

SERVICES = {"WhereIs": g.WhereIs, "MemoryFile": g.MemoryFile}
SRV_TYPES = sorted(go2vlm_srvs())


def our_type(typename: str) -> type:
    srv, _, part = typename.rpartition("/")[2].partition("_")
    return getattr(SERVICES[srv], part)


def test_every_srv_file_has_a_type() -> None:
    assert {f"go2vlm_msgs/srv/{n}_{p}" for n in SERVICES for p in ("Request", "Response")} == set(SRV_TYPES)
    assert {s.NAME for s in SERVICES.values()} == {f"go2vlm_msgs/srv/{n}" for n in SERVICES}


@pytest.mark.parametrize("typename", SRV_TYPES)
def test_names_and_field_order(typename: str) -> None:
    name = typename.rpartition("/")[2]
    assert our_type(typename).__idl_typename__ == f"go2vlm_msgs::srv::dds_::{name}_"
    assert wire_type(our_type(typename)).__idl_typename__ == f"go2vlm_msgs::srv::dds_::{name}_"
    assert [f for f, _ in fields_of(typename)] == list(our_type(typename).__dataclass_fields__)


@pytest.mark.parametrize("typename", SRV_TYPES)
def test_cdr_equals_rosbags(typename: str) -> None:
    cls = our_type(typename)

    @settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
    @given(values=strategy(typename))
    def run(values: dict[str, Any]) -> None:
        ours = to_ours(cls, values)
        ref = rosbags_cdr(typename, values)
        assert ours.serialize() == ref
        assert cls.deserialize(ref) == ours

    run()
