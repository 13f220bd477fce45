"""The answer delay (perception/answer_delay.py): a slow model's answers, one frame at a time, each about
its own frame and never earlier than latency_s after it; and its node over real DDS."""

from __future__ import annotations

import threading

from busutil import wait_for
from hypothesis import given
from hypothesis import strategies as st

from go2vlm.bus import QOS_DEFAULT, Node, running
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.std_msgs import Header
from go2vlm.msgs.vision_msgs import Detection2DArray, detection_array, detection_boxes
from go2vlm.perception.answer_delay import AnswerDelay
from go2vlm.perception.answer_delay_node import AnswerDelayConfig, AnswerDelayNode


@given(
    latency=st.sampled_from([0.0, 0.1, 0.5, 1.0, 2.5, 5.0]),
    gaps=st.lists(st.floats(min_value=0.01, max_value=1.0), min_size=1, max_size=200),
)
def test_answers_are_about_their_frame_late_enough_and_one_at_a_time(latency: float, gaps: list[float]) -> None:
    delay: AnswerDelay[int] = AnswerDelay(latency)
    t, out, taken = 0.0, [], []
    for i, gap in enumerate(gaps):
        t += gap
        before = delay.busy
        for stamp, answer in delay.offer(t, i):
            out.append((t, stamp, answer))
        if delay.busy is not None and delay.busy is not before and delay.busy[1] == i:
            taken.append(i)
    for now, stamp, answer in out:
        assert now + 1e-9 >= stamp + latency  # never early
        assert answer in taken  # an answer about a frame it looked at, with that frame's stamp
    assert [a for _, _, a in out] == taken[: len(out)]  # in order, none twice
    assert len(taken) - len(out) <= 1  # at most one in flight
    n = delay.counters
    assert n["taken"] + n["skipped"] == len(gaps) and n["answered"] == len(out)


def test_zero_latency_answers_each_frame_on_the_next() -> None:
    delay: AnswerDelay[str] = AnswerDelay(0.0)
    assert delay.offer(0.0, "a") == []
    assert delay.offer(0.1, "b") == [(0.0, "a")]
    assert delay.offer(0.2, "c") == [(0.1, "b")]


class _Rig(Node):
    name = "answer_delay_rig"

    def __init__(self, **kw) -> None:
        super().__init__(**kw)
        self.lock = threading.Lock()
        self.got: list[tuple[float, list]] = []
        self.pub = self.create_publisher(Detection2DArray, "/sim/detections", QOS_DEFAULT)
        self.create_subscription(Detection2DArray, "/vlm/detections", self.on_out, QOS_DEFAULT)

    def on_out(self, msg: Detection2DArray) -> None:
        with self.lock:
            self.got.append((msg.header.stamp.to_sec(), detection_boxes(msg)))


def test_node_delays_frames_by_their_stamps() -> None:
    node, rig = AnswerDelayNode(AnswerDelayConfig(latency_s=0.5)), _Rig()
    with running(node, rig):
        i = 0

        def send() -> bool:
            nonlocal i
            stamp = Time(sec=100 + i // 10, nanosec=(i % 10) * 100_000_000)
            rig.pub.publish(detection_array(Header(stamp=stamp), [("red_ball", (1.0, 2.0, 3.0, 4.0), 1.0)]))
            i += 1
            with rig.lock:
                return len(rig.got) >= 3

        assert wait_for(send, 30)
    stamps = [s for s, _ in rig.got]
    assert all(round((b - a) * 10) >= 5 for a, b in zip(stamps, stamps[1:], strict=False))  # one per 0.5 s of stamps
    assert rig.got[0][1][0][0] == "red_ball"
