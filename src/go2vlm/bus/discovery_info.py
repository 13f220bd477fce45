"""Announce our nodes to ROS 2 tools: `ros_discovery_info` (what `ros2 node list` and rqt_graph read).

ROS 2 does not see nodes in DDS discovery; each rmw publishes one `rmw_dds_common/ParticipantEntitiesInfo`
per participant, listing its nodes and which reader/writer GUIDs belong to each, on the bare DDS
topic `ros_discovery_info` (no `rt/` prefix), reliable, transient-local, keep-last 1. We do the same
for every `Node` in this process: the Node runtime calls `node_added`, `endpoint_added` and
`node_removed`, and every change republishes the participant's full list.

Set `GO2VLM_DISCOVERY_INFO=0` to switch it off.
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

from go2vlm.bus import domain
from go2vlm.bus.qos import QOS_LATCHED
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
