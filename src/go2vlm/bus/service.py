"""ROS 2 services over DDS, byte for byte as rmw_cyclonedds_cpp puts them on the wire.

A service `/follower/get_parameters` of type `rcl_interfaces/srv/GetParameters` is two topics:

- requests on `rq/follower/get_parametersRequest`, type `rcl_interfaces::srv::dds_::GetParameters_Request_`
- replies on `rr/follower/get_parametersReply`, type `rcl_interfaces::srv::dds_::GetParameters_Response_`

rmw_cyclonedds_cpp puts a request header in front of every request and reply, inside the CDR
payload (serdata.hpp `cdds_request_header_t`, written by `serialize_top_level` for a
`cdds_request_wrapper_t`): `uint64 guid` then `int64 seq`, 16 bytes right after the 4-byte
encapsulation header, then the request or response fields. 16 is a multiple of 8, so the fields
serialize exactly as the bare message would. A client sets `guid` to the instance handle of its
request writer and `seq` to a process-wide counter; the server copies both into the reply, and the
client keeps only replies whose `guid` is its own (rmw_node.cpp `rmw_send_request`,
`rmw_take_response`). We declare that layout as a flat IDL struct under the message's own DDS type
name (`wire_type`): rmw_cyclonedds sends no XTypes type information, so peers match on the name.

Pairing (rmw_node.cpp `rmw_init_cs`, `check_for_response_reader`, `check_for_service_reader_writer`):
the reader and writer of one client carry `clientid=<id>;` in their USER_DATA QoS, a service's
`serviceid=<id>;`, where <id> is the participant GUID prefix plus a counter (`endpoint_id`). Before
replying, a server waits until it has matched the reply reader of the requesting client (else the
reply, reliable but volatile, would reach nobody); a client waits until it sees a request reader and a
reply writer of the same service. Both sides do that here too.

QoS: reliable, volatile (bus/qos.py QOS_SERVICES / QOS_PARAMETERS), like rmw's service profiles.
Fast DDS (rmw_fastrtps_cpp) carries the request identity differently (in the RTPS inline QoS, not in
the payload), so a ROS 2 peer must use rmw_cyclonedds_cpp to call or serve these services.
"""

from __future__ import annotations

import dataclasses
import enum
import itertools
import threading
import time
import types as pytypes
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from typing import Any, Generic, Protocol, TypeVar

from cyclonedds.core import DDSException, InstanceState, Policy, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct, types
from cyclonedds.idl._type_normalize import get_extended_type_hints
from cyclonedds.internal import InvalidSample
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.util import duration

from go2vlm.bus import domain
from go2vlm.bus.endpoints import Publisher, Subscription, delete_now
from go2vlm.bus.log import Logger
from go2vlm.bus.qos import QOS_SERVICES, QosProfile

__all__ = [
    "GUID_FIELD",
    "SEQ_FIELD",
    "Service",
    "ServiceClient",
    "ServiceError",
    "SrvType",
    "endpoint_id",
    "error_response",
    "reply_topic",
    "request_topic",
    "unwrap",
    "wire_type",
    "wrap",
]

Req = TypeVar("Req")
Resp = TypeVar("Resp")
ReqT_co = TypeVar("ReqT_co", covariant=True)
RespT_co = TypeVar("RespT_co", covariant=True)

# The request header's fields in our flat declaration of the wrapper (names are ours; only the
# layout is on the wire).
GUID_FIELD = "cdds_request_guid"
SEQ_FIELD = "cdds_request_seq"

# A reply waits this long for the client's reply reader to be matched (rmw_cyclonedds waits 100 ms,
# blocking its executor; we keep the reply pending and let the executor run meanwhile).
REPLY_WAIT_S = 1.0


class SrvType(Protocol[ReqT_co, RespT_co]):
    """A service type as msgs/ declares one: `NAME`, `Request`, `Response` (like rclpy's)."""

    # Read-only, so that a class with these class attributes (msgs/) is one.
    @property
    def NAME(self) -> str: ...
    @property
    def Request(self) -> type[ReqT_co]: ...
    @property
    def Response(self) -> type[RespT_co]: ...


class ServiceHost(Protocol):
    """What a Service needs of its node (a Node): its participant, its counters and its log."""

    participant: DomainParticipant
    log: Logger

    def count(self, name: str, n: int = 1) -> int: ...


