"""player: publishes a rosbag2 bag (MCAP) back onto the bus with its original timing, and the bag's
time on /clock. `go2vlm play` runs it; a program embeds it like any node (`start()`, then wait on
`finished`).

Topics
  publishes   every topic of the bag (or of `topics`) with its recorded type, the serialized samples
              exactly as stored; QoS as recorded (offered_qos_profiles): reliable if every recorded
              publisher was, transient-local (latched) if every one was, keep-last their depth
              /clock  rosgraph_msgs/Clock (reliable, volatile, keep-last 10), the bag's time (the
              messages' log time), at clock_hz while playing, so use_sim_time nodes follow the bag;
              a /clock recorded in the bag is not replayed while this is on
  subscribes  nothing
Remapping (`--remap /a:=/b`) renames a topic as it is published.

Timing: message i goes out at start + (log_time_i - log_time_0) / rate; `loop` starts over at the
end. Before the first message the player waits (at most wait_timeout_s) until every topic in
`wait_for` has a subscriber, so a freshly started consumer hears the bag from its first message.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any

from go2vlm.apps.bag.bagfile import BagReader
from go2vlm.bus import QOS_DEFAULT, Node, Publisher, QosProfile, param
from go2vlm.bus.topics import CLOCK
from go2vlm.msgs import get_type
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.rosgraph_msgs import Clock

__all__ = ["PlayerConfig", "PlayerNode"]


@dataclass
class PlayerConfig:
    bag: str = param("", help="the bag folder (with metadata.yaml) or an .mcap file")
    rate: float = param(1.0, help="playback speed factor", min=0.01, max=1000.0)
    loop: bool = param(False, help="start over at the end")
    topics: list[str] = param(list, help="play only these topics (default: all)")
    clock: bool = param(True, help="publish the bag's time on /clock")
    clock_hz: float = param(40.0, help="/clock rate while playing", min=1.0, max=1000.0)
    wait_for: list[str] = param(list, help="before playing, wait until these topics have a subscriber")
    wait_timeout_s: float = param(10.0, help="give up waiting for wait_for subscribers after this", min=0.0)
    delay_s: float = param(0.0, help="sleep this long before playing", min=0.0)

    def validate(self) -> None:
        if not self.bag:
            raise ValueError("bag is required: a bag folder or an .mcap file")


class PlayerNode(Node):
    name = "player"
    Config = PlayerConfig
    provides_clock = True  # with use_sim_time its clock is the bag's time, which it publishes on /clock

    def __init__(self, config: PlayerConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        c: PlayerConfig = self.config
        self.reader = BagReader(c.bag)
        wanted = set(c.topics) if c.topics else set(self.reader.topics)
        missing = sorted(wanted - set(self.reader.topics))
        if missing:
            raise ValueError(f"topic(s) not in the bag: {', '.join(missing)}; it has {', '.join(self.reader.topics)}")
        self.pubs: dict[str, Publisher[Any]] = {}
        for name in sorted(wanted):
            t = self.reader.topics[name]
            if name == CLOCK.name and c.clock:
                self.log.info("not replaying the recorded /clock: the player publishes the bag's time (clock=false)")
                continue
            try:
                cls = get_type(t.type)
            except ValueError:
                self.log.warning(f"skipping {name}: go2vlm has no definition of type {t.type}")
                continue
            self.pubs[name] = self.create_publisher(cls, name, _replay_qos(t.offered_qos))
        self.clock_pub = CLOCK.publisher(self) if c.clock else None
        self.published = 0
        self.loops = 0
        self.bag_time_ns = self.reader.start_ns
        self.finished = threading.Event()
        self._play_thread: threading.Thread | None = None

    def start(self) -> PlayerNode:
        super().start()
        if self._play_thread is None:
            self._play_thread = threading.Thread(target=self._play_safely, name=f"{self.node_name}:play", daemon=True)
            self._play_thread.start()
        return self

    # -- playback (its own thread) ---------------------------------------------------------------
    def _play_safely(self) -> None:
        try:
            self._wait_for_subscribers()
            if self.config.delay_s and self._stop.wait(self.config.delay_s):
                return
            while not self._stop.is_set():
                self.bag_time_ns = self.reader.start_ns  # a new loop: the clock starts over
                self._play_once()
                self.loops += 1
                if not self.config.loop:
                    break
        except Exception as exc:
            self.count("playback_errors")
            self.log.error(f"playback failed: {type(exc).__name__}: {exc}")
        finally:
            self.finished.set()

    def _wait_for_subscribers(self) -> None:
        pubs = [self.pubs[t] for t in self.config.wait_for if t in self.pubs]
        if not pubs:
            return
        deadline = time.monotonic() + self.config.wait_timeout_s
        while any(p.matched == 0 for p in pubs) and time.monotonic() < deadline:
            if self._stop.wait(0.02):
                return
        waiting = [p.topic for p in pubs if p.matched == 0]
        if waiting:
            self.log.warning(f"no subscriber on {', '.join(waiting)} after {self.config.wait_timeout_s:g} s; playing")
        self._stop.wait(0.25)  # we see the reader; give it a moment to see us

    def _play_once(self) -> None:
        rate = self.config.rate
        t0 = self.reader.start_ns
        wall0 = time.monotonic()
        tick = 1.0 / self.config.clock_hz
        next_clock = wall0
        for msg in self.reader.messages(set(self.pubs)):
            due = wall0 + (msg.log_time_ns - t0) / 1e9 / rate
            while True:
                now = time.monotonic()
                if self.clock_pub is not None and now >= next_clock:
                    # never past the message still to come: /clock only moves forward
                    self._publish_clock(min(t0 + int((now - wall0) * rate * 1e9), msg.log_time_ns))
                    next_clock = max(next_clock + tick, now)
                if now >= due:
                    break
                wake = min(due, next_clock) if self.clock_pub is not None else due
                if self._stop.wait(max(0.0, wake - now)):
                    return
            self.pubs[msg.topic].publish_raw(msg.data)
            self.published += 1
            self.bag_time_ns = msg.log_time_ns
        if self.clock_pub is not None:
            self._publish_clock(self.reader.end_ns)

    def _publish_clock(self, t_ns: int) -> None:
        if self.clock_pub is None or t_ns < self.bag_time_ns:
            return
        self.bag_time_ns = t_ns
        self.clock_pub.publish(Clock(clock=Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)))
        if self.clock.sim:
            self.clock.set(t_ns * 1e-9)

    def close(self) -> None:
        if self._play_thread is not None:
            self._play_thread.join(2.0)


def _replay_qos(offered: list[QosProfile]) -> QosProfile:
    """The QoS to publish a topic with: what every recorded publisher offered, as `ros2 bag play` does."""
    if not offered:
        return QOS_DEFAULT
    return QosProfile(
        reliable=all(q.reliable for q in offered),
        transient_local=all(q.transient_local for q in offered),
        depth=max(q.depth for q in offered),
    )
