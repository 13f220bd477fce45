"""`go2vlm record` as a real process against real publishers: rosbags' AnyReader reads every message
back equal to what was sent (a 640x480 image stream, a latched topic published before the recorder
started, a best-effort topic), the bytes are the wire CDR, and the metadata follows rosbag2 Jazzy."""

from __future__ import annotations

import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from busutil import GO2VLM, Procs, env, wait_for
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from go2vlm.apps.bag.recorder import BagRecorder
from go2vlm.bus import QOS_DEFAULT, QOS_IMAGE, QOS_LATCHED, QOS_SENSOR, Node, QosProfile, running
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.image import numpy_to_image
from go2vlm.msgs.msgdef import msgdef, rihs01
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.std_msgs import Header, String

FRAMES = 20
TWISTS = 60


class Sender(Node):
    name = "bag_test_sender"


@pytest.fixture
def sender() -> Iterator[Sender]:
    n = Sender()
    with running(n):
        yield n


def metadata(bag: Path) -> dict[str, Any]:
    try:
        return yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    except (OSError, TypeError, KeyError, yaml.YAMLError):
        return {}


def counts(bag: Path) -> dict[str, int]:
    return {t["topic_metadata"]["name"]: t["message_count"] for t in metadata(bag).get("topics_with_message_count", [])}


def padded_equal(raw: bytes, ser: bytes) -> bool:
    """The wire bytes: our CDR, padded to whole 4-byte words as Cyclone writes it."""
    return raw[: len(ser)] == ser and len(raw) - len(ser) < 4 and not any(raw[len(ser) :])


def test_record_process_reads_back_with_rosbags(procs: Procs, sender: Sender, tmp_path: Path) -> None:
    bag = tmp_path / "run1"
    latched_pub = sender.create_publisher(String, "/rec/latched", QOS_LATCHED)
    latched = String(data="set before the recorder started: 狗")
    latched_pub.publish(latched)
    img_pub = sender.create_publisher(Image, "/rec/image", QOS_IMAGE)
    twist_pub = sender.create_publisher(Twist, "/rec/twist", QOS_DEFAULT)
    fast_pub = sender.create_publisher(String, "/rec/fast", QOS_SENSOR)
    rec = procs.start(
        "record", "/rec/latched", "/rec/image", "/rec/twist", "/rec/fast", "-o", str(bag), "--no-progress"
    )
    pubs = (latched_pub, img_pub, twist_pub, fast_pub)
    assert wait_for(lambda: all(p.matched for p in pubs), 30), "the recorder did not subscribe to every topic"
    assert wait_for(lambda: counts(bag).get("/rec/latched") == 1, 20), "the latched sample was not recorded"

    rng = np.random.default_rng(7)
    images = []
    for i in range(FRAMES):
        arr = rng.integers(0, 255, (480, 640, 3), dtype=np.uint8)
        msg = numpy_to_image(arr, "rgb8", Header(frame_id="cam", stamp=sender.stamp(1000.0 + i)))
        images.append(msg)
        img_pub.publish(msg)
        sender._stop.wait(0.03)  # about 30 Hz
    twists = [Twist(linear=Vector3(x=i * 0.01), angular=Vector3(z=-i * 0.02)) for i in range(TWISTS)]
    for t in twists:
        twist_pub.publish(t)
    fast = [String(data=f"fast {i}") for i in range(10)]
    for f in fast:
        fast_pub.publish(f)

    want = {"/rec/latched": 1, "/rec/image": FRAMES, "/rec/twist": TWISTS}
    ok = wait_for(lambda: all(counts(bag).get(k) == v for k, v in want.items()), 30)
    assert ok, f"metadata counts {counts(bag)} never reached {want}"
    assert procs.stop(rec, signal.SIGINT, timeout=20) == 0
    out = rec.stdout.read() if rec.stdout else ""
    assert "Traceback" not in out

    # -- rosbags reads every message back ---------------------------------------------------------
    ts = get_typestore(Stores.ROS2_JAZZY)
    got: dict[str, list[Any]] = {}
    raws: dict[str, list[bytes]] = {}
    with AnyReader([bag], default_typestore=ts) as reader:
        for conn, _t, raw in reader.messages():
            got.setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
            raws.setdefault(conn.topic, []).append(bytes(raw))
        qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
        types = {c.topic: c.msgtype for c in reader.connections}
    assert types == {
        "/rec/latched": "std_msgs/msg/String",
        "/rec/image": "sensor_msgs/msg/Image",
        "/rec/twist": "geometry_msgs/msg/Twist",
        "/rec/fast": "std_msgs/msg/String",
    }
    assert [m.data for m in got["/rec/latched"]] == [latched.data]
    assert len(got["/rec/image"]) == FRAMES
    for sent, back, raw in zip(images, got["/rec/image"], raws["/rec/image"], strict=True):
        assert (back.height, back.width, back.encoding, back.step) == (480, 640, "rgb8", 640 * 3)
        assert back.header.frame_id == "cam" and back.header.stamp.sec == sent.header.stamp.sec
        assert back.data.tobytes() == sent.data
        assert padded_equal(raw, sent.serialize())
    assert [(m.linear.x, m.angular.z) for m in got["/rec/twist"]] == [(t.linear.x, t.angular.z) for t in twists]
    for sent, raw in zip(twists, raws["/rec/twist"], strict=True):
        assert padded_equal(raw, sent.serialize())
    # best-effort: whatever arrived arrived once, in order
    fast_back = [m.data for m in got.get("/rec/fast", [])]
    assert fast_back == [f.data for f in fast if f.data in fast_back]

    # -- QoS profiles as offered ------------------------------------------------------------------
    def first(topic: str) -> tuple[str, str, int]:
        q = qos[topic][0]
        return q.reliability.name.lower(), q.durability.name.lower(), q.depth

    assert first("/rec/latched") == ("reliable", "transient_local", 1)
    assert first("/rec/image") == ("reliable", "volatile", QOS_IMAGE.depth)
    assert first("/rec/twist") == ("reliable", "volatile", 10)
    assert first("/rec/fast") == ("best_effort", "volatile", QOS_SENSOR.depth)

    # -- rosbag2's layout -------------------------------------------------------------------------
    meta = metadata(bag)
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap" and meta["ros_distro"] == "jazzy"
    assert meta["relative_file_paths"] == ["run1_0.mcap"]
    assert meta["message_count"] == sum(len(v) for v in got.values())
    assert meta["starting_time"]["nanoseconds_since_epoch"] > 0 and meta["duration"]["nanoseconds"] > 0
    hashes = {
        t["topic_metadata"]["name"]: t["topic_metadata"]["type_description_hash"]
        for t in meta["topics_with_message_count"]
    }
    assert hashes["/rec/image"] == rihs01(Image)
    with open(bag / "run1_0.mcap", "rb") as f:
        r = make_reader(f)
        assert r.get_header().profile == "ros2"
        summary = r.get_summary()
        assert summary is not None
        schemas = {s.name: s for s in summary.schemas.values()}
        assert schemas["sensor_msgs/msg/Image"].encoding == "ros2msg"
        assert schemas["sensor_msgs/msg/Image"].data.decode() == msgdef(Image)
        for ch in summary.channels.values():
            assert ch.message_encoding == "cdr"
            assert ch.metadata["topic_type_hash"].startswith("RIHS01_")
            assert yaml.safe_load(ch.metadata["offered_qos_profiles"])[0]["history"] == "keep_last"
        assert any(m.name == "rosbag2" and "serialized_metadata" in m.metadata for m in r.iter_metadata())
        for _s, _c, m in r.iter_messages():
            assert m.publish_time > 0 and m.log_time >= m.publish_time - 5_000_000_000


