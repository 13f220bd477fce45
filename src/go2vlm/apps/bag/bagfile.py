"""The rosbag2 bag layout (ROS 2 Jazzy, metadata version 9, MCAP storage), written and read with the
`mcap` library.

A bag is a folder:

    my_bag/
      metadata.yaml        rosbag2_bagfile_information: version 9, storage_identifier mcap, ...
      my_bag_0.mcap        profile ros2; schemas `ros2msg` (.msg text with dependencies); channels
                           `cdr` with metadata offered_qos_profiles (YAML) and topic_type_hash
                           (RIHS01); messages: the serialized samples as received, log_time =
                           receive time, publish_time = the writer's source timestamp (ns)

`BagWriter` writes one; `BagReader` reads one (or a bare .mcap) back for `go2vlm play`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, BinaryIO

import yaml

from go2vlm.bus import QosProfile
from go2vlm.errors import ConfigError

__all__ = [
    "BagError",
    "BagMessage",
    "BagReader",
    "BagTopic",
    "BagWriter",
    "METADATA_FILE",
    "qos_from_dict",
    "qos_to_dict",
]

METADATA_FILE = "metadata.yaml"
METADATA_VERSION = 9  # rosbag2 in ROS 2 Jazzy
ROS_DISTRO = "jazzy"
# rmw's "infinite" duration, as rosbag2 writes it for deadline, lifespan and lease duration.
_INFINITE = {"sec": 9223372036, "nsec": 854775807}


class BagError(ConfigError):
    """A bag that cannot be written or read (exists already, missing, not rosbag2/MCAP)."""


def _version(dist: str) -> str:
    try:
        return version(dist)
    except PackageNotFoundError:
        return "unknown"


def qos_to_dict(q: QosProfile) -> dict[str, Any]:
    """One offered QoS profile as rosbag2 Jazzy (metadata version 9) writes it."""
    return {
        "history": "keep_last",
        "depth": q.depth,
        "reliability": "reliable" if q.reliable else "best_effort",
        "durability": "transient_local" if q.transient_local else "volatile",
        "deadline": dict(_INFINITE),
        "lifespan": dict(_INFINITE),
        "liveliness": "automatic",
        "liveliness_lease_duration": dict(_INFINITE),
        "avoid_ros_namespace_conventions": False,
    }


def qos_from_dict(d: dict[str, Any]) -> QosProfile:
    """A profile from metadata: v9 names or the integer enums of older rosbag2 versions."""
    rel = d.get("reliability", "reliable")
    dur = d.get("durability", "volatile")
    depth = int(d.get("depth") or 0)
    return QosProfile(
        reliable=rel in ("reliable", 1, "1", "system_default", 0, "0"),
        transient_local=dur in ("transient_local", 1, "1"),
        depth=depth if depth > 0 else 10,  # 0: unknown (`ros2 bag record` from graph data)
    )


def dump_qos(profiles: list[QosProfile]) -> str:
    """The offered_qos_profiles YAML text of an MCAP channel."""
    return yaml.safe_dump([qos_to_dict(q) for q in profiles], sort_keys=False, default_flow_style=False).strip()


@dataclass
class BagTopic:
    name: str
    type: str  # ROS name, e.g. sensor_msgs/msg/Image
    offered_qos: list[QosProfile] = field(default_factory=list)
    type_hash: str = ""
    message_count: int = 0
    bytes: int = 0


class BagWriter:
    """Creates `folder/` with `folder_0.mcap` and keeps `metadata.yaml` current.

    `metadata.yaml` is written at once (empty), rewritten by `write_metadata()` (atomically: a
    temporary file renamed over it) and finally by `close()`, so a bag whose recorder died still
    names its topics.
    """

    def __init__(self, folder: str | Path, *, compression: str = "none", chunk_size: int = 1 << 20) -> None:
        from mcap.writer import CompressionType, Writer

        self.folder = Path(folder)
        if self.folder.exists() and (not self.folder.is_dir() or any(self.folder.iterdir())):
            raise BagError(f"output folder {str(self.folder)!r} already exists; choose a new one")
        if compression not in ("none", "zstd", "lz4"):
            raise BagError(f"compression {compression!r} is not one of none, zstd, lz4")
        self.folder.mkdir(parents=True, exist_ok=True)
        self.file_name = f"{self.folder.name}_0.mcap"
        self._file: BinaryIO = open(self.folder / self.file_name, "wb")  # noqa: SIM115 (closed in close())
        kinds = {"none": CompressionType.NONE, "zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4}
        self._mcap = Writer(self._file, chunk_size=chunk_size, compression=kinds[compression])
        self._mcap.start(profile="ros2", library=f"go2vlm {_version('go2vlm')}, mcap {_version('mcap')}")
        self.topics: dict[str, BagTopic] = {}
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self.start_ns: int | None = None
        self.end_ns = 0
        self.message_count = 0
        self.closed = False
        self.write_metadata()

    def add_topic(self, name: str, ros_type: str, msgdef: str, type_hash: str, offered: list[QosProfile]) -> None:
        if name in self._channels:
            return
        schema_id = self._schemas.get(ros_type)
        if schema_id is None:
            schema_id = self._mcap.register_schema(name=ros_type, encoding="ros2msg", data=msgdef.encode())
            self._schemas[ros_type] = schema_id
        meta = {"offered_qos_profiles": dump_qos(offered), "topic_type_hash": type_hash}
        channel_id = self._mcap.register_channel(topic=name, message_encoding="cdr", schema_id=schema_id, metadata=meta)
        self._channels[name] = channel_id
        self._sequence[channel_id] = 0
        self.topics[name] = BagTopic(name, ros_type, list(offered), type_hash)

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int) -> None:
        channel_id = self._channels[topic]
        seq = self._sequence[channel_id] = self._sequence[channel_id] + 1
        self._mcap.add_message(channel_id, log_time=log_time_ns, data=data, publish_time=publish_time_ns, sequence=seq)
        t = self.topics[topic]
        t.message_count += 1
        t.bytes += len(data)
        self.message_count += 1
        self.start_ns = log_time_ns if self.start_ns is None else min(self.start_ns, log_time_ns)
        self.end_ns = max(self.end_ns, log_time_ns)

    def metadata(self) -> dict[str, Any]:
        start = self.start_ns or 0
        duration = max(0, self.end_ns - start) if self.start_ns is not None else 0
        return {
            "version": METADATA_VERSION,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": self.message_count,
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": t.name,
                        "type": t.type,
                        "serialization_format": "cdr",
                        "offered_qos_profiles": [qos_to_dict(q) for q in t.offered_qos],
                        "type_description_hash": t.type_hash,
                    },
                    "message_count": t.message_count,
                }
                for t in self.topics.values()
            ],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [self.file_name],
            "files": [
                {
                    "path": self.file_name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                    "duration": {"nanoseconds": duration},
                    "message_count": self.message_count,
                }
            ],
            "custom_data": {"recorded_by": f"go2vlm {_version('go2vlm')}"},
            "ros_distro": ROS_DISTRO,
        }

    def write_metadata(self) -> None:
        """metadata.yaml, replaced atomically; the MCAP written so far goes to the disk too."""
        if not self.closed:
            self._file.flush()
        text = yaml.safe_dump({"rosbag2_bagfile_information": self.metadata()}, sort_keys=False)
        tmp = self.folder / f".{METADATA_FILE}.tmp"
        tmp.write_text(text)
        os.replace(tmp, self.folder / METADATA_FILE)

    def close(self) -> None:
        if self.closed:
            return
        # rosbag2 also stores the metadata inside the MCAP, so the .mcap alone is a complete bag.
        self._mcap.add_metadata("rosbag2", {"serialized_metadata": yaml.safe_dump(self.metadata(), sort_keys=False)})
        self._mcap.finish()
        self._file.close()
        self.closed = True
        self.write_metadata()


@dataclass
class BagMessage:
    topic: str
    data: bytes  # serialized: encapsulation header + CDR
    log_time_ns: int


class BagReader:
    """Topics (type, offered QoS) and messages in log-time order of a rosbag2 folder or a .mcap."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise BagError(f"bag {str(self.path)!r} does not exist")
        self.files: list[Path] = []
        self.topics: dict[str, BagTopic] = {}
        self.start_ns = 0
        self.end_ns = 0
        meta_path = self.path / METADATA_FILE if self.path.is_dir() else None
        if meta_path is not None and meta_path.is_file():
            self._read_metadata(meta_path)
        elif self.path.is_dir():
            self.files = sorted(self.path.glob("*.mcap"))
        else:
            self.files = [self.path]
        if not self.files:
            raise BagError(f"{str(self.path)!r} holds no .mcap file")
        self._read_summaries()

    def _read_metadata(self, meta_path: Path) -> None:
        try:
            doc = yaml.safe_load(meta_path.read_text())["rosbag2_bagfile_information"]
        except (yaml.YAMLError, KeyError, TypeError) as exc:
            raise BagError(f"{meta_path}: not a rosbag2 metadata file ({exc})") from None
        if doc.get("storage_identifier") != "mcap":
            raise BagError(f"{meta_path}: storage {doc.get('storage_identifier')!r} is not mcap (only MCAP bags play)")
        self.files = [self.path / p for p in doc.get("relative_file_paths") or []]
        for entry in doc.get("topics_with_message_count") or []:
            tm = entry["topic_metadata"]
            offered = tm.get("offered_qos_profiles") or []
            if isinstance(offered, str):  # metadata version < 9: a YAML string
                offered = yaml.safe_load(offered) or []
            self.topics[tm["name"]] = BagTopic(
                tm["name"],
                tm["type"],
                [qos_from_dict(q) for q in offered],
                tm.get("type_description_hash", ""),
                int(entry.get("message_count", 0)),
            )

    def _read_summaries(self) -> None:
        from mcap.exceptions import McapError
        from mcap.reader import make_reader

        starts, ends = [], []
        for f in self.files:
            if not f.is_file():
                raise BagError(f"bag file {str(f)!r} is missing")
            with open(f, "rb") as stream:
                try:
                    summary = make_reader(stream).get_summary()
                except (McapError, ValueError, EOFError) as exc:
                    raise BagError(f"{f}: not a complete MCAP file ({exc})") from None
            if summary is None:
                raise BagError(f"{f}: the MCAP file has no summary (was the recorder killed?)")
            if summary.statistics and summary.statistics.message_count:
                starts.append(summary.statistics.message_start_time)
                ends.append(summary.statistics.message_end_time)
            for ch in summary.channels.values():
                if ch.topic in self.topics:
                    continue
                schema = summary.schemas.get(ch.schema_id)
                offered = yaml.safe_load(ch.metadata.get("offered_qos_profiles", "") or "[]") or []
                self.topics[ch.topic] = BagTopic(
                    ch.topic,
                    schema.name if schema else "",
                    [qos_from_dict(q) for q in offered],
                    ch.metadata.get("topic_type_hash", ""),
                )
        self.start_ns = min(starts, default=0)
        self.end_ns = max(ends, default=0)

    def messages(self, topics: set[str] | None = None) -> Iterator[BagMessage]:
        from mcap.reader import make_reader

        for f in self.files:
            with open(f, "rb") as stream:
                reader = make_reader(stream)
                for _schema, channel, message in reader.iter_messages(
                    topics=sorted(topics) if topics is not None else None, log_time_order=True
                ):
                    yield BagMessage(channel.topic, message.data, message.log_time)


def default_bag_name() -> str:
    """`rosbag2_2025_01_31-12_00_00`, as `ros2 bag record` names a bag."""
    return time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S")
