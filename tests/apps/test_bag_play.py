"""`go2vlm play` as a real process: every message back in order with its recorded bytes, timing scaled
by --rate, each topic with its recorded QoS, /clock with the bag's time, --topics and --remap."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest
from busutil import GO2VLM, Procs, Recorder, env, wait_for

from go2vlm.apps.bag.bagfile import BagWriter
from go2vlm.bus import QOS_DEFAULT, QOS_IMAGE, QOS_LATCHED, QOS_SENSOR, Node, running
from go2vlm.bus.graph import discover
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.msgdef import msgdef, rihs01, ros_type
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.std_msgs import String

T0 = 1_700_000_000_000_000_000  # the bag's start (ns)
STEP = 100_000_000  # 100 ms between messages
N = 20


class Listener(Node):
    name = "play_test_listener"


def make_bag(folder: Path) -> tuple[list[String], list[Twist], Image]:
    """A bag written by our writer: a 10 Hz String, a 10 Hz Twist, one latched-at-record Image."""
    w = BagWriter(folder)
    for topic, cls, qos in (
        ("/bag/text", String, QOS_DEFAULT),
        ("/bag/twist", Twist, QOS_SENSOR),
        ("/bag/image", Image, QOS_LATCHED),
    ):
        w.add_topic(topic, ros_type(cls), msgdef(cls), rihs01(cls), [qos])
    texts = [String(data=f"message {i}") for i in range(N)]
    twists = [Twist(linear=Vector3(x=i / 10)) for i in range(N)]
    image = Image(height=2, width=2, encoding="mono8", step=2, data=b"\x01\x02\x03\x04")
    w.write("/bag/image", image.serialize(), T0, T0)
    for i in range(N):
        t = T0 + i * STEP
        w.write("/bag/text", texts[i].serialize(), t, t)
        w.write("/bag/twist", twists[i].serialize(), t + 1000, t)
    w.close()
    return texts, twists, image


def test_play_timing_qos_clock_and_remap(procs: Procs, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    texts, twists, image = make_bag(bag)
    node = Listener()
    got_text, got_twist, got_clock, got_image = Recorder(), Recorder(), Recorder(), Recorder()
    node.create_subscription(String, "/bag/text", got_text, QOS_DEFAULT)
    node.create_subscription(Twist, "/renamed/twist", got_twist, QOS_SENSOR)
    node.create_subscription(Clock, "/clock", got_clock, QOS_DEFAULT)
    with running(node):
        play = procs.start(
            "play", str(bag), "--rate", "2", "--remap", "/bag/twist:=/renamed/twist",
            "--wait-for", "/bag/text", "/renamed/twist", "/clock",
        )  # fmt: skip
        # A late joiner gets the latched image as long as the player runs: it publishes transient-local.
        assert wait_for(lambda: len(got_text) >= 1, 30), "nothing played"
        node.create_subscription(Image, "/bag/image", got_image, QOS_LATCHED)
        assert wait_for(lambda: len(got_text) == N and len(got_twist) >= N - 2, 30)
        play.wait(30)
    out = play.stdout.read() if play.stdout else ""
    assert play.returncode == 0, out
    assert [m.data for m in got_text.msgs()] == [m.data for m in texts]
    back_twists = [m.linear.x for m in got_twist.msgs()]
    assert back_twists == [t.linear.x for t in twists if t.linear.x in back_twists]  # best-effort, in order
    assert got_image.msgs() and got_image.msgs()[0] == image
    # --rate 2: 19 gaps of 100 ms of bag time take about 0.95 s (a lower bound only: a busy machine is slower)
    times = [t for t, _ in got_text.items]
    assert times[-1] - times[0] >= 0.8 * (N - 1) * STEP / 1e9 / 2
    clocks = [m.clock.sec * 1_000_000_000 + m.clock.nanosec for m in got_clock.msgs()]
    assert clocks and clocks == sorted(clocks)
    assert clocks[0] >= T0 and clocks[-1] == T0 + (N - 1) * STEP + 1000  # ends at the last message's time
    assert "published" in out and "Traceback" not in out


def test_play_offers_the_recorded_qos_and_filters_topics(procs: Procs, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    make_bag(bag)
    play = procs.start("play", str(bag), "--loop", "--rate", "5", "--topics", "/bag/image", "/bag/twist")
    seen: dict = {}

    def ready() -> bool:
        seen.update(discover(0.3))
        return "/bag/image" in seen and "/bag/twist" in seen and bool(seen["/bag/image"].publishers)

    assert wait_for(ready, 30), seen.keys()
    assert "/bag/text" not in seen
    image_qos = seen["/bag/image"].publishers[0]
    assert image_qos.reliable and image_qos.transient_local and image_qos.depth == QOS_LATCHED.depth
    twist_qos = seen["/bag/twist"].publishers[0]
    assert not twist_qos.reliable and not twist_qos.transient_local and twist_qos.depth == QOS_SENSOR.depth
    assert procs.stop(play) == 0


def test_recorded_bag_plays_back_byte_for_byte(tmp_path: Path) -> None:
    """Record with the recorder, play with the player: a subscriber gets the very messages."""
    from go2vlm.apps.bag.recorder import BagRecorder

    sender = Listener(node_name="play_test_sender")
    pub = sender.create_publisher(Image, "/rt/img", QOS_IMAGE)
    frames = [Image(height=1, width=3, encoding="rgb8", step=9, data=bytes(range(i, i + 9))) for i in range(15)]
    with running(sender):
        rec = BagRecorder(tmp_path / "rt", ["/rt/img"]).start()
        assert wait_for(lambda: pub.matched > 0, 20)
        for f in frames:
            pub.publish(f)
            time.sleep(0.02)  # a 50 Hz stream: the recorded gaps pace the replay of a depth-2 writer
        assert wait_for(lambda: rec.messages == len(frames), 20)
        rec.stop()
    listener = Listener()
    got = Recorder()
    listener.create_subscription(Image, "/rt/img", got, QOS_DEFAULT)
    with running(listener):
        out = subprocess.run(
            # at a fifth of the rate: the gaps a depth-2 writer needs hold on a busy machine too
            [*GO2VLM, "play", str(tmp_path / "rt"), "--wait-for", "/rt/img", "--rate", "0.2"],
            capture_output=True,
            text=True,
            timeout=60,
            env=env(),
        )
        assert out.returncode == 0, out.stderr
        assert wait_for(lambda: len(got) == len(frames), 30)
    assert got.msgs() == frames


@pytest.mark.parametrize(
    "args",
    [("play", "/nonexistent/bag"), ("play", "{bag}", "--topics", "/nope"), ("play", "{bag}", "--rate", "0")],
)
def test_play_usage_errors(tmp_path: Path, args: tuple[str, ...]) -> None:
    make_bag(tmp_path / "b")
    cmd = [a.format(bag=tmp_path / "b") for a in args]
    start = time.monotonic()
    out = subprocess.run([*GO2VLM, *cmd], capture_output=True, text=True, timeout=60, env=env())
    assert out.returncode == 2, out.stderr
    assert "Traceback" not in out.stderr and out.stderr.strip().count("\n") == 0, out.stderr
    assert time.monotonic() - start < 60
