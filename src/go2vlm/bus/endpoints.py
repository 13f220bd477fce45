"""Publishers and subscriptions: the DDS writer and reader under every topic a node uses.

Made by `Node.create_publisher` / `create_subscription` / `create_raw_subscription`, and by
services (bus/service.py), which pair one of each. They need only a participant, so this module
does not know `Node`.

Every sample a Subscription takes is checked for size (msgs/sizes.py) before its callback sees it:
its serialized bytes against `max_msg_bytes` before it is decoded, then the size its fields declare
(a grid's cells, an image's pixels, a cloud's points, an array's items) against the caps and its
data. A refused sample is dropped; `refused` counts them and `last_refusal` says why.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from cyclonedds._clayer import ddspy_take, ddspy_write
from cyclonedds.core import DDSException, InstanceState, ReadCondition, SampleState, ViewState
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader

from go2vlm.bus import domain
from go2vlm.bus.qos import QosProfile
from go2vlm.msgs.sizes import SizeCaps, SizeError, check_size

M = TypeVar("M")


def delete_now(entity: Any) -> None:
    """Delete a DDS entity now. cyclonedds-python deletes only when the object is garbage
    collected, and until then a latched writer keeps handing its last sample to late joiners."""
    entity.__del__()


@dataclass(frozen=True)
class Endpoint:
    """A DDS writer (or reader) as discovery describes it: its GUID and its participant's GUID."""

    guid: str
    participant: str
    topic: str = ""
    type_name: str = ""


def _endpoint(data: Any) -> Endpoint:
    return Endpoint(str(data.key), str(data.participant_key), data.topic_name, data.type_name)


class Publisher(Generic[M]):
    """`dds_name` and `user_data` are for services (bus/service.py): a DDS topic name other than
    `rt/<topic>`, and the USER_DATA QoS that pairs a service's endpoints."""

    def __init__(
        self,
        participant: DomainParticipant,
        msg_type: type[M],
        topic: str,
        qos: QosProfile,
        *,
        dds_name: str | None = None,
        user_data: str | None = None,
    ) -> None:
        self.topic = topic
        self.msg_type = msg_type
        self.qos = qos
        dds_topic = domain.topic(participant, dds_name or domain.dds_topic_name(topic), msg_type)
        self._writer: DataWriter[Any] | None = DataWriter(participant, dds_topic, qos=qos.to_dds(user_data))
        self.count = 0
        self._lock = threading.Lock()  # nodes publish from worker threads, and shutdown closes

    def publish(self, msg: M) -> None:
        with self._lock:
            if self._writer is None:
                return  # a worker thread finishing after shutdown; the writer is gone
            self._writer.write(msg)
            self.count += 1

    def publish_raw(self, data: bytes) -> None:
        """Publish an already serialized sample (encapsulation header + CDR, e.g. from a bag) as is."""
        with self._lock:
            if self._writer is None:
                return
            # Cyclone wants whole 4-byte words; CDR readers ignore the trailing padding.
            ret = ddspy_write(self._writer._ref, data + b"\0" * (-len(data) % 4))
            if ret < 0:
                raise DDSException(ret, f"writing a serialized sample on {self.topic}")
            self.count += 1

    @property
    def matched(self) -> int:
        """How many readers are matched (a readiness check before publishing)."""
        return len(self._writer.get_matched_subscriptions()) if self._writer is not None else 0

    @property
    def guid(self) -> Any:
        if self._writer is None:
            raise RuntimeError(f"the publisher on {self.topic} is closed")
        return self._writer.guid

    @property
    def dds_writer(self) -> DataWriter[Any] | None:
        """The DDS writer (None after close)."""
        return self._writer

    def close(self) -> None:
        """Delete the writer now (idempotent): a latched sample leaves with it."""
        with self._lock:
            if self._writer is not None:
                delete_now(self._writer)
            self._writer = None


