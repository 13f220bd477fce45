"""Where was the robot at stamp t? A small tf buffer of one transform (odom -> base_link), on the
stamps of its samples (sim time or wall time: the node's clock), interpolated between samples.

    history = PoseHistory(horizon_s=30.0)
    history.add(t, x, y, yaw)            # every /odom (or /tf odom -> base_link) sample
    pose = history.at(stamp)             # Pose2D, or PoseUnavailable with a reason

Rules
- Samples come in stamp order; a sample older than the newest is dropped (counted), and a jump back
  by more than the horizon (a restarted simulator) starts the history again.
- `at(t)` interpolates x and y linearly and yaw along the shorter way round between the two samples
  around t. It refuses a stamp older than the oldest sample (`older_than_history`), newer than the
  newest by more than `max_extrapolation_s` (`newer_than_pose`: wait for the pose to catch up), or
  between two samples more than `max_gap_s` apart (`pose_gap`: the robot may have done anything).
- It keeps `horizon_s` of samples (and at most `max_samples`): bounded whatever the rate.

An input stamped newer than the newest pose may wait for it (`PoseWait`): at most `wait_s` after it
arrived, at most `max_items` of them, retried on each new pose.
"""

from __future__ import annotations

import bisect
import math
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Generic, TypeVar

__all__ = ["Pose2D", "PoseHistory", "PoseUnavailable", "PoseWait", "wrap_angle"]

T = TypeVar("T")


def wrap_angle(a: float) -> float:
    """`a` in [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class Pose2D:
    """A planar pose in the world (odometry) frame: x, y (m), yaw (rad)."""

    x: float
    y: float
    yaw: float

    def to_world(self, bx: float, by: float) -> tuple[float, float]:
        """A point in this pose's frame (x forward, y left) -> the world frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return self.x + c * bx - s * by, self.y + s * bx + c * by

    def to_local(self, wx: float, wy: float) -> tuple[float, float]:
        """A world point -> this pose's frame."""
        dx, dy = wx - self.x, wy - self.y
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return c * dx + s * dy, -s * dx + c * dy


class PoseUnavailable(LookupError):
    """No pose for that stamp; `reason` is older_than_history | newer_than_pose | pose_gap | no_pose."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


@dataclass
class PoseHistory:
    horizon_s: float = 30.0
    max_samples: int = 10_000
    max_extrapolation_s: float = 0.05
    max_gap_s: float = 1.0
    counters: Counter[str] = field(default_factory=Counter)

    def __post_init__(self) -> None:
        self._t: list[float] = []
        self._p: list[tuple[float, float, float]] = []

    def __len__(self) -> int:
        return len(self._t)

    @property
    def oldest(self) -> float | None:
        return self._t[0] if self._t else None

    @property
    def newest(self) -> float | None:
        return self._t[-1] if self._t else None

    def add(self, t: float, x: float, y: float, yaw: float) -> bool:
        """One sample; False (counted) when it is not finite or older than the newest."""
        if not all(math.isfinite(v) for v in (t, x, y, yaw)):
            self.counters["bad_poses"] += 1
            return False
        if self._t and t <= self._t[-1]:
            if self._t[-1] - t > self.horizon_s:
                self.counters["restarts"] += 1  # a jump back (a restarted sim): start again
                self.clear()
            else:
                self.counters["out_of_order"] += 1
                return False
        self._t.append(t)
        self._p.append((x, y, wrap_angle(yaw)))
        self._trim()
        return True

    def clear(self) -> None:
        self._t.clear()
        self._p.clear()

    def _trim(self) -> None:
        cut = bisect.bisect_left(self._t, self._t[-1] - self.horizon_s)
        cut = max(cut, len(self._t) - self.max_samples)
        if cut > 0 and (cut > 256 or len(self._t) > self.max_samples):  # amortised: drop in batches
            del self._t[:cut]
            del self._p[:cut]

    def at(self, t: float) -> Pose2D:
        """The pose at stamp `t` (see the module docstring); PoseUnavailable when there is none."""
        if not self._t:
            raise PoseUnavailable("no_pose", "no pose received yet")
        oldest = max(self._t[0], self._t[-1] - self.horizon_s)
        if t < oldest:
            raise PoseUnavailable("older_than_history", f"stamp {t:.3f} is {oldest - t:.2f} s older than the history")
        if t >= self._t[-1]:
            if t - self._t[-1] > self.max_extrapolation_s:
                raise PoseUnavailable("newer_than_pose", f"stamp {t:.3f} is {t - self._t[-1]:.3f} s past the pose")
            return Pose2D(*self._p[-1])
        i = bisect.bisect_right(self._t, t)  # self._t[i-1] <= t < self._t[i]
        t0, t1 = self._t[i - 1], self._t[i]
        if t1 - t0 > self.max_gap_s:
            raise PoseUnavailable("pose_gap", f"no pose between {t0:.3f} and {t1:.3f}")
        a = (t - t0) / (t1 - t0)
        (x0, y0, w0), (x1, y1, w1) = self._p[i - 1], self._p[i]
        return Pose2D(x0 + a * (x1 - x0), y0 + a * (y1 - y0), wrap_angle(w0 + a * wrap_angle(w1 - w0)))


class PoseWait(Generic[T]):
    """Inputs whose pose has not come yet: `pose_for` gives the pose at a stamp, or keeps the input
    (None) while the pose may still come, or raises PoseUnavailable; `due()` hands the kept ones back
    (with when they arrived) for another try after a new pose."""

    def __init__(self, wait_s: float, max_items: int = 16) -> None:
        self.wait_s = wait_s
        self._items: deque[tuple[float, T]] = deque(maxlen=max_items)

    def __len__(self) -> int:
        return len(self._items)

    def pose_for(self, history: PoseHistory, stamp: float, item: T, arrived: float, now: float) -> Pose2D | None:
        try:
            return history.at(stamp)
        except PoseUnavailable as exc:
            if exc.reason in ("newer_than_pose", "no_pose") and now - arrived <= self.wait_s:
                self._items.append((arrived, item))  # the pose will catch up
                return None
            raise

    def due(self) -> list[tuple[float, T]]:
        items = list(self._items)
        self._items.clear()
        return items
