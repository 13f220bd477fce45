"""Who sent a message: a subscription callback can receive the writer's identity (its GUID and its
participant's GUID), a subscription lists its matched writers, and ros_discovery_info names the node
that owns a GUID, for a writer in this process and one in another process."""

from __future__ import annotations

from typing import Any

from busutil import Procs, Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, Endpoint, Node, discovery_info, running
from go2vlm.msgs.std_msgs import String


def test_sender_identity_writers_and_node_names(procs: Procs) -> None:
    listener = Node(node_name="sender_listener")
    local = Node(node_name="sender_local")
    got: list[tuple[str, Endpoint | None]] = []
    plain = Recorder()
    sub = listener.create_subscription(
        String, "/bus/sender", lambda m, s: got.append((m.data, s)), QOS_DEFAULT, with_sender=True
    )
    listener.create_subscription(String, "/bus/sender", plain, QOS_DEFAULT)  # without: one argument, as before
    pub = local.create_publisher(String, "/bus/sender", QOS_DEFAULT)
    with running(listener, local):
        assert wait_for(lambda: pub.matched >= 2, 10)
        pub.publish(String(data="local"))
        assert wait_for(lambda: any(d == "local" for d, _ in got), 10)
        sender = next(s for d, s in got if d == "local")
        assert sender is not None and sender.guid == str(pub.guid) and sender.participant == str(local.participant.guid)
        assert sender.topic == "rt/bus/sender" and sender.type_name == "std_msgs::msg::dds_::String_"
        assert [m.data for m in plain.msgs()] == ["local"]

        other = procs.start("topic", "pub", "/bus/sender", "std_msgs/msg/String", "{data: remote}", "--rate", "10")
        assert wait_for(lambda: any(d == "remote" for d, _ in got), 20)
        remote: Any = next(s for d, s in got if d == "remote")
        assert remote.participant != str(listener.participant.guid), "another process, another participant"
        writers = {w.guid for w in sub.writers()}
        assert {str(pub.guid), remote.guid} <= writers
        names = discovery_info.directory()
        assert wait_for(lambda: names.node_of(remote.guid) == "/go2vlm_topic_pub", 10)
        assert names.node_of(pub.guid) == "/sender_local"
        assert "/sender_listener" in names.nodes_in(listener.participant.guid)
        procs.stop(other)
        assert wait_for(lambda: remote.guid not in {w.guid for w in sub.writers()}, 15), "a writer that left"
