"""Announce our nodes to ROS 2 tools: `ros_discovery_info` (what `ros2 node list` and rqt_graph read).

ROS 2 does not see nodes in DDS discovery; each rmw publishes one `rmw_dds_common/ParticipantEntitiesInfo`
per participant, listing its nodes and which reader/writer GUIDs belong to each, on the bare DDS
topic `ros_discovery_info` (no `rt/` prefix), reliable, transient-local, keep-last 1. We do the same
for every `Node` in this process: the Node runtime calls `node_added`, `endpoint_added` and
`node_removed`, and every change republishes the participant's full list.

Set `GO2VLM_DISCOVERY_INFO=0` to switch it off.

`directory()` reads the same topic back: which node (ours or a ROS 2 node) owns a writer GUID, and
which nodes live in a participant, for tools and for status reports that name a DDS endpoint.
"""

from __future__ import annotations

import os
import re
import threading
import uuid
from dataclasses import dataclass, field
from typing import Any

from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader

from go2vlm.bus import domain
from go2vlm.bus.qos import QOS_LATCHED, QosProfile
from go2vlm.msgs.rmw_dds_common import Gid, NodeEntitiesInfo, ParticipantEntitiesInfo

TOPIC = "ros_discovery_info"
_NODE_NAME_RE = re.compile(r"[^A-Za-z0-9_]")


@dataclass
class _NodeEntry:
    namespace: str
    name: str
    readers: list[bytes] = field(default_factory=list)
    writers: list[bytes] = field(default_factory=list)


class _Announcer:
    """The `ros_discovery_info` writer of one participant and the nodes it announces."""

    def __init__(self, dp: DomainParticipant) -> None:
        self.gid = Gid.from_bytes(dp.guid.bytes)
        self.nodes: dict[int, _NodeEntry] = {}
        self.writer = DataWriter(dp, domain.topic(dp, TOPIC, ParticipantEntitiesInfo), qos=QOS_LATCHED.to_dds())

    def message(self) -> ParticipantEntitiesInfo:
        return ParticipantEntitiesInfo(
            gid=self.gid,
            node_entities_info_seq=[
                NodeEntitiesInfo(
                    node_namespace=n.namespace,
                    node_name=n.name,
                    reader_gid_seq=[Gid.from_bytes(g) for g in n.readers],
                    writer_gid_seq=[Gid.from_bytes(g) for g in n.writers],
                )
                for n in self.nodes.values()
            ],
        )

    def publish(self) -> None:
        try:
            self.writer.write(self.message())
        except Exception:  # graph announcements are best-effort; never break a node over them
            pass


_lock = threading.Lock()
_announcers: dict[int, _Announcer] = {}


def enabled() -> bool:
    return os.environ.get("GO2VLM_DISCOVERY_INFO", "1").strip().lower() not in ("0", "false", "no", "off")


def ros_node_name(name: str) -> str:
    """A valid ROS 2 node name (letters, digits, underscores; not starting with a digit)."""
    clean = _NODE_NAME_RE.sub("_", name) or "node"
    return "_" + clean if clean[0].isdigit() else clean


def _gid_bytes(guid: Any) -> bytes:
    return guid.bytes if isinstance(guid, uuid.UUID) else bytes(guid)


def _announcer(dp: DomainParticipant) -> _Announcer:
    a = _announcers.get(id(dp))
    if a is None:
        a = _announcers[id(dp)] = _Announcer(dp)
    return a


def node_added(node: Any, namespace: str = "/") -> None:
    if not enabled():
        return
    with _lock:
        a = _announcer(node.participant)
        a.nodes[id(node)] = _NodeEntry(namespace, ros_node_name(node.node_name))
        a.publish()


def endpoint_added(node: Any, guid: Any, is_reader: bool) -> None:
    if not enabled():
        return
    with _lock:
        a = _announcers.get(id(node.participant))
        entry = a.nodes.get(id(node)) if a else None
        if a is None or entry is None:
            return
        (entry.readers if is_reader else entry.writers).append(_gid_bytes(guid))
        a.publish()


def endpoint_removed(node: Any, guid: Any, is_reader: bool) -> None:
    with _lock:
        a = _announcers.get(id(node.participant))
        entry = a.nodes.get(id(node)) if a else None
        gids = (entry.readers if is_reader else entry.writers) if entry else []
        if a is None or _gid_bytes(guid) not in gids:
            return
        gids.remove(_gid_bytes(guid))
        a.publish()


def node_removed(node: Any) -> None:
    with _lock:
        a = _announcers.get(id(node.participant))
        if a is None or a.nodes.pop(id(node), None) is None:
            return
        a.publish()


def current(dp: DomainParticipant | None = None) -> ParticipantEntitiesInfo | None:
    """What this process announces now (for tests and `go2vlm node list`)."""
    with _lock:
        a = _announcers.get(id(dp or domain.participant()))
        return a.message() if a else None


class Directory:
    """The nodes announced on `ros_discovery_info` by every participant on the domain (ROS 2's too).

    The topic is keyless (one DDS instance for all participants): a keep-last-1 reader would keep
    only the last participant's announcement, so the reader keeps a deep history and every call
    takes what arrived; the newest announcement of each participant wins.
    """

    def __init__(self, dp: DomainParticipant) -> None:
        qos = QosProfile(reliable=True, transient_local=True, depth=256)
        self._reader = DataReader(dp, domain.topic(dp, TOPIC, ParticipantEntitiesInfo), qos=qos.to_dds())
        self._latest: dict[bytes, ParticipantEntitiesInfo] = {}
        self._lock = threading.Lock()

    def announcements(self) -> list[ParticipantEntitiesInfo]:
        """The newest announcement of each participant seen so far."""
        with self._lock:
            for s in self._reader.take(N=256):
                if isinstance(s, ParticipantEntitiesInfo):
                    self._latest[s.gid.to_bytes()] = s
            return list(self._latest.values())

    def node_of(self, guid: Any) -> str | None:
        """The full name ("/safety") of the node that owns the reader or writer `guid`, if announced."""
        raw = _guid_bytes(guid)
        for info in self.announcements():
            for n in info.node_entities_info_seq:
                if any(g.to_bytes() == raw for g in (*n.writer_gid_seq, *n.reader_gid_seq)):
                    return full_name(n.node_namespace, n.node_name)
        return None

    def nodes_in(self, participant: Any) -> list[str]:
        """The full names of the nodes a participant announces (empty if it announces none)."""
        raw = _guid_bytes(participant)
        for info in self.announcements():
            if info.gid.to_bytes() == raw:
                return [full_name(n.node_namespace, n.node_name) for n in info.node_entities_info_seq]
        return []


def full_name(namespace: str, name: str) -> str:
    return f"{namespace.rstrip('/')}/{name}"


def _guid_bytes(guid: Any) -> bytes:
    if isinstance(guid, str):
        return uuid.UUID(guid).bytes
    return _gid_bytes(guid)


_directories: dict[int, Directory] = {}


def directory(dp: DomainParticipant | None = None) -> Directory:
    """The process-wide Directory of a participant (created on first use)."""
    dp = dp or domain.participant()
    with _lock:
        d = _directories.get(id(dp))
        if d is None:
            d = _directories[id(dp)] = Directory(dp)
        return d
