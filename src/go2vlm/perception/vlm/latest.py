"""A one-frame mailbox: the camera callback puts, the inference worker takes, newest wins.

Inference takes hundreds of milliseconds to seconds; a camera sends 10-30 frames a second.
Queueing frames (the VLM article ran inference inside the callback with a depth-10 queue)
makes every answer describe the past, later and later. Here the callback never waits: it
overwrites the slot, and each overwritten frame is counted as dropped. Receive times come from
the node's clock (sim time with use_sim_time).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Generic, TypeVar

from go2vlm.bus.clock import Clock

__all__ = ["LatestSlot", "Stamped"]

T = TypeVar("T")


@dataclass(frozen=True)
class Stamped(Generic[T]):
    item: T
    received_t: float  # clock.monotonic() at put: for ages
    received_stamp: float  # clock.now() at put: ROS time, for an item without a stamp of its own
    seq: int  # 1, 2, 3, ... in arrival order


class LatestSlot(Generic[T]):
    def __init__(self, clock: Clock | None = None) -> None:
        self.clock = clock if clock is not None else Clock()
        self._cond = threading.Condition()
        self._item: Stamped[T] | None = None
        self._closed = False
        self.received = 0
        self.dropped = 0
        self.taken = 0

    def put(self, item: T) -> bool:
        """Store ``item`` as the newest; returns True if an untaken older item was dropped."""
        with self._cond:
            self.received += 1
            dropped = self._item is not None
            if dropped:
                self.dropped += 1
            self._item = Stamped(item, self.clock.monotonic(), self.clock.now(), self.received)
            self._cond.notify()
            return dropped

    def peek(self) -> T | None:
        """The item waiting to be taken, if any, without taking it (for status and tests)."""
        with self._cond:
            return None if self._item is None else self._item.item

    def take(self, timeout_s: float | None = None) -> Stamped[T] | None:
        """The newest untaken item, waiting up to ``timeout_s`` (wall seconds: a poll interval for the
        consumer's own stop check, not a decision); None on timeout or close."""
        with self._cond:
            if self._item is None and not self._closed:
                self._cond.wait(timeout_s)
            item, self._item = self._item, None
            if item is not None:
                self.taken += 1
            return item

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()