class Subscription(Generic[M]):
    """`dds_name` and `user_data`: as for Publisher."""

    def __init__(
        self,
        participant: DomainParticipant,
        msg_type: type[M],
        topic: str,
        callback: Callable[..., object],  # what it returns is dropped
        qos: QosProfile,
        *,
        with_sender: bool = False,
        dds_name: str | None = None,
        user_data: str | None = None,
    ) -> None:
        self.topic = topic
        self.msg_type = msg_type
        self.qos = qos
        self.callback = callback
        self.with_sender = with_sender
        dds_topic = domain.topic(participant, dds_name or domain.dds_topic_name(topic), msg_type)
        self._reader = DataReader(participant, dds_topic, qos=qos.to_dds(user_data))
        self.condition = ReadCondition(self._reader, SampleState.Any | ViewState.Any | InstanceState.Any)
        self.count = 0
        self.caps = SizeCaps()  # the node's (Node sets them)
        self.refused = 0  # samples dropped for their size (msgs/sizes.py)
        self.last_refusal = ""
        self._senders: dict[int, Endpoint] = {}  # publication handle -> writer (handles are never reused)

    _MASK = SampleState.Any | ViewState.Any | InstanceState.Any

    def take(self) -> list[M]:
        """Up to 64 samples, decoded, each within the size caps (the module docstring); the rest dropped."""
        ret = ddspy_take(self._reader._ref, self._MASK, 64)
        if isinstance(ret, int):
            raise DDSException(ret, f"taking samples on {self.topic}")
        out = []
        for data, info in ret:
            if not info.valid_data:
                continue  # an instance's state change (a writer gone), no data
            if len(data) > self.caps.max_msg_bytes:  # before a byte of it is decoded
                self._refuse(f"{len(data)} bytes, more than the {self.caps.max_msg_bytes} a sample may take")
                continue
            msg = self._reader._topic.data_type.deserialize(data)  # as DataReader.take decodes
            try:
                check_size(msg, self.caps)
            except SizeError as exc:
                self._refuse(str(exc))
                continue
            msg.sample_info = info
            out.append(msg)
        self.count += len(out)
        return out

    def _refuse(self, why: str) -> None:
        self.refused += 1
        self.last_refusal = why

    def sender(self, msg: Any) -> Endpoint | None:
        """The writer of a message this subscription took (None once that writer is gone)."""
        info = getattr(msg, "sample_info", None)
        if info is None:
            return None
        handle = int(info.publication_handle)
        found = self._senders.get(handle)
        if found is None:
            try:
                data = self._reader.get_matched_publication_data(handle)
            except Exception:  # unmatched since: the writer left
                data = None
            if data is None:
                return None
            found = self._senders[handle] = _endpoint(data)
        return found

    def writers(self) -> list[Endpoint]:
        """The writers matched with this subscription now, ours included."""
        out = []
        for handle in self._reader.get_matched_publications():
            try:
                data = self._reader.get_matched_publication_data(handle)
            except Exception:  # gone between the two calls
                continue
            if data is not None:
                out.append(_endpoint(data))
        return out

    @property
    def guid(self) -> Any:
        return self._reader.guid

    @property
    def dds_reader(self) -> DataReader[Any]:
        return self._reader

    @property
    def publisher_count(self) -> int:
        return len(self._reader.get_matched_publications())

    def close(self) -> None:
        delete_now(self.condition)
        delete_now(self._reader)


@dataclass(frozen=True)
class RawSample:
    """A sample as it came off the wire: the serialized bytes (encapsulation header + CDR), not decoded."""

    data: bytes
    source_timestamp: int  # ns since the epoch, the writer's clock
    publication_handle: int  # which writer sent it


class RawSubscription(Subscription[RawSample]):
    """Hands the callback `RawSample`s: no decoding (and no size check), for tools that store or forward bytes."""

    def take(self) -> list[RawSample]:
        ret = ddspy_take(self._reader._ref, self._MASK, 64)
        if isinstance(ret, int):
            raise DDSException(ret, f"taking serialized samples on {self.topic}")
        out = [RawSample(data, info.source_timestamp, info.publication_handle) for data, info in ret if info.valid_data]
        self.count += len(out)
        return out
