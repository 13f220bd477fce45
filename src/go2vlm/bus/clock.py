"""A node's clock: the one source of time for stamps and for every elapsed-time decision.

    clock = Clock()                    # wall mode (use_sim_time false)
    clock.now()                        # ROS time for header stamps: seconds since the epoch
    clock.monotonic()                  # time for timeouts, ages and periods: a steady clock
    clock = Clock(sim=True)            # sim mode (use_sim_time true)
    clock.set(12.34)                   # fed by /clock (Node does this) or by the sim's physics
    clock.now() == clock.monotonic() == 12.34

Wall mode: `now()` is `time.time()` and `monotonic()` is `time.monotonic()`, so a wall-clock jump
(NTP, a manual `date`) moves stamps but never fires or stretches a timeout.
Sim mode: both are the newest simulation time received; 0.0 and `started` false until the first
one arrives, as in ROS 2. A sim that restarts sends time backwards: the clock follows (a time jump),
and the node's timers re-anchor (bus/node.py).

Worker threads wait on the clock with `wait_until(t, stop)` / `sleep(dt, stop)` instead of
`Event.wait(seconds)`, so their periods are in the node's time too.
"""

from __future__ import annotations

import threading
import time

__all__ = ["Clock"]

# A sim-mode waiter re-checks its stop event this often (wall seconds): `set()` wakes it on every
# new time, but nothing wakes it when only `stop` is set.
_STOP_POLL_S = 0.05


class Clock:
    """Wall time (steady for elapsed time, epoch for stamps), or simulation time from `set()`."""

    def __init__(self, sim: bool = False) -> None:
        self._sim = bool(sim)
        self._t = 0.0
        self._started = not self._sim
        self._jumps = 0
        self._cond = threading.Condition()

    @property
    def sim(self) -> bool:
        """True with use_sim_time: the time comes from `set()` (/clock), not from the host."""
        return self._sim

    @property
    def started(self) -> bool:
        """Wall mode: always. Sim mode: once the first time has arrived."""
        return self._started

    @property
    def jumps_back(self) -> int:
        """How many times sim time went backwards (a restarted simulator)."""
        return self._jumps

    def now(self) -> float:
        """ROS time in seconds, for stamps: the epoch (wall mode) or sim time (0.0 until started)."""
        return self._t if self._sim else time.time()

    def monotonic(self) -> float:
        """Seconds for elapsed-time decisions: a steady clock (wall mode) or sim time."""
        return self._t if self._sim else time.monotonic()

    def set(self, t: float) -> None:
        """Sim mode: the newest simulation time (seconds). Wakes every `wait_until`."""
        if not self._sim:
            raise RuntimeError("Clock.set: this clock runs on wall time (use_sim_time is false)")
        with self._cond:
            if self._started and t < self._t:
                self._jumps += 1
            self._t = float(t)
            self._started = True
            self._cond.notify_all()

    def wait_until(self, t: float, stop: threading.Event | None = None) -> bool:
        """Block until `monotonic() >= t` or `stop` is set; True when it returned because of `stop`."""
        if not self._sim:
            while True:
                left = t - time.monotonic()
                if left <= 0:
                    return False
                if stop is None:
                    time.sleep(left)
                elif stop.wait(left):
                    return True
        with self._cond:
            while self._t < t or not self._started:
                if stop is not None and stop.is_set():
                    return True
                self._cond.wait(_STOP_POLL_S if stop is not None else None)
        return False

    def sleep(self, dt: float, stop: threading.Event | None = None) -> bool:
        """`wait_until(monotonic() + dt, stop)`."""
        return self.wait_until(self.monotonic() + dt, stop)

    def wake(self) -> None:
        """Wake sim-mode waiters now so they see their stop event (a node shutting down)."""
        with self._cond:
            self._cond.notify_all()

    def __repr__(self) -> str:
        return f"Clock(sim, t={self._t:.6f})" if self._sim else "Clock(wall)"
