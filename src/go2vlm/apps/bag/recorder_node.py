"""recorder: writes topics into a rosbag2 bag (MCAP storage), the serialized samples exactly as they
came off the wire (no decoding, no re-encoding). `go2vlm record` runs it; `BagRecorder` embeds it.

Topics
  subscribes  every topic in `topics` (or, with `all`, every topic on the bus whose type go2vlm
              knows, minus `exclude`), as soon as a publisher of it is discovered, also later ones.
              QoS: adapted to the publishers, as `ros2 bag record` does: reliable if every
              publisher is, transient-local (so latched samples are recorded) if every publisher is;
              keep-last `queue_depth`. A publisher that appears later with a weaker QoS makes the
              recorder re-subscribe (samples heard twice meanwhile are written once).
  publishes   nothing

Bag layout (apps/bag/bagfile.py): `out/metadata.yaml` (rosbag2 Jazzy, version 9; rewritten
atomically every `metadata_period_s` and at the end) and `out/<name>_0.mcap` (schemas ros2msg from
go2vlm.msgs.msgdef, channels cdr with offered_qos_profiles and topic_type_hash, log_time = receive
time, publish_time = the sample's source timestamp). Shutting the node down finishes the bag.
"""

from __future__ import annotations

import functools
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication

from go2vlm.apps.bag.bagfile import BagTopic, BagWriter, default_bag_name
from go2vlm.bus import Node, QosProfile, RawSample, RawSubscription, param
from go2vlm.bus.domain import ros_topic_name
from go2vlm.bus.graph import profile_of
from go2vlm.msgs import get_type
from go2vlm.msgs.msgdef import msgdef, rihs01, ros_type

__all__ = ["RecorderConfig", "RecorderNode", "TopicStats"]


@dataclass
class RecorderConfig:
    out: str = param("", help="bag folder to create (must not exist); default rosbag2_<date>-<time>")
    topics: list[str] = param(list, help="topics to record, e.g. [/camera/image_raw, /cmd_vel]")
    all: bool = param(False, help="record every topic whose type go2vlm knows (minus exclude)")
    exclude: list[str] = param(list, help="topics never recorded")
    queue_depth: int = param(500, help="reader queue per topic (keep-last); absorbs disk stalls", min=10)
    compression: str = param("none", help="MCAP chunk compression", choices=("none", "zstd", "lz4"))
    chunk_size: int = param(1 << 20, help="MCAP chunk size in bytes", min=1024)
    metadata_period_s: float = param(2.0, help="rewrite metadata.yaml this often", min=0.1)
    discovery_period_s: float = param(0.1, help="look for new publishers this often", min=0.02)

    def validate(self) -> None:
        if not self.all and not self.topics:
            raise ValueError("give topics to record, or all=true")
        for t in (*self.topics, *self.exclude):
            if not t.startswith("/"):
                raise ValueError(f"topic {t!r} must start with /")


@dataclass
class TopicStats:
    topic: str
    type: str
    messages: int
    bytes: int
    qos: str


@dataclass
class _Topic:
    name: str
    cls: type
    publishers: dict[Any, QosProfile]
    sub: RawSubscription | None = None
    qos: QosProfile | None = None
    retiring: list[tuple[RawSubscription, float]] | None = None  # old readers, kept until this time
    seen: dict[tuple[int, int], None] | None = None  # (writer, source time) while two readers overlap


