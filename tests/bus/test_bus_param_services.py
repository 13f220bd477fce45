"""Parameters at runtime over real DDS: every node serves rcl_interfaces' parameter services; a
change is validated as at start-up, applied in one step, or refused with its reason and nothing
changed; the bytes on the wire are rmw_cyclonedds_cpp's (a 'foreign' client and server made of
rosbags bytes talk to ours)."""

from __future__ import annotations

import dataclasses
import struct
import threading
import typing
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest
from busutil import Recorder, foreign_write, raw_take, wait_for
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from rosbagsutil import typestore

from go2vlm.bus import Node, domain, param, running
from go2vlm.bus import discovery_info as di
from go2vlm.bus.param_services import (
    ParameterClient,
    describe,
    from_value,
    param_kind,
    parse_value,
    python_to_value,
    to_value,
    value_of,
)
from go2vlm.bus.params import ParamError, build_config
from go2vlm.bus.qos import QOS_PARAMETERS
from go2vlm.bus.service import ServiceClient, reply_topic, request_topic, wire_type
from go2vlm.launch.registry import NODES, node_class
from go2vlm.msgs import rcl_interfaces as rcl
from go2vlm.msgs.rcl_interfaces import (
    PARAMETER_BOOL,
    PARAMETER_BOOL_ARRAY,
    PARAMETER_DOUBLE,
    PARAMETER_DOUBLE_ARRAY,
    PARAMETER_INTEGER,
    PARAMETER_NOT_SET,
    PARAMETER_STRING,
    PARAMETER_STRING_ARRAY,
    ParameterEvent,
    ParameterValue,
)


@dataclass
class KnobsConfig:
    gain: float = param(1.0, help="a gain", min=0.0, max=10.0, live=True)
    count: int = param(2, help="a count", min=0, max=100, live=True)
    label: str = param("a", choices=("a", "b", "c"), live=True)
    flags: list[bool] = param(list, live=True)
    table: list[dict] = param(list, help="rows of {name, ...}", live=True)
    maybe: float | None = param(None, live=True)
    rate_hz: float = param(10.0, help="read at start-up", min=1.0)

    def validate(self) -> None:
        if self.label == "c" and self.count > 10:
            raise ValueError("label c allows a count of at most 10")
        for row in self.table:
            if "name" not in row:
                raise ValueError("every table row needs a name")


