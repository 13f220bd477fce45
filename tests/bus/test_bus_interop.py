"""What a real ROS 2 Jazzy peer would see and send, proven with rosbags bytes and raw DDS:
`ros_discovery_info` announcements, foreign CDR on rt/cmd_vel and rt/camera/image_raw, XTypes ids."""

from __future__ import annotations

import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import bus_probe_node
import numpy as np
import pytest
from busutil import GO2VLM, Procs, Recorder, env, foreign_write, raw_take, wait_for
from cyclonedds.builtin import (
    BuiltinDataReader,
    BuiltinTopicDcpsParticipant,
    BuiltinTopicDcpsPublication,
    BuiltinTopicDcpsSubscription,
)
from cyclonedds.idl._xt_builder import XTBuilder
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from rosbagsutil import typestore

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node, QosProfile, domain, running
from go2vlm.bus import discovery_info as di
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.image import numpy_to_image
from go2vlm.msgs.rmw_dds_common import ParticipantEntitiesInfo
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.std_msgs import Header, String


class Peer(Node):
    name = "bus_interop_peer"


@pytest.fixture
def node() -> Iterator[Peer]:
    n = Peer(node_name="bus_interop_peer")
    with running(n):
        yield n


def discovery_reader() -> DataReader:
    dp = domain.participant()
    topic = domain.topic(dp, di.TOPIC, ParticipantEntitiesInfo)
    # keyless topic: one instance for every participant, so a deep history keeps them all
    return DataReader(dp, topic, qos=QosProfile(reliable=True, transient_local=True, depth=256).to_dds())


def test_topic_is_bare_and_latched() -> None:
    assert di.TOPIC == "ros_discovery_info"  # ROS 2 uses the bare DDS name, no rt/ prefix
    assert QOS_LATCHED.reliable and QOS_LATCHED.transient_local and QOS_LATCHED.depth == 1
    assert di.ros_node_name("go2vlm-topic.echo") == "go2vlm_topic_echo"
    assert di.ros_node_name("2cam") == "_2cam"


def test_in_process_nodes_are_announced() -> None:
    # Without the parameter services, so that the counts are the node's own topics (the services'
    # endpoints are announced too: tests/bus/test_bus_param_services.py).
    a = Peer(node_name="announce_a", parameter_services=False)
    b = Peer(node_name="announce_b", parameter_services=False)
    a.create_publisher(String, "/announce/x")
    b.create_subscription(String, "/announce/x", lambda _m: None)
    b.create_subscription(String, "/announce/y", lambda _m: None)
    info = di.current()
    assert info is not None
    assert info.gid.to_bytes() == domain.participant().guid.bytes
    nodes = {n.node_name: n for n in info.node_entities_info_seq}
    assert (len(nodes["announce_a"].reader_gid_seq), len(nodes["announce_a"].writer_gid_seq)) == (0, 1)
    assert (len(nodes["announce_b"].reader_gid_seq), len(nodes["announce_b"].writer_gid_seq)) == (2, 0)
    assert nodes["announce_a"].writer_gid_seq[0].to_bytes() == a.publishers[0].guid.bytes
    assert nodes["announce_a"].node_namespace == "/"
    a.shutdown()
    b.shutdown()
    names = {n.node_name for n in di.current().node_entities_info_seq}  # type: ignore[union-attr]
    assert not names & {"announce_a", "announce_b"}


# Every node serves the six parameter services (a request reader and a reply writer each) and
# publishes /parameter_events, as an rclcpp node does.
PARAM_READERS, PARAM_WRITERS = 6, 7


def test_subprocess_node_shows_up_in_ros_discovery_info(procs: Procs) -> None:
    """What `ros2 node list` / rqt_graph decode: our probe node with its 1 reader and 2 writers (and the
    parameter services' endpoints), whose gids are the participant's and the endpoints' DDS GUIDs."""
    reader = discovery_reader()
    p = bus_probe_node.start(procs, "--name", "probe_graph")
    found: dict[str, Any] = {}

    def seen() -> bool:
        for s in reader.take(N=32):
            if isinstance(s, ParticipantEntitiesInfo):
                for n in s.node_entities_info_seq:
                    readers, writers = len(n.reader_gid_seq), len(n.writer_gid_seq)
                    if n.node_name == "probe_graph" and (readers, writers) == (1 + PARAM_READERS, 2 + PARAM_WRITERS):
                        found["participant"], found["node"] = s.gid.to_bytes(), n
        return bool(found)

    assert wait_for(seen, 15), "probe_graph never announced on ros_discovery_info"
    node = found["node"]
    assert node.node_namespace == "/"
    dp = domain.participant()
    participants = {
        s.key.bytes for s in BuiltinDataReader(dp, BuiltinTopicDcpsParticipant).take(N=64) if hasattr(s, "key")
    }
    assert found["participant"] in participants
    pubs = {
        s.key.bytes: s.topic_name
        for s in BuiltinDataReader(dp, BuiltinTopicDcpsPublication).take(N=256)
        if isinstance(getattr(s, "topic_name", None), str)
    }
    subs = {
        s.key.bytes: s.topic_name
        for s in BuiltinDataReader(dp, BuiltinTopicDcpsSubscription).take(N=256)
        if isinstance(getattr(s, "topic_name", None), str)
    }
    writers = sorted(pubs[g.to_bytes()] for g in node.writer_gid_seq)
    readers = sorted(subs[g.to_bytes()] for g in node.reader_gid_seq)
    assert [t for t in writers if t.startswith("rt/")] == ["rt/parameter_events", "rt/probe/out", "rt/probe/tick"]
    assert [t for t in readers if t.startswith("rt/")] == ["rt/probe/in"]
    assert "rq/probe_graph/set_parametersRequest" in readers and "rr/probe_graph/set_parametersReply" in writers
    assert procs.stop(p) == 128 + signal.SIGINT  # stopped by Ctrl-C: the signal convention


