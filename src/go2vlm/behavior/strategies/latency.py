"""How long the object memory's answers take, measured: the stamp of each newer answer (the frame it
was about) against when the memory had it taken in. Pure; the search asks it whether turning on at
some rate would turn past more of the view than it may between two answers."""

from __future__ import annotations

from collections import deque

__all__ = ["Answers"]


class Answers:
    """The newest answer's frame (on the mission's clock) and the latency of the last `keep` answers."""

    def __init__(self, keep: int = 20) -> None:
        self.through: float | None = None  # the newest answer's frame, None before any
        self._latency: deque[float] = deque(maxlen=keep)

    def take(self, answered_through: float | None, now: float) -> None:
        """The memory says it has taken in answers about frames up to `answered_through` (None: none
        yet); only a newer one counts, and adds one latency."""
        if answered_through is not None and (self.through is None or answered_through > self.through):
            self.through = answered_through
            self._latency.append(max(0.0, now - answered_through))

    @property
    def latency(self) -> float | None:
        """The measured answer latency (s): the 80th percentile of the last answers, None before any."""
        if not self._latency:
            return None
        lat = sorted(self._latency)
        return lat[min(len(lat) - 1, int(0.8 * len(lat)))]

    def fast_for(self, rate: float, view: float | None, share: float) -> bool:
        """Turning at `rate` (rad/s) turns at most `share` of the `view` (rad) between two answers;
        an unknown latency or view is not fast."""
        lat = self.latency
        return lat is not None and view is not None and lat * rate <= share * view
