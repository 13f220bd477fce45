"""How a slow grounding model delivers its answers, without I/O: it looks at one frame at a time (the
newest when it is free), and its answer about that frame comes `latency_s` after the frame's stamp;
frames that arrive while it is busy are never looked at. Driven by the frames' stamps only.

    delay = AnswerDelay(latency_s=2.5)
    for stamp, answer in frames:            # e.g. the sim's ground-truth boxes of every head frame
        for out in delay.offer(stamp, answer):
            publish(out)                    # an answer about an older frame, with that frame's stamp

Answers come out when a later frame arrives whose stamp has reached the due time, so with a 10 Hz
camera they are late by up to one frame period more than `latency_s` (as a real model's would be seen
by a 10 Hz consumer). When answers arrive seldom (a real model's, held back), `due(now)` lets the
caller's clock release them instead.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Generic, TypeVar

__all__ = ["AnswerDelay"]

T = TypeVar("T")


@dataclass
class AnswerDelay(Generic[T]):
    latency_s: float
    busy: tuple[float, T] | None = None  # (frame stamp, its answer) being "inferred"
    counters: Counter[str] = field(default_factory=Counter)

    def __post_init__(self) -> None:
        if not self.latency_s >= 0.0:
            raise ValueError(f"latency_s must be >= 0, got {self.latency_s}")

    def offer(self, stamp: float, answer: T) -> list[tuple[float, T]]:
        """A new frame (its stamp and the answer a perfect model would give about it): the answers now
        due, oldest first (at most one), then this frame is taken if the model is free."""
        out = self.due(stamp)
        if self.busy is None:
            self.busy = (stamp, answer)
            self.counters["taken"] += 1
        else:
            self.counters["skipped"] += 1  # arrived while the model was busy
        return out

    def due(self, now: float) -> list[tuple[float, T]]:
        """The answer held back, if `now` has reached its due time (at most one)."""
        if self.busy is None or now + 1e-9 < self.busy[0] + self.latency_s:
            return []
        out, self.busy = [self.busy], None
        self.counters["answered"] += 1
        return out
