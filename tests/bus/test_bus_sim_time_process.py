"""A node with use_sim_time, as a real process over real DDS: it does nothing until /clock arrives,
then its timers follow /clock and its stamps carry sim time. A wall-clock twin of the same node runs
beside it, so "nothing happened" is checked against something that did, not against a sleep."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest
from busutil import Procs, Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, Node
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.sensor_msgs import Image

PERIOD = 0.5  # the sim-time node's frame period (sim seconds)
START = 10.0  # sim time when our /clock starts
STEP = 0.05


class ClockProbe(Node):
    name = "sim_time_probe"

    def __init__(self) -> None:
        super().__init__()
        self.sim_frames = Recorder()
        self.wall_frames = Recorder()
        self.create_subscription(Image, "/camera/image_raw", self.sim_frames, QOS_DEFAULT)
        self.wall_sub = self.create_subscription(Image, "/twin/image_raw", self.wall_frames, QOS_DEFAULT)
        self.clock_pub = self.create_publisher(Clock, "/clock", QOS_DEFAULT)

    def stamps(self) -> list[float]:
        return [round(m.header.stamp.to_sec(), 6) for m in self.sim_frames.msgs()]


@pytest.fixture
def probe(procs: Procs) -> Iterator[ClockProbe]:
    p = ClockProbe().start()
    procs.start("run", "test_pattern", "--param", f"period_s={PERIOD}", "--param", "use_sim_time=true")
    procs.start(
        "run", "test_pattern", "--name", "twin", "--param", "period_s=0.1",
        "--remap", "/camera/image_raw:=/twin/image_raw", "--remap", "/camera/camera_info:=/twin/camera_info",
    )  # fmt: skip
    yield p
    p.shutdown()


def _publish_clock_until(probe: ClockProbe, t: float, pred: object, timeout: float = 20.0) -> bool:
    """Publish /clock = t until `pred()` holds (best-effort readers may miss one sample)."""
    stop = threading.Event()

    def again() -> None:
        while not stop.wait(0.05):  # pacing of a publisher, not a timing assertion
            probe.clock_pub.publish(Clock(clock=Time.from_sec(t)))

    probe.clock_pub.publish(Clock(clock=Time.from_sec(t)))
    th = threading.Thread(target=again, daemon=True)
    th.start()
    try:
        return wait_for(pred, timeout)  # type: ignore[arg-type]
    finally:
        stop.set()
        th.join()


def test_a_sim_time_node_waits_for_clock_then_follows_it(probe: ClockProbe) -> None:
    # The wall twin publishes every 0.1 s of wall time; in that time the sim-time node, with no
    # /clock, publishes no periodic frame (at most its start-up frame, stamped 0).
    assert wait_for(lambda: len(probe.wall_frames) >= 15, 30.0), "the wall-clock twin is not publishing"
    assert all(s == 0.0 for s in probe.stamps()), probe.stamps()
    assert len(probe.sim_frames) <= 1
    before = len(probe.sim_frames)

    # /clock starts at START: timers anchor there. Step sim time by STEP up to two periods later.
    ticks = [round(START + i * STEP, 6) for i in range(int(2 * PERIOD / STEP) + 1)]
    published: list[float] = []
    for t in ticks[:-1]:
        probe.clock_pub.publish(Clock(clock=Time.from_sec(t)))
        published.append(t)
        time.sleep(0.02)  # publisher pacing, as the sim paces its physics chunks; nothing is asserted on it
    end = ticks[-1]
    published.append(end)
    assert _publish_clock_until(probe, end, lambda: end in probe.stamps()), (probe.stamps(), end)

    after = probe.stamps()[before:]
    print(f"sim-time frames after /clock started at {START}: {after}")
    assert all(s in published for s in after), f"stamps are sim time from /clock: {after}"
    assert after == sorted(after) and after[-1] == end
    # The period is sim time: the frames due at START + PERIOD and START + 2 * PERIOD (if a /clock
    # sample was missed, the next one carries the frame; never a burst). The new-reader frame for
    # the probe, also on the node's clock, is the only other one.
    periodic = [s for s in after if s >= START + PERIOD - 1e-9]
    assert len(periodic) <= 3 and end in periodic, after
    assert all(s > START for s in after), "nothing fires at the first /clock: timers anchor there"
    assert len(after) <= 5, f"no burst of frames: {after}"