class ServiceError(RuntimeError):
    """A service that is not there, or a reply that did not come in time."""


# The text fields an error reply carries its reason in, where a response has one (ours: `message`;
# rcl_interfaces' results: `reason`).
_REASON_FIELDS = ("message", "reason")
MAX_REASON = 300


def error_response(cls: type[Resp], reason: str) -> Resp:
    """A response of type `cls` that says a request failed: every field at its default (False, 0,
    empty), and `reason` in its text field (`message` or `reason`, at the top or one level down, as
    in SetParametersAtomically's `result.reason`). A response without such a field goes back empty."""
    resp = cls()
    for f in dataclasses.fields(resp):  # type: ignore[arg-type]  # an IdlStruct is a dataclass
        value = getattr(resp, f.name)
        if f.name in _REASON_FIELDS and isinstance(value, str):
            setattr(resp, f.name, reason)
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            for g in dataclasses.fields(value):
                if g.name in _REASON_FIELDS and isinstance(getattr(value, g.name), str):
                    setattr(value, g.name, reason)
    return resp


def request_topic(service: str) -> str:
    """`/follower/get_parameters` -> `rq/follower/get_parametersRequest`."""
    return "rq" + domain.dds_topic_name(service)[2:] + "Request"


def reply_topic(service: str) -> str:
    """`/follower/get_parameters` -> `rr/follower/get_parametersReply`."""
    return "rr" + domain.dds_topic_name(service)[2:] + "Reply"


def wire_type(cls: type) -> type:
    """`cls` with rmw_cyclonedds' request header in front (see `_wire_type`)."""
    return _wire_type(cls)  # uncached here: mypy reads a type[X] argument of a cached function as unhashable


@cache
def _wire_type(cls: type) -> type:
    """`cls` with rmw_cyclonedds' request header (uint64 guid, int64 seq) in front of its fields, under
    `cls`'s own DDS type name: what a service request or reply is on the wire. A flat struct rather
    than {header; body}: a nested struct of the same type name would look recursive to XTypes."""
    hints = get_extended_type_hints(cls)
    own = dataclasses.fields(cls)
    clash = {GUID_FIELD, SEQ_FIELD} & {f.name for f in own}
    if clash:
        raise TypeError(f"{cls.__name__} has fields named like the request header: {sorted(clash)}")

    def body(ns: dict[str, Any]) -> None:
        header = {GUID_FIELD: types.uint64, SEQ_FIELD: types.int64}
        ns["__annotations__"] = {**header, **{f.name: hints[f.name] for f in own}}
        ns[GUID_FIELD] = 0
        ns[SEQ_FIELD] = 0
        for f in own:
            ns[f.name] = field(default=f.default, default_factory=f.default_factory)

    name = f"{cls.__name__}Wire"
    wire = pytypes.new_class(name, (IdlStruct,), {"typename": cls.__idl_typename__}, body)  # type: ignore[attr-defined]
    wire.__module__ = __name__
    return dataclass(wire)


def wrap(msg: Any, guid: int, seq: int) -> Any:
    """The wire sample for `msg` with the request header (`guid`, `seq`)."""
    values = {f.name: getattr(msg, f.name) for f in dataclasses.fields(msg)}
    return wire_type(type(msg))(**{GUID_FIELD: guid, SEQ_FIELD: seq}, **values)


def unwrap(sample: Any, cls: type[Req]) -> tuple[int, int, Req]:
    """(guid, seq, message) from a wire sample."""
    values = {f.name: getattr(sample, f.name) for f in dataclasses.fields(cls)}  # type: ignore[arg-type]  # an IdlStruct is a dataclass
    return getattr(sample, GUID_FIELD), getattr(sample, SEQ_FIELD), cls(**values)


_ids = itertools.count(1)
_ids_lock = threading.Lock()


def endpoint_id(dp: DomainParticipant) -> str:
    """A client/service id as rmw_cyclonedds makes one (`get_unique_csid`, `csid_to_string`): the
    participant's 12-byte GUID prefix and a big-endian counter, in hex, dot-separated."""
    with _ids_lock:
        n = next(_ids)
    raw = dp.guid.bytes[:12] + n.to_bytes(4, "big")
    return f"{raw[0]:2x}" + "".join(f".{b:x}" for b in raw[1:])  # setw(2) on the first byte only, as rmw