def test_recorder_api_all_topics_late_publishers_and_weaker_qos(sender: Sender, tmp_path: Path) -> None:
    """`BagRecorder` (what an episode runner embeds): -a picks up topics that appear later, honours
    exclude, and a later best-effort publisher on a reliable topic is heard without duplicates."""
    rec = BagRecorder(tmp_path / "api", all_topics=True, exclude=["/api/skip"], discovery_period_s=0.05).start()
    try:
        a = sender.create_publisher(String, "/api/mixed", QOS_DEFAULT)
        skip = sender.create_publisher(String, "/api/skip", QOS_DEFAULT)
        assert wait_for(lambda: a.matched > 0, 20)
        for i in range(20):
            a.publish(String(data=f"a{i}"))
        b = sender.create_publisher(String, "/api/mixed", QosProfile(reliable=False, depth=10))
        assert wait_for(lambda: b.matched > 0, 20), "no reader for the best-effort publisher"
        for i in range(20, 40):
            a.publish(String(data=f"a{i}"))
        for i in range(10):
            b.publish(String(data=f"b{i}"))
        late = sender.create_publisher(String, "/api/late", QOS_DEFAULT)
        assert wait_for(lambda: late.matched > 0, 20)
        late.publish(String(data="late"))
        skip.publish(String(data="never"))
        done = wait_for(lambda: {s.topic: s.messages for s in rec.stats()}.get("/api/late") == 1, 20)
        assert done, rec.stats()
        assert wait_for(lambda: {s.topic: s.messages for s in rec.stats()}.get("/api/mixed", 0) >= 40, 20)
    finally:
        result = rec.stop()
    assert result.out == tmp_path / "api"
    with AnyReader([result.out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        topics = {c.topic for c in reader.connections}
        mixed = [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages() if c.topic == "/api/mixed"]
    assert "/api/skip" not in topics and "/api/late" in topics
    assert [m for m in mixed if m.startswith("a")] == [f"a{i}" for i in range(40)], "reliable samples lost or doubled"
    assert len(mixed) == len(set(mixed)), "a sample was written twice"


def run_cli(*args: str, timeout: float = 30) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*GO2VLM, *args], capture_output=True, text=True, timeout=timeout, env=env())


def test_usage_errors_are_one_line(tmp_path: Path) -> None:
    for args in (("record",), ("record", "-a", "/x"), ("record", "/x", "--duration", "0")):
        out = run_cli(*args)
        assert out.returncode == 2, (args, out.stderr)
        assert "Traceback" not in out.stderr and out.stderr.strip().count("\n") == 0, out.stderr
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "x").write_text("x")
    out = run_cli("record", "-a", "-o", str(tmp_path / "taken"), "--duration", "1")
    assert out.returncode == 2 and "already exists" in out.stderr and "Traceback" not in out.stderr


def test_duration_stops_with_a_complete_bag(tmp_path: Path) -> None:
    out = run_cli("record", "-a", "-o", str(tmp_path / "short"), "--duration", "1", "--no-progress")
    assert out.returncode == 0, out.stderr
    with AnyReader([tmp_path / "short"], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        assert reader.message_count >= 0