class Knobs(Node):
    name = "knobs"
    Config = KnobsConfig

    def __init__(self, config: KnobsConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        self.changes: list[frozenset[str]] = []
        self.fail_next = False

    def check_params(self, new: KnobsConfig, changed: frozenset[str]) -> None:
        if new.gain == 7.0:
            raise ValueError("7 is refused by the node")

    def on_params_changed(self, old: KnobsConfig, changed: frozenset[str]) -> None:
        if self.fail_next:
            self.fail_next = False
            raise RuntimeError("cannot apply")
        self.changes.append(changed)


@pytest.fixture
def knobs() -> Iterator[tuple[Knobs, ParameterClient]]:
    node = Knobs()
    with running(node), ParameterClient("knobs", timeout_s=15) as client:
        yield node, client


def v(value: Any) -> ParameterValue:
    return python_to_value(value)


# -- types -----------------------------------------------------------------------------------------
def test_param_kinds() -> None:
    assert param_kind(bool) == (PARAMETER_BOOL, False)
    assert param_kind(int) == (PARAMETER_INTEGER, False)
    assert param_kind(float | None) == (PARAMETER_DOUBLE, False)
    assert param_kind(str) == (PARAMETER_STRING, False)
    assert param_kind(list[str]) == (PARAMETER_STRING_ARRAY, False)
    assert param_kind(tuple[float, float, float] | None) == (PARAMETER_DOUBLE_ARRAY, False)
    for structured in (list[dict], dict, list[list[int]]):
        assert param_kind(structured) == (PARAMETER_STRING, True)  # YAML text


def test_values_convert_both_ways() -> None:
    assert value_of(to_value(0.4, float)) == 0.4
    assert value_of(to_value([True, False], list[bool])) == [True, False]
    assert to_value(None, float | None).type == PARAMETER_NOT_SET
    assert from_value(v(3), float, "gain") == 3  # an integer for a double, as a whole number
    assert from_value(ParameterValue(), float | None, "maybe") is None
    table = [{"name": "a", "p": 1}]
    text = to_value(table, list[dict])
    assert text.type == PARAMETER_STRING and text.string_value == "[{name: a, p: 1}]"
    with pytest.raises(ParamError, match="'gain' is a double, setting it to a string is not allowed"):
        from_value(v("abc"), float, "gain")
    with pytest.raises(ParamError, match="cannot be unset"):
        from_value(ParameterValue(), float, "gain")


def test_command_line_text_follows_the_declared_type() -> None:
    assert parse_value("0.4", PARAMETER_DOUBLE) == v(0.4)
    assert parse_value("1", PARAMETER_DOUBLE) == v(1.0)  # `1` for a double is 1.0
    assert parse_value("123", PARAMETER_STRING) == v("123")  # text stays text
    assert parse_value("[[0, 1]]", PARAMETER_STRING) == v("[[0, 1]]")
    assert parse_value("abc", PARAMETER_DOUBLE) == v("abc")  # the node says why it is wrong
    assert parse_value("[1, 2.5]", PARAMETER_DOUBLE_ARRAY) == v([1.0, 2.5])


# -- a node's services -------------------------------------------------------------------------------
def test_list_get_types_describe(knobs: tuple[Knobs, ParameterClient]) -> None:
    _node, client = knobs
    names = client.list()
    assert names == sorted(["gain", "count", "label", "flags", "table", "maybe", "rate_hz", "use_sim_time"])
    got = dict(zip(names, (value_of(x) for x in client.get(names)), strict=True))
    assert got == {
        "gain": 1.0,
        "count": 2,
        "label": "a",
        "flags": [],
        "table": "[]",
        "maybe": None,
        "rate_hz": 10.0,
        "use_sim_time": False,
    }
    assert client.types(["gain", "flags", "table", "use_sim_time"]) == [
        PARAMETER_DOUBLE,
        PARAMETER_BOOL_ARRAY,
        PARAMETER_STRING,
        PARAMETER_BOOL,
    ]
    gain, rate, table, sim = client.describe(["gain", "rate_hz", "table", "use_sim_time"])
    assert (gain.read_only, rate.read_only, table.read_only, sim.read_only) == (False, True, False, True)
    assert gain.description == "a gain" and gain.type == PARAMETER_DOUBLE
    assert [(r.from_value, r.to_value) for r in gain.floating_point_range] == [(0.0, 10.0)]
    (count,) = client.describe(["count"])
    assert [(r.from_value, r.to_value) for r in count.integer_range] == [(0, 100)]
    assert "YAML text of a list[dict]" in table.additional_constraints
    with pytest.raises(ParamError, match="does not declare parameter\\(s\\) 'nope'"):
        client.get(["gain", "nope"])


def test_list_prefixes_and_depth(knobs: tuple[Knobs, ParameterClient]) -> None:
    node, _client = knobs
    server = node.parameter_server
    assert server is not None
    assert server.list_parameters(rcl.ListParameters_Request(prefixes=["gain"])).result.names == ["gain"]
    assert server.list_parameters(rcl.ListParameters_Request(prefixes=["gai"])).result.names == []
    # Our names have no "." levels: depth 1 lists them all.
    assert server.list_parameters(rcl.ListParameters_Request(depth=1)).result.names == sorted(server.fields)


def test_set_applies_at_once_and_publishes_an_event(knobs: tuple[Knobs, ParameterClient]) -> None:
    node, client = knobs
    events = Recorder()
    listener = Node(node_name="knobs_events", parameter_services=False)
    listener.create_subscription(ParameterEvent, "/parameter_events", events, QOS_PARAMETERS)
    with running(listener):
        assert wait_for(lambda: node.parameter_server.events.matched > 0, 15)  # type: ignore[union-attr]
        (result,) = client.set({"gain": v(2.5)})
        assert result.successful and result.reason == ""
        assert node.config.gain == 2.5 and node.changes == [frozenset({"gain"})]
        assert value_of(client.get(["gain"])[0]) == 2.5
        assert wait_for(lambda: len(events) > 0, 10)
    event = events.msgs()[0]
    assert event.node == "/knobs"
    assert [(p.name, value_of(p.value)) for p in event.changed_parameters] == [("gain", 2.5)]


def test_structured_and_optional_values(knobs: tuple[Knobs, ParameterClient]) -> None:
    node, client = knobs
    assert (
        client.set({"table": v("[{name: left, w: 2}]"), "maybe": v(1), "flags": v([True])})
        == [rcl.SetParametersResult(successful=True)] * 3
    )
    assert node.config.table == [{"name": "left", "w": 2}] and node.config.maybe == 1.0 and node.config.flags == [True]
    (result,) = client.set({"maybe": ParameterValue()})
    assert result.successful and node.config.maybe is None


@pytest.mark.parametrize(
    ("name", "value", "reason"),
    [
        ("gain", v(25.0), "'gain': 25.0 is above the maximum 10.0"),
        ("gain", v(-1.0), "is below the minimum 0.0"),
        ("gain", v("fast"), "wrong parameter type: 'gain' is a double, setting it to a string is not allowed"),
        ("count", v(2.5), "wrong parameter type: 'count' is an integer, setting it to a double"),
        ("label", v("z"), "'z' is not one of ['a', 'b', 'c']"),
        ("table", v("[{w: 2}]"), "every table row needs a name"),
        ("table", v("[unclosed"), "is not a mapping"),
        ("gain", v(7.0), "7 is refused by the node"),
        ("gain", ParameterValue(), "'gain' cannot be unset"),
        ("rate_hz", v(20.0), "'rate_hz' is read-only"),
        ("use_sim_time", v(True), "'use_sim_time' is read-only"),
        ("nope", v(1.0), "'nope' is not declared by node 'knobs'"),
    ],
)
def test_refused_changes_leave_the_node_unchanged(
    knobs: tuple[Knobs, ParameterClient], name: str, value: ParameterValue, reason: str
) -> None:
    node, client = knobs
    before = node.config
    (result,) = client.set({name: value})
    assert not result.successful
    assert reason in result.reason
    assert node.config is before and node.changes == []
    assert node.counters["parameter_changes_refused"] == 1


def test_cross_field_rule_and_atomic_sets(knobs: tuple[Knobs, ParameterClient]) -> None:
    node, client = knobs
    # Each parameter of SetParameters on its own: the first goes in, the second breaks validate().
    first, second = client.set({"count": v(50), "label": v("c")})
    assert first.successful and not second.successful and "at most 10" in second.reason
    assert (node.config.count, node.config.label) == (50, "a")
    # Atomically: all or none.
    bad = client.set_atomically({"gain": v(3.0), "label": v("c")})
    assert not bad.successful and (node.config.gain, node.config.label) == (1.0, "a")
    good = client.set_atomically({"count": v(5), "label": v("c")})
    assert good.successful and (node.config.count, node.config.label) == (5, "c")
    assert node.changes[-1] == frozenset({"count", "label"})


def test_a_failing_hook_restores_the_old_values(knobs: tuple[Knobs, ParameterClient]) -> None:
    node, client = knobs
    before = node.config
    node.fail_next = True
    (result,) = client.set({"gain": v(4.0)})
    assert not result.successful and "cannot apply" in result.reason
    assert node.config is before and node.config.gain == 1.0
    assert node.changes == [frozenset({"gain"})]  # the hook ran again for the old values


def test_parameter_services_are_announced(knobs: tuple[Knobs, ParameterClient]) -> None:
    node, _client = knobs
    info = di.current()
    assert info is not None
    (entry,) = [n for n in info.node_entities_info_seq if n.node_name == "knobs"]
    readers = {s.guid.bytes for s in node.subscriptions}
    writers = {p.guid.bytes for p in node.publishers}
    assert {g.to_bytes() for g in entry.reader_gid_seq} == readers and len(readers) == 6
    assert {g.to_bytes() for g in entry.writer_gid_seq} == writers and len(writers) == 7  # + /parameter_events
    assert sorted(s.name for s in node.services) == sorted(f"/knobs/{n}" for n in rcl.PARAMETER_SERVICES)


# -- the wire: foreign (rosbags) bytes in rmw_cyclonedds' request wrapper ---------------------------------
def wrapped(typename: str, values: Any, guid: int, seq: int) -> bytes:
    ts = typestore()
    raw = bytes(ts.serialize_cdr(ts.types[typename](**values), typename))
    return raw[:4] + struct.pack("<Qq", guid, seq) + raw[4:]


def unwrapped(typename: str, raw: bytes) -> tuple[int, int, Any]:
    guid, seq = struct.unpack("<Qq", raw[4:20])
    return guid, seq, typestore().deserialize_cdr(raw[:4] + raw[20:], typename)


def test_a_foreign_client_gets_a_reply_even_if_its_reader_comes_late(knobs: tuple[Knobs, ParameterClient]) -> None:
    """A ROS 2 client as rmw_cyclonedds_cpp makes one: rosbags bytes behind the request header,
    `clientid` in USER_DATA. Its reply reader is created only after the request has arrived: the
    service holds the reply until that reader is matched, as rmw_cyclonedds does."""
    node, _client = knobs
    dp = domain.participant()
    service = "/knobs/get_parameters"
    user_data = "clientid=01.2.3.4.5.6.7.8.9.a.b.c.0.0.0.63;"
    writer = DataWriter(
        dp,
        domain.topic(dp, request_topic(service), wire_type(rcl.GetParameters_Request)),
        qos=QOS_PARAMETERS.to_dds(user_data),
    )
    assert wait_for(lambda: len(writer.get_matched_subscriptions()) > 0, 15)
    guid, seq = 0x1122334455667788, 42
    foreign_write(
        writer,
        wire_type(rcl.GetParameters_Request)(),
        wrapped("rcl_interfaces/srv/GetParameters_Request", {"names": ["gain", "label"]}, guid, seq),
    )
    svc = next(s for s in node.services if s.name == service)
    assert wait_for(lambda: svc.pending, 10), "the request never arrived"
    reader = DataReader(
        dp,
        domain.topic(dp, reply_topic(service), wire_type(rcl.GetParameters_Response)),
        qos=QOS_PARAMETERS.to_dds(user_data),
    )
    got: list[bytes] = []
    assert wait_for(lambda: bool(got.extend(raw_take(reader)) or got), 10), "no reply"
    got_guid, got_seq, reply = unwrapped("rcl_interfaces/srv/GetParameters_Response", got[0])
    assert (got_guid, got_seq) == (guid, seq)
    assert [(x.type, x.double_value, x.string_value) for x in reply.values] == [
        (PARAMETER_DOUBLE, 1.0, ""),
        (PARAMETER_STRING, 0.0, "a"),
    ]
    for entity in (reader, writer):
        entity.__del__()


def test_our_client_against_a_foreign_server() -> None:
    """Our client's request, taken raw, is rmw_cyclonedds' layout with rosbags' bytes; a reply of
    rosbags bytes behind the echoed header is what `call` returns."""
    dp = domain.participant()
    service = "/foreign/set_parameters"
    user_data = "serviceid=01.2.3.4.5.6.7.8.9.a.b.c.0.0.0.64;"
    reader = DataReader(
        dp,
        domain.topic(dp, request_topic(service), wire_type(rcl.SetParameters_Request)),
        qos=QOS_PARAMETERS.to_dds(user_data),
    )
    writer = DataWriter(
        dp,
        domain.topic(dp, reply_topic(service), wire_type(rcl.SetParameters_Response)),
        qos=QOS_PARAMETERS.to_dds(user_data),
    )
    request = rcl.SetParameters_Request(parameters=[rcl.Parameter(name="kp", value=v(0.5))])
    result: dict[str, Any] = {}
    with ServiceClient(rcl.SetParameters, service, dp, QOS_PARAMETERS) as client:
        caller = threading.Thread(target=lambda: result.update(reply=client.call(request, 20)))
        caller.start()
        raws: list[bytes] = []
        assert wait_for(lambda: bool(raws.extend(raw_take(reader)) or raws), 20), "no request arrived"
        guid, seq, req = unwrapped("rcl_interfaces/srv/SetParameters_Request", raws[0])
        assert guid == client.guid
        assert [(p.name, p.value.type, p.value.double_value) for p in req.parameters] == [("kp", PARAMETER_DOUBLE, 0.5)]
        ts = typestore()
        res = ts.types["rcl_interfaces/msg/SetParametersResult"](successful=False, reason="no, thanks")
        reply = wrapped("rcl_interfaces/srv/SetParameters_Response", {"results": [res]}, guid + 1, seq)
        foreign_write(writer, wire_type(rcl.SetParameters_Response)(), reply)  # another client's: ignored
        reply = wrapped("rcl_interfaces/srv/SetParameters_Response", {"results": [res]}, guid, seq)
        foreign_write(writer, wire_type(rcl.SetParameters_Response)(), reply)
        caller.join(20)
    assert result["reply"] == rcl.SetParameters_Response(
        results=[rcl.SetParametersResult(successful=False, reason="no, thanks")]
    )
    for entity in (reader, writer):
        entity.__del__()


# -- nodes that derive state from their parameters -------------------------------------------------
def test_safety_gate_lowers_limits_live_and_refuses_raising() -> None:
    from go2vlm.safety.gate_node import SafetyGateNode

    gate = SafetyGateNode()
    with running(gate), ParameterClient("safety", timeout_s=15) as client:
        assert gate.core.limits.wz == 1.0
        (r,) = client.set({"max_vyaw": v(0.3)})
        assert r.successful and gate.core.limits.wz == 0.3
        assert gate.status(gate.clock.monotonic())["limits"]["wz"] == 0.3
        (r,) = client.set({"max_vyaw": v(0.6)})  # under the Go2 ceiling, still a raise
        assert not r.successful and "loosening a safety limit at runtime is refused (max_vyaw 0.3 -> 0.6)" in r.reason
        (r,) = client.set({"max_vyaw": v(5.0)})
        assert not r.successful and "above the maximum 4.0" in r.reason
        (r,) = client.set({"accel_linear": v(2.0)})
        assert not r.successful and "accel_linear 1 -> 2" in r.reason
        (r,) = client.set({"rate_hz": v(20.0)})
        assert not r.successful and "read-only" in r.reason
        assert gate.core.limits.wz == 0.3 and gate.core.limits.accel_linear == 1.0


def test_color_detector_rebuilds_its_ranges() -> None:
    from go2vlm.perception.color import resolve_ranges
    from go2vlm.perception.color_detector_node import ColorDetectorNode

    det = ColorDetectorNode()
    with running(det), ParameterClient("color_detector", timeout_s=15) as client:
        assert client.set({"color": v("blue")})[0].successful
        assert det._ranges == resolve_ranges("blue")
        (r,) = client.set({"color": v("custom")})  # custom needs hsv_ranges: validate() refuses
        assert not r.successful and "needs hsv_ranges" in r.reason and det._ranges == resolve_ranges("blue")
        r = client.set_atomically({"color": v("custom"), "hsv_ranges": v("[[0, 120, 70, 10, 255, 255]]")})
        assert r.successful and det._ranges == resolve_ranges([[0, 120, 70, 10, 255, 255]])


def test_commander_rebuilds_its_mission_parameters() -> None:
    from go2vlm.behavior.commander_node import CommanderNode

    cmd = CommanderNode()
    with running(cmd), ParameterClient("commander", timeout_s=15) as client:
        assert client.set_atomically({"max_linear": v(0.2), "kp_angular": v(1.0)}).successful
        assert (cmd.mission.params.max_linear, cmd.mission.params.kp_angular) == (0.2, 1.0)
        (r,) = client.set({"control_rate_hz": v(10.0)})
        assert not r.successful and "read-only" in r.reason


@pytest.mark.parametrize("kind", sorted(NODES))
def test_every_node_kinds_parameters_survive_the_wire(kind: str) -> None:
    """Each parameter of each node kind as a ROS value and back (what dump, then --params-file or a
    set, does) gives the same Config; every one has a descriptor."""
    cls = node_class(kind).Config
    required = {
        "vlm": {"model": "some/model"},
        "player": {"bag": "some.mcap"},
        "recorder": {"all": True},
    }.get(kind, {})
    default = build_config(cls, required, node=kind)
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        pv = to_value(getattr(default, f.name), hints[f.name])
        back = from_value(rcl.ParameterValue.deserialize(pv.serialize()), hints[f.name], f.name)
        again = build_config(cls, {**required, f.name: back}, node=kind)
        assert getattr(again, f.name) == getattr(default, f.name), f.name
        d = describe(f, hints[f.name], read_only=not f.metadata.get("live"))
        assert d.name == f.name and pv.type in (d.type, PARAMETER_NOT_SET), f.name


def test_commander_lowers_its_goal_bounds_live_and_refuses_raising() -> None:
    """max_goal_s and max_go_to_m go down while the commander runs, never up: the gate's rule."""
    from go2vlm.behavior.commander_node import CommanderNode

    cmd = CommanderNode()
    with running(cmd), ParameterClient("commander", timeout_s=15) as client:
        assert client.set({"max_goal_s": v(60.0)})[0].successful and cmd.config.max_goal_s == 60.0
        for name, value, was in (("max_goal_s", 86400.0, 60), ("max_go_to_m", 500.0, 25)):
            (r,) = client.set({name: v(value)})
            assert not r.successful and f"loosening a safety limit at runtime is refused ({name} {was} ->" in r.reason
        r = client.set_atomically({"max_linear": v(0.1), "max_angular": v(2.0)})
        assert not r.successful and "max_angular 0.8 -> 2" in r.reason and cmd.mission.params.max_linear == 0.4
        assert (cmd.config.max_goal_s, cmd.config.max_go_to_m) == (60.0, 25.0)
