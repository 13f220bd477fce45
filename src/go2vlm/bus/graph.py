"""What is on the wire: topics, their types and their publishers' QoS, from DDS discovery."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription
from cyclonedds.core import Policy

from go2vlm.bus import domain
from go2vlm.bus.qos import QosProfile


@dataclass
class TopicInfo:
    name: str  # ROS name, e.g. /camera/image_raw
    types: set[str] = field(default_factory=set)  # DDS type names
    publishers: list[QosProfile] = field(default_factory=list)
    subscribers: int = 0


def discover(wait_s: float = 1.0, own: bool = False) -> dict[str, TopicInfo]:
    """Topics seen within `wait_s`. Our own tool's endpoints are left out unless `own`."""
    dp = domain.participant()
    pubs = BuiltinDataReader(dp, BuiltinTopicDcpsPublication)
    subs = BuiltinDataReader(dp, BuiltinTopicDcpsSubscription)
    me = dp.guid
    found: dict[str, TopicInfo] = {}
    deadline = time.monotonic() + wait_s  # wall time: waiting for DDS discovery (a CLI tool)
    while True:
        for reader, is_pub in ((pubs, True), (subs, False)):
            for ep in reader.take(N=256):
                # Samples of endpoints that went away carry no topic name.
                if not isinstance(getattr(ep, "topic_name", None), str):
                    continue
                if not own and ep.participant_key == me:
                    continue
                ros = domain.ros_topic_name(ep.topic_name)
                if ros is None:
                    continue
                info = found.setdefault(ros, TopicInfo(ros))
                info.types.add(ep.type_name)
                if is_pub:
                    info.publishers.append(profile_of(ep.qos))
                else:
                    info.subscribers += 1
        if time.monotonic() >= deadline:
            break
        time.sleep(0.05)
    return found


def profile_of(qos: object) -> QosProfile:
    reliable = True
    transient = False
    depth = 10
    for policy in qos:  # type: ignore[attr-defined]
        if policy == Policy.Reliability.BestEffort:
            reliable = False
        if policy in (Policy.Durability.TransientLocal, Policy.Durability.Transient, Policy.Durability.Persistent):
            transient = True
        if isinstance(policy, Policy.History.KeepLast):
            depth = policy.depth
    return QosProfile(reliable=reliable, transient_local=transient, depth=depth)


def compatible_reader_qos(publishers: list[QosProfile], default: QosProfile) -> QosProfile:
    """The reader QoS that matches every publisher, as `ros2 topic echo` picks it."""
    if not publishers:
        return default
    return QosProfile(
        reliable=all(p.reliable for p in publishers),
        transient_local=all(p.transient_local for p in publishers),
        depth=max(default.depth, 10),
    )