class RecorderNode(Node):
    name = "recorder"
    Config = RecorderConfig

    def __init__(self, config: RecorderConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        c: RecorderConfig = self.config
        self.out = Path(c.out or default_bag_name())
        self.bag = BagWriter(self.out, compression=c.compression, chunk_size=c.chunk_size)
        self._topics: dict[str, _Topic] = {}
        self._stats_lock = threading.Lock()
        self._pubs = BuiltinDataReader(self.participant, BuiltinTopicDcpsPublication)
        self._warned: set[str] = set()
        self.started_at = time.monotonic()
        self.create_timer(c.discovery_period_s, self._discover)
        self.create_timer(c.metadata_period_s, self._write_metadata)
        self._discover()

    # -- which topics --------------------------------------------------------------------------
    def _wanted(self, topic: str) -> bool:
        c = self.config
        if topic in c.exclude:
            return False
        return c.all or topic in c.topics

    def _discover(self) -> None:
        changed: set[str] = set()
        for ep in self._pubs.take(N=256):
            name = getattr(ep, "topic_name", None)
            if not isinstance(name, str):
                continue  # a publisher that went away: its samples stay recorded
            topic = ros_topic_name(name)
            if topic is None or not self._wanted(topic):
                continue
            try:
                cls = get_type(ep.type_name)
            except ValueError:
                if topic not in self._warned:
                    self._warned.add(topic)
                    self.log.warning(f"not recording {topic}: go2vlm has no definition of type {ep.type_name}")
                continue
            t = self._topics.get(topic)
            if t is None:
                t = self._topics[topic] = _Topic(topic, cls, {})
            elif cls is not t.cls:
                if f"{topic}:{ep.type_name}" not in self._warned:
                    self._warned.add(f"{topic}:{ep.type_name}")
                    self.log.warning(f"{topic}: ignoring a publisher of {ep.type_name}; recording {ros_type(t.cls)}")
                continue
            t.publishers[ep.key] = profile_of(ep.qos)
            changed.add(topic)
        for topic in changed:
            self._subscribe(self._topics[topic])
        self._retire()

    def _subscribe(self, t: _Topic) -> None:
        pubs = list(t.publishers.values())
        want = QosProfile(
            reliable=all(p.reliable for p in pubs),
            transient_local=all(p.transient_local for p in pubs),
            depth=self.config.queue_depth,
        )
        if t.name not in self.bag.topics:
            # The offered QoS are those known now, in the MCAP channel and in metadata.yaml alike (readers
            # match the two); rosbag2 does the same.
            self.bag.add_topic(t.name, ros_type(t.cls), msgdef(t.cls), rihs01(t.cls), pubs)
        if t.qos is not None and _covers(t.qos, want):
            return
        if t.sub is not None:
            # A weaker publisher joined: the new reader hears it; the old one drains for a while.
            self.log.info(f"{t.name}: re-subscribing as {want.describe()} for a new publisher")
            t.retiring = [*(t.retiring or []), (t.sub, time.monotonic() + 2.0)]
            t.seen = {}
        t.qos = want
        t.sub = self.create_raw_subscription(t.cls, t.name, functools.partial(self._on_sample, t), want)
        if t.retiring is None:
            self.log.info(f"recording {t.name} [{ros_type(t.cls)}] ({want.describe()})")

    def _retire(self) -> None:
        now = time.monotonic()
        for t in self._topics.values():
            if not t.retiring:
                continue
            keep = []
            for sub, until in t.retiring:
                if now < until:
                    keep.append((sub, until))
                else:
                    self.destroy_subscription(sub)
            t.retiring = keep or None
            if not keep:
                t.seen = None

    # -- writing -------------------------------------------------------------------------------
    def _on_sample(self, t: _Topic, s: RawSample) -> None:
        if t.seen is not None:
            key = (s.publication_handle, s.source_timestamp)
            if key in t.seen:
                return
            t.seen[key] = None
            if len(t.seen) > 10000:
                t.seen.pop(next(iter(t.seen)))
        with self._stats_lock:
            # Receive time on the node clock: wall time, or sim time with use_sim_time (as ros2 bag record).
            self.bag.write(t.name, s.data, int(self.clock.now() * 1e9), s.source_timestamp)

    def _write_metadata(self) -> None:
        with self._stats_lock:
            self.bag.write_metadata()

    def stats(self) -> list[TopicStats]:
        """Messages and bytes per topic so far (safe from any thread)."""
        with self._stats_lock:
            topics: list[BagTopic] = list(self.bag.topics.values())
            qos = {name: tp.qos.describe() for name, tp in self._topics.items() if tp.qos is not None}
            return [
                TopicStats(
                    t.name,
                    t.type,
                    t.message_count,
                    t.bytes,
                    qos.get(t.name, ""),
                )
                for t in topics
            ]

    @property
    def message_count(self) -> int:
        return self.bag.message_count

    def close(self) -> None:
        # Shutdown joined the executor: nothing writes any more. Take what is still queued first.
        for t in self._topics.values():
            for sub in [t.sub, *(s for s, _ in t.retiring or [])]:
                if sub is None:
                    continue
                try:
                    while batch := sub.take():
                        for s in batch:
                            self._on_sample(t, s)
                except Exception as exc:
                    self.log.error(f"{t.name}: could not take the last samples: {exc}")
        with self._stats_lock:
            self.bag.close()
        try:
            self._pubs.__del__()
        except Exception:
            pass


def _covers(have: QosProfile, want: QosProfile) -> bool:
    """True when a reader with `have` matches every publisher that `want` was computed for."""
    return (want.reliable or not have.reliable) and (want.transient_local or not have.transient_local)