def user_data_key(qos: Any, key: str) -> str | None:
    """The value of `key` in an endpoint's USER_DATA (`k=v;` pairs, as rmw writes them), or None."""
    data = next((p.data for p in (qos or []) if isinstance(p, Policy.Userdata)), None)
    if not data:
        return None
    for item in data.decode("utf-8", "replace").split(";"):
        k, sep, v = item.partition("=")
        if sep and k == key:
            return v
    return None


class _Client(enum.Enum):
    PRESENT = "present"  # its reply reader is matched: reply now
    MAYBE = "maybe"  # its request writer is there, its reply reader not matched yet: wait
    GONE = "gone"  # its request writer is gone: nobody to answer


@dataclass
class _Reply:
    sample: Any
    writer: int  # instance handle of the requesting client's request writer
    deadline: float  # time.monotonic()


class Service(Generic[Req, Resp]):
    """The server side of a service on a Node: `handler(request) -> response` runs on the node's
    executor thread, like a subscription callback. Made by `Node.create_service`.

    Every request is answered: a handler that raises (or returns something that is not its
    response) gets the caller an error reply (`error_response`: `success`/`found` false, the reason
    in `message`) at once instead of a timeout; it is logged, counted on the node
    (`service_errors`) and here (`errors`, `last_error`), and the node keeps serving."""

    def __init__(
        self,
        node: ServiceHost,
        srv_type: SrvType[Req, Resp],
        name: str,
        handler: Callable[[Req], Resp],
        qos: QosProfile = QOS_SERVICES,
    ) -> None:
        self.node = node
        self.name = name
        self.srv_type = srv_type
        self.handler = handler
        self.id = endpoint_id(node.participant)
        user_data = f"serviceid={self.id};"
        self._pending: list[_Reply] = []
        self.answered = 0  # requests answered, errors included
        self.errors = 0  # of those, answered with an error reply because the handler failed
        self.last_error = ""
        self.reply_pub: Publisher[Any] = Publisher(
            node.participant, wire_type(srv_type.Response), name, qos, dds_name=reply_topic(name), user_data=user_data
        )
        self.request_sub: Subscription[Any] = Subscription(
            node.participant,
            wire_type(srv_type.Request),
            name,
            self._on_request,
            qos,
            dds_name=request_topic(name),
            user_data=user_data,
        )

    @property
    def pending(self) -> bool:
        return bool(self._pending)

    def _on_request(self, sample: Any) -> None:
        guid, seq, request = unwrap(sample, self.srv_type.Request)
        writer = sample.sample_info.publication_handle
        try:
            response = self.handler(request)
            if not isinstance(response, want := self.srv_type.Response):
                raise TypeError(f"the handler returned {type(response).__name__}, not {want.__name__}")
            sample = wrap(response, guid, seq)
        except Exception as exc:  # the caller gets the reason now, not a timeout
            sample = wrap(self._failed(exc), guid, seq)
        self.answered += 1
        # Wall time: waiting for DDS discovery of the client's reply reader.
        self._pending.append(_Reply(sample, writer, time.monotonic() + REPLY_WAIT_S))
        self.flush()

    def _failed(self, exc: Exception) -> Resp:
        """The error reply for a request whose handler raised `exc`; logged and counted."""
        text = " ".join(str(exc).split())
        reason = f"error: {self.name} failed: {type(exc).__name__}" + (f": {text}" if text else "")
        reason = reason[:MAX_REASON]
        self.errors += 1
        self.last_error = reason
        n = self.node.count("service_errors")
        self.node.log.throttled("error", 2.0, f"{reason} (answered with an error; {n} so far)", key=f"srv:{self.name}")
        return error_response(self.srv_type.Response, reason)

    def stats(self) -> dict[str, int | str]:
        """What a status shows of this service: requests answered, error replies, the last error."""
        return {"answered": self.answered, "errors": self.errors, "last_error": self.last_error}

    def flush(self) -> bool:
        """Send the replies whose clients are ready; True while some still wait."""
        keep: list[_Reply] = []
        for reply in self._pending:
            state = self._client(reply.writer)
            if state is _Client.PRESENT:
                self.reply_pub.publish(reply.sample)
            elif state is _Client.MAYBE and time.monotonic() < reply.deadline:
                keep.append(reply)
            elif state is _Client.MAYBE:
                n = self.node.count("service_replies_dropped")
                self.node.log.throttled(
                    "warning", 2.0, f"{self.name}: the client's reply reader never matched; reply dropped ({n})"
                )
        self._pending = keep
        return bool(keep)

    def _client(self, writer_handle: int) -> _Client:
        reader, writer = self.request_sub.dds_reader, self.reply_pub.dds_writer
        if writer is None:
            return _Client.GONE
        try:
            ep = reader.get_matched_publication_data(writer_handle)
        except DDSException:
            ep = None
        if ep is None:
            return _Client.GONE
        client_id = user_data_key(ep.qos, "clientid")
        if client_id is None:
            return _Client.PRESENT  # a client without an id (as rmw_cyclonedds: assume all is well)
        for handle in writer.get_matched_subscriptions():
            try:
                sub = writer.get_matched_subscription_data(handle)
            except DDSException:
                continue
            if sub is not None and user_data_key(sub.qos, "clientid") == client_id:
                return _Client.PRESENT
        return _Client.MAYBE