def wait_until_ticking(node: Peer) -> None:
    ticks = Recorder()
    node.create_subscription(String, "/probe/tick", ticks)
    assert wait_for(lambda: len(ticks) > 0, 20), "the probe node never started"


def test_topic_list_hides_ros_discovery_info(procs: Procs, node: Peer) -> None:
    p = bus_probe_node.start(procs, "--name", "probe_list")
    wait_until_ticking(node)
    out = subprocess.run(
        [*GO2VLM, "topic", "list", "-t", "--wait", "2"], capture_output=True, text=True, timeout=30, env=env()
    )
    assert "/probe/tick [std_msgs/msg/String]" in out.stdout
    assert "ros_discovery_info" not in out.stdout and "rmw_dds_common" not in out.stdout
    procs.stop(p)


# -- foreign bytes --------------------------------------------------------------------------------


def rosbags_twist(x: float, wz: float) -> tuple[Any, bytes]:
    ts = typestore()
    v3 = ts.types["geometry_msgs/msg/Vector3"]
    msg = ts.types["geometry_msgs/msg/Twist"](linear=v3(x=x, y=0.0, z=0.0), angular=v3(x=0.0, y=0.0, z=wz))
    return msg, bytes(ts.serialize_cdr(msg, "geometry_msgs/msg/Twist"))


def rosbags_image(h: int, w: int, frame: str) -> tuple[Any, bytes]:
    ts = typestore()
    rng = np.random.default_rng(7)
    data = rng.integers(0, 255, h * w * 3, dtype=np.uint8)
    hdr = ts.types["std_msgs/msg/Header"](
        stamp=ts.types["builtin_interfaces/msg/Time"](sec=12, nanosec=345), frame_id=frame
    )
    msg = ts.types["sensor_msgs/msg/Image"](
        header=hdr, height=h, width=w, encoding="rgb8", is_bigendian=0, step=w * 3, data=data
    )
    return msg, bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/Image"))


@pytest.mark.parametrize("where", ["in-process", "subprocess"])
def test_foreign_cmd_vel_and_image_reach_go2vlm(procs: Procs, node: Peer, where: str, tmp_path: Path) -> None:
    """A 'foreign' (rosbags-serialized, ROS-2-exact) writer on rt/cmd_vel and rt/camera/image_raw is
    understood by our subscriptions and by `go2vlm topic echo` in another process."""
    dp = domain.participant()
    twist_ref, twist_raw = rosbags_twist(0.3, -0.7)
    img_ref, img_raw = rosbags_image(3, 5, "front_camera")
    tw = DataWriter(dp, domain.topic(dp, "rt/cmd_vel", Twist), qos=QOS_DEFAULT.to_dds())
    iw = DataWriter(dp, domain.topic(dp, "rt/camera/image_raw", Image), qos=QOS_SENSOR.to_dds())
    if where == "in-process":
        twists, images = Recorder(), Recorder()
        node.create_subscription(Twist, "/cmd_vel", twists)
        node.create_subscription(Image, "/camera/image_raw", images, QOS_SENSOR)
        done = lambda: len(twists) > 0 and len(images) > 0  # noqa: E731
    else:
        out_t, out_i = (tmp_path / "t.jsonl").open("w"), (tmp_path / "i.jsonl").open("w")
        cmd = [*GO2VLM, "topic", "echo"]
        et = subprocess.Popen(
            [*cmd, "/cmd_vel", "geometry_msgs/msg/Twist", "--json", "--count", "1", "--timeout", "15"],
            stdout=out_t,
            env=env(),
        )
        ei = subprocess.Popen(
            [
                *cmd,
                "/camera/image_raw",
                "sensor_msgs/msg/Image",
                "--json",
                "--count",
                "1",
                "--timeout",
                "15",
                "--qos",
                "sensor",
                "--bytes",
                "list",
            ],
            stdout=out_i,
            env=env(),
        )
        procs.procs += [et, ei]
        done = lambda: et.poll() is not None and ei.poll() is not None  # noqa: E731
    deadline = time.monotonic() + 20
    while not done() and time.monotonic() < deadline:
        foreign_write(tw, Twist(), twist_raw)
        foreign_write(iw, Image(), img_raw)
        time.sleep(0.05)
    assert done()
    if where == "in-process":
        t, i = twists.msgs()[0], images.msgs()[0]
        assert t == Twist(linear=Vector3(x=0.3), angular=Vector3(z=-0.7))
        assert (i.header.frame_id, i.header.stamp.sec, i.header.stamp.nanosec) == ("front_camera", 12, 345)
        assert i.data == img_ref.data.tobytes() and (i.height, i.width, i.step) == (3, 5, 15)
        assert i.serialize() == img_raw
    else:
        import json

        t = json.loads((tmp_path / "t.jsonl").read_text().splitlines()[0])
        i = json.loads((tmp_path / "i.jsonl").read_text().splitlines()[0])
        assert t["linear"]["x"] == 0.3 and t["angular"]["z"] == -0.7
        assert i["header"]["frame_id"] == "front_camera" and i["data"] == img_ref.data.tolist()


