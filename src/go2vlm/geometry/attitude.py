"""The body's pitch over time. The head camera looks down with the body: a Go2 stands 0.8 degrees
nose down and rocks about that as it trots, and a level camera's monocular range of an object 5 m
away read 1.2 m far. Ranging takes the pitch at each frame's stamp from here. Pure, timestamp-driven.

    pitch = PitchHistory(horizon_s=10.0)
    pitch.add(stamp, quat_pitch(w, x, y, z))   # from /odom (or /imu)
    pitch.at(frame_stamp)                      # the nearest sample's; 0.0 (level) before any
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass, field

__all__ = ["PitchHistory"]


@dataclass
class PitchHistory:
    horizon_s: float = 10.0  # samples older than this behind the newest are dropped
    _t: deque[float] = field(default_factory=deque, init=False, repr=False)
    _p: deque[float] = field(default_factory=deque, init=False, repr=False)

    def add(self, t: float, pitch: float) -> bool:
        """One sample (rad, + nose down); False when not finite or not newer than the newest (a stamp
        far older: a restarted clock, and the history starts again)."""
        if not (math.isfinite(t) and math.isfinite(pitch)):
            return False
        if self._t and t <= self._t[-1]:
            if self._t[-1] - t <= self.horizon_s:
                return False
            self._t.clear()
            self._p.clear()
        self._t.append(t)
        self._p.append(pitch)
        while self._t[0] < t - self.horizon_s:
            self._t.popleft()
            self._p.popleft()
        return True

    def at(self, t: float) -> float:
        """The pitch of the sample nearest stamp `t`; 0.0 (level) with none."""
        if not self._t:
            return 0.0
        i = bisect.bisect_left(self._t, t)
        if i == len(self._t) or (i > 0 and t - self._t[i - 1] < self._t[i] - t):
            i -= 1
        return self._p[i]