_seqs = itertools.count(1)  # rmw_cyclonedds numbers requests process-wide (`next_request_id`)


class ServiceClient(Generic[Req, Resp]):
    """The client side, without a Node (CLI tools): `call(request)` blocks for the reply.

    Time here is wall time: waits for DDS discovery and for a reply from another process."""

    def __init__(
        self,
        srv_type: SrvType[Req, Resp],
        name: str,
        participant: DomainParticipant | None = None,
        qos: QosProfile = QOS_SERVICES,
    ) -> None:
        dp = participant or domain.participant()
        self.name = name
        self.srv_type = srv_type
        self.id = endpoint_id(dp)
        dds_qos = qos.to_dds(f"clientid={self.id};")
        self._writer = DataWriter(dp, domain.topic(dp, request_topic(name), wire_type(srv_type.Request)), qos=dds_qos)
        self._reader = DataReader(dp, domain.topic(dp, reply_topic(name), wire_type(srv_type.Response)), qos=dds_qos)
        self._cond = ReadCondition(self._reader, SampleState.Any | ViewState.Any | InstanceState.Any)
        self._waitset = WaitSet(dp)
        self._waitset.attach(self._cond)
        # What rmw_cyclonedds puts in the header's guid; cyclonedds-python hands it out signed.
        self.guid = self._writer.instance_handle & 0xFFFF_FFFF_FFFF_FFFF

    def service_is_ready(self) -> bool:
        """A request reader and a reply writer of one service are matched (a `serviceid` in common,
        or, for servers without ids, any of each)."""
        readers = [self._writer.get_matched_subscription_data(h) for h in self._writer.get_matched_subscriptions()]
        writers = [self._reader.get_matched_publication_data(h) for h in self._reader.get_matched_publications()]
        ids = {user_data_key(r.qos, "serviceid") for r in readers if r is not None} - {None}
        if not ids:
            return bool(readers) and bool(writers)
        return any(w is not None and user_data_key(w.qos, "serviceid") in ids for w in writers)

    def wait_for_service(self, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while not self.service_is_ready():
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)
        return True

    def call(self, request: Any, timeout_s: float = 5.0) -> Any:
        """Send `request` and return the response; ServiceError if none comes within `timeout_s`."""
        deadline = time.monotonic() + timeout_s
        if not self.wait_for_service(timeout_s):
            raise ServiceError(f"service {self.name} is not available (waited {timeout_s:g} s)")
        seq = next(_seqs)
        self._writer.write(wrap(request, self.guid, seq))
        while True:
            for sample in self._reader.take(N=16):
                if isinstance(sample, InvalidSample):
                    continue
                guid, got_seq, response = unwrap(sample, self.srv_type.Response)
                if guid == self.guid and got_seq == seq:
                    return response
            left = deadline - time.monotonic()
            if left <= 0:
                raise ServiceError(f"no reply from {self.name} within {timeout_s:g} s")
            self._waitset.wait(duration(seconds=min(left, 0.1)))

    def close(self) -> None:
        self._waitset.detach(self._cond)
        for entity in (self._cond, self._reader, self._writer, self._waitset):
            delete_now(entity)

    def __enter__(self) -> ServiceClient[Req, Resp]:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()