def test_go2vlm_bytes_decode_with_rosbags(node: Peer) -> None:
    """The bytes our publishers put on the wire, taken raw from a DDS reader, decode with rosbags
    (what a ROS 2 C++ node would do) to the same message."""
    dp = domain.participant()
    treader = DataReader(dp, domain.topic(dp, "rt/interop/cmd_vel", Twist), qos=QOS_DEFAULT.to_dds())
    ireader = DataReader(dp, domain.topic(dp, "rt/interop/image", Image), qos=QOS_DEFAULT.to_dds())
    tpub = node.create_publisher(Twist, "/interop/cmd_vel")
    ipub = node.create_publisher(Image, "/interop/image")
    arr = np.arange(2 * 7 * 3, dtype=np.uint8).reshape(2, 7, 3)
    img = numpy_to_image(arr, "bgr8", Header(frame_id="c"))
    tpub.publish(Twist(linear=Vector3(x=0.5), angular=Vector3(z=0.25)))
    ipub.publish(img)
    got: dict[str, bytes] = {}
    assert wait_for(lambda: _fill(got, treader, ireader), 10)
    ts = typestore()
    t = ts.deserialize_cdr(got["t"], "geometry_msgs/msg/Twist")
    assert (t.linear.x, t.angular.z) == (0.5, 0.25)
    i = ts.deserialize_cdr(got["i"], "sensor_msgs/msg/Image")
    assert (i.header.frame_id, i.encoding, i.height, i.width, i.step) == ("c", "bgr8", 2, 7, 21)
    np.testing.assert_array_equal(i.data.reshape(2, 7, 3), arr)


def _fill(got: dict[str, bytes], treader: DataReader, ireader: DataReader) -> bool:
    for key, reader in (("t", treader), ("i", ireader)):
        if not got.get(key):
            raws = raw_take(reader)
            if raws:
                got[key] = raws[0]
    return bool(got.get("t")) and bool(got.get("i"))


def test_bytes_field_has_the_xtypes_id_of_an_octet_sequence() -> None:
    """Declaring Image.data as `bytes` (one block, fast) describes the same type to DDS as the
    textbook `sequence<octet>` declaration, so peers using either match."""

    from bus_naive_types import NaiveImage

    ours, _ = XTBuilder.process_type(Image)
    naive, _ = XTBuilder.process_type(NaiveImage)
    assert ours.minimal.typeid_with_size == naive.minimal.typeid_with_size
    assert ours.complete.typeid_with_size == naive.complete.typeid_with_size
    sample = Image(height=1, width=1, encoding="mono8", step=1, data=b"\x07")
    assert NaiveImage.deserialize(sample.serialize()).data == [7]


def test_node_list(procs: Procs, node: Peer) -> None:
    p = bus_probe_node.start(procs, "--name", "probe_nodes")
    wait_until_ticking(node)
    out = subprocess.run(
        [*GO2VLM, "node", "list", "-v", "--wait", "2"], capture_output=True, text=True, timeout=30, env=env()
    )
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert "/probe_nodes" in lines, out.stdout
    block = lines[lines.index("/probe_nodes") :][:14]
    assert block == [
        "/probe_nodes",
        "  Subscribers:",
        "    /probe/in",
        "  Publishers:",
        "    /parameter_events",
        "    /probe/out",
        "    /probe/tick",
        "  Service Servers:",
        "    /probe_nodes/describe_parameters",
        "    /probe_nodes/get_parameter_types",
        "    /probe_nodes/get_parameters",
        "    /probe_nodes/list_parameters",
        "    /probe_nodes/set_parameters",
        "    /probe_nodes/set_parameters_atomically",
    ]
    procs.stop(p)
