"""A look: hold still until an answer about a frame taken since the stop has come back. Shared by
the remembered-place navigation and the stop-and-look search (one look at a time: a new `key`, what
is looked at, starts a new one). Pure, timestamp-driven."""

from __future__ import annotations

import math

__all__ = ["Look"]


class Look:
    def __init__(self) -> None:
        self.key: object = None  # what the current look is for (None: no look)
        self.still_since = math.inf  # frames from this time on are taken at the current heading

    def forget(self) -> None:
        """The robot moves (or looks elsewhere): the next look waits for a newer frame."""
        self.key = None

    def check(
        self, key: object, now: float, *, settle_s: float, timeout_s: float, answered: float | None,
        latency: float | None,
    ) -> str:  # fmt: skip
        """'waiting' until an answer about a frame taken `settle_s` after the stop has come back
        ('answered': `answered` is the newest answer's frame), or 'timeout': `timeout_s` before any
        answer latency is known, else 2.5 x the latency + 1 s."""
        if key != self.key:
            self.key = key
            self.still_since = now + settle_s
        if answered is not None and answered >= self.still_since:
            return "answered"
        limit = timeout_s if latency is None else 2.5 * latency + 1.0
        return "timeout" if now - self.still_since > limit else "waiting"
