"""Perception regression from a bag: record the camera and the perception outputs of the real pipeline
(MuJoCo sim head camera -> color_detector, as real processes), replay only /camera/image_raw through
fresh perception nodes, and compare their outputs with the recorded ones, frame by frame (outputs
carry their source image's stamp).

To put another perception node under the same test, add a `Stage` to STAGES: the node kind, its
output topic and type, and how one output is compared with its recorded twin.
"""

from __future__ import annotations

import signal
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from busutil import Procs, Recorder, wait_for
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from go2vlm.bus import QOS_DEFAULT, Node, running
from go2vlm.msgs.geometry_msgs import PointStamped

# Slow: the sim and the colour detector as processes into a bag, then a replay through fresh nodes.
pytestmark = pytest.mark.slow


@dataclass
class Stage:
    kind: str  # node kind (`go2vlm run KIND`)
    topic: str  # its output
    msg_type: type
    key: Callable[[Any], tuple[int, int]]  # the source image's stamp, from an output message
    same: Callable[[Any, Any], bool]  # (replayed, recorded) -> equal


def _stamp(m: Any) -> tuple[int, int]:
    return (m.header.stamp.sec, m.header.stamp.nanosec)


STAGES = [
    Stage(
        "color_detector",
        "/detected_target",
        PointStamped,
        _stamp,
        lambda a, b: (a.point.x, a.point.y, a.point.z) == (b.point.x, b.point.y, b.point.z),
    ),
    # The tracker joins here, e.g. Stage("tracker", "/tracked_target", ..., _stamp, compare_tracks),
    # once its node kind is registered.
]
FRAMES = 25  # frames with a detection to record


class Collector(Node):
    name = "regression_collector"


def read_bag(bag: Path, topic: str) -> dict[tuple[int, int], Any]:
    out = {}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        for conn, _t, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            out[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = raw
    return out


def test_replayed_camera_reproduces_perception(procs: Procs, tmp_path: Path) -> None:
    bag = tmp_path / "perception"
    # 1. the real pipeline, recorded
    sim = procs.start(
        "run", "sim",
        "--param", "mode=kinematic", "--param", "world=follow_ball",
        "--param", "camera_width=320", "--param", "camera_height=240", "--param", "camera_rate_hz=10",
        "--param", "world_camera=false",
    )  # fmt: skip
    detectors = [procs.start("run", s.kind) for s in STAGES]
    rec = procs.start("record", "/camera/image_raw", *(s.topic for s in STAGES), "-o", str(bag), "--no-progress")
    watch = Collector()
    seen = Recorder()
    watch.create_subscription(PointStamped, STAGES[0].topic, seen, QOS_DEFAULT)
    with running(watch):
        ok = wait_for(lambda: len(seen) >= FRAMES + 5, 120)
    assert ok, f"only {len(seen)} detections from the live pipeline"
    assert procs.stop(rec, signal.SIGINT, timeout=20) == 0
    for p in (*detectors, sim):
        procs.stop(p)

    recorded_images = read_bag(bag, "/camera/image_raw")
    assert len(recorded_images) >= FRAMES
    for stage in STAGES:
        recorded = {}
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            conns = [c for c in reader.connections if c.topic == stage.topic]
            for _conn, _t, raw in reader.messages(connections=conns):
                m = stage.msg_type.deserialize(bytes(raw))
                recorded[stage.key(m)] = m
        assert len(recorded) >= FRAMES
        assert set(recorded) <= set(recorded_images), "an output whose image is not in the bag"

        # 2. only the camera, replayed through a fresh node
        fresh = procs.start("run", stage.kind)
        got = Recorder()
        col = Collector(node_name="regression_replay")
        sub = col.create_subscription(stage.msg_type, stage.topic, got, QOS_DEFAULT)
        with running(col):
            assert wait_for(lambda sub=sub: sub.publisher_count > 0, 30), f"{stage.kind} did not start"
            # Half speed: the detector reads images best-effort, as from a camera.
            play = procs.start(
                "play", str(bag), "--topics", "/camera/image_raw", "--rate", "0.5", "--wait-for", "/camera/image_raw"
            )
            assert play.wait(120) == 0, play.stdout.read() if play.stdout else ""
            expected = len(recorded)
            wait_for(lambda got=got, n=expected: len(got) >= n, 10)
        procs.stop(fresh)

        # 3. the same outputs for the same frames
        replayed = {stage.key(m): m for m in got.msgs()}
        extra = set(replayed) - set(recorded)
        assert not extra, f"{stage.kind}: outputs for frames that had none when recorded: {sorted(extra)[:5]}"
        different = [k for k in replayed if not stage.same(replayed[k], recorded[k])]
        assert not different, f"{stage.kind}: {len(different)} outputs differ, e.g. {replayed[different[0]]}"
        # Only a frame lost on the way (best-effort) may miss its output.
        assert len(replayed) >= 0.9 * len(recorded), f"{stage.kind}: {len(replayed)} of {len(recorded)} outputs"
