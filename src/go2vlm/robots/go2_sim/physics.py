"""The sim node's physics thread: it steps the `Go2Sim` in chunks, runs what other threads queued for
it (Go2Sim is not thread-safe), applies the node's command, publishes what is due on one sim-time
schedule, and paces sim time against the wall clock.

The schedule is the bus timers' rule (bus/node.py `Timer`): each output is due on a grid of its
period in sim time from the start (0.02, 0.04 ... for 50 Hz, so stamps are whole multiples of the
period), fires at most once per chunk, and skips the periods a long chunk jumped over instead of
bursting them, keeping its phase.

Wall time where it says so: start-up, pacing against the wall (`rtf`, catching up a lag under
CATCH_UP_S, re-anchoring after a longer stall and counting an overrun), the achieved rtf, /sim/status
(2 Hz of wall time) and the viewer are about how fast the host runs the sim.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from go2vlm.bus import Clock, Logger, Timer
from go2vlm.robots.go2_sim.publishers import SimPublishers
from go2vlm.robots.go2_sim.render_thread import RenderThread, Snapshot
from go2vlm.sim import Go2Sim
from go2vlm.sim.odometry_drift import OdometryDrift
from go2vlm.sim.state import RobotState

__all__ = ["CATCH_UP_S", "PhysicsHost", "PhysicsThread"]

# A real-time run that falls behind by less than this catches up (briefly faster than real time),
# so that a short stall (another process, a GC pause) does not lower the real-time factor for good.
CATCH_UP_S = 2.0
STATUS_PERIOD_S = 0.5  # /sim/status, wall time
LOG_PERIOD_S = 10.0  # the progress log line, wall time


def _noop() -> None:
    pass


class PhysicsHost(Protocol):
    """What the physics thread needs of its node (the sim node)."""

    node_name: str
    config: Any  # SimNodeConfig
    clock: Clock
    log: Logger
    sim: Go2Sim
    outputs: SimPublishers
    renderer: RenderThread
    bridge: Any  # UnitreeSimBridge or None
    odometry: OdometryDrift  # what /odom and rt/sportmodestate report of the true state

    def count(self, key: str) -> int: ...

    def now(self) -> float: ...

    def set_sim_time(self, t: float) -> None: ...

    def apply_command(self, sim: Go2Sim) -> None: ...

    def publish_status(self) -> None: ...


class PhysicsThread:
    def __init__(self, node: PhysicsHost) -> None:
        self.node = node
        self.sim: Go2Sim = node.sim
        self._calls: list[Callable[[Go2Sim], None]] = []
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self.stopping = threading.Event()
        self.rtf = 0.0  # achieved, over the last ~2 s of wall time
        self.busy_s = 0.0
        self.state: RobotState | None = None  # the newest state read on this thread
        self.fell_reported = False

    # -- from other threads ------------------------------------------------------------------
    def call(self, fn: Callable[[Go2Sim], None]) -> None:
        """Run `fn(sim)` on the physics thread before the next step."""
        with self._lock:
            self._calls.append(fn)

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=f"{self.node.node_name}:physics", daemon=True)
            self._thread.start()

    def stop(self) -> None:
        self.stopping.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(5.0)

    # -- the thread --------------------------------------------------------------------------
    def _run(self) -> None:
        try:
            self._loop()
        except Exception as exc:
            self.node.count("physics_errors")
            self.node.log.error(f"physics thread stopped: {type(exc).__name__}: {exc}")

    def _schedule(self) -> dict[str, Timer]:
        """The sim-time outputs, each on the bus timers' rule; a camera that is off has none."""
        cfg = self.node.config
        t0 = self.sim.time
        periods = {
            "state": 1.0 / cfg.state_rate_hz,
            "head": 1.0 / cfg.camera_rate_hz if cfg.camera else None,
            "world": 1.0 / cfg.world_camera_rate_hz if "world" in self.node.outputs.cams else None,
            "ground_truth": 1.0 / cfg.ground_truth_rate_hz,
            "lidar": 1.0 / cfg.lidar_rate_hz,
        }
        return {name: Timer(p, _noop, t0 + p) for name, p in periods.items() if p is not None}

    def _due(self, timers: dict[str, Timer], t: float) -> set[str]:
        due = set()
        for name, timer in timers.items():
            if timer.due(t):
                timer.advance(t)
                due.add(name)
        return due

    def _wait_for_cameras(self) -> None:
        deadline = time.monotonic() + 30.0
        renderer = self.node.renderer
        while self.node.outputs.cams and not renderer.ready.wait(0.1) and not self.stopping.is_set():
            if time.monotonic() > deadline:
                self.node.log.warning("the cameras are not ready after 30 s; starting the clock anyway")
                break

    def _loop(self) -> None:
        node, sim, cfg, out = self.node, self.sim, self.node.config, self.node.outputs
        chunk = max(1, int(round(1.0 / (max(cfg.clock_rate_hz, cfg.state_rate_hz) * sim.dt))))
        timers = self._schedule()
        lidar_period = timers["lidar"].period_s
        viewer = _open_viewer(node, sim) if cfg.viewer else None
        next_viewer = 0.0
        self._wait_for_cameras()

        wall0, sim0 = time.monotonic(), sim.time  # pacing reference
        hist: list[tuple[float, float]] = [(wall0, sim0)]
        next_status, next_log = wall0, wall0 + LOG_PERIOD_S
        state = self.state = sim.state()
        reported = state
        while not self.stopping.is_set():
            t_busy = time.perf_counter()
            self._run_calls()
            node.apply_command(sim)
            sim.step(chunk)
            t = sim.time
            if node.clock.sim:
                node.set_sim_time(t)
            stamp_t = node.now()  # sim time with use_sim_time, else the wall clock
            due = self._due(timers, t)
            if "state" in due:
                state = self.state = sim.state()
                reported = node.odometry.reported(state)  # the truth unless odom_drift
                out.state(reported, stamp_t)
            out.sim_clock(t)
            if "head" in due or "world" in due:
                if cfg.fast:  # as fast as the host renders too: every frame due in sim time is drawn
                    node.renderer.wait_idle(self.stopping)
                d = sim.data
                snap = Snapshot(
                    t, stamp_t, d.qpos.copy(), d.mocap_pos.copy(), d.mocap_quat.copy(), "head" in due, "world" in due
                )
                node.renderer.submit(snap)
            if "ground_truth" in due:
                out.ground_truth(stamp_t)
            if "lidar" in due and node.config.lidar:  # live: read each time
                out.lidar_scan(stamp_t, lidar_period)
            if "state" in due and state.fell and not self.fell_reported:
                self.fell_reported = True
                node.log.error(f"the robot fell at sim time {t:.2f} s")
            if node.bridge is not None:
                node.bridge.on_step(reported if "state" in due else None)
            if viewer is not None and time.monotonic() >= next_viewer:
                next_viewer = time.monotonic() + 1 / 60
                if viewer.is_running():
                    viewer.sync()
            self.busy_s += time.perf_counter() - t_busy

            mono = time.monotonic()
            hist.append((mono, t))
            while len(hist) > 2 and mono - hist[0][0] > 2.0:
                hist.pop(0)
            if mono > hist[0][0]:
                self.rtf = (t - hist[0][1]) / (mono - hist[0][0])
            if mono >= next_status:
                next_status = mono + STATUS_PERIOD_S
                if "state" not in due:
                    self.state = sim.state()
                node.publish_status()
            if mono >= next_log:
                next_log = mono + LOG_PERIOD_S
                target = "fast" if cfg.fast else f"target {cfg.rtf:g}"
                node.log.info(f"sim time {t:.1f} s, real-time factor {self.rtf:.2f} ({target}), mode {state.mode}")
            if not cfg.fast:
                lag = wall0 + (t - sim0) / cfg.rtf - mono
                if lag > 0:
                    self.stopping.wait(lag)
                elif lag < -CATCH_UP_S:
                    # Far behind (a stall, a machine too slow): re-anchor instead of a long fast burst.
                    node.count("physics_overruns")
                    wall0, sim0 = mono, t
        if viewer is not None:
            viewer.close()

    def _run_calls(self) -> None:
        with self._lock:
            calls, self._calls = self._calls, []
        for fn in calls:
            try:
                fn(self.sim)
            except Exception as exc:
                self.node.count("physics_call_errors")
                self.node.log.throttled("error", 2.0, f"physics call failed: {type(exc).__name__}: {exc}")


def _open_viewer(node: Any, sim: Go2Sim) -> Any:
    """MuJoCo's passive viewer on the physics thread, or None (no display, no viewer)."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        node.log.error("--viewer needs a display (DISPLAY/WAYLAND_DISPLAY is not set); running headless")
        return None
    try:
        import mujoco.viewer

        return mujoco.viewer.launch_passive(sim.model, sim.data)
    except Exception as exc:
        node.log.error(f"cannot open the MuJoCo viewer ({type(exc).__name__}: {exc}); running headless")
        return None
