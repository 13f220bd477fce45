"""The node runtime: publishers, subscriptions, services, timers, parameters, a clock and logging,
one executor thread per node.

Parameters at runtime: every node serves ROS 2's parameter services (`ros2 param`, `go2vlm param`;
bus/param_services.py) unless made with parameter_services=False (tools). A change of a
`param(..., live=True)` parameter is validated as at start-up, offered to `check_params` (which may
refuse it), then `self.config` becomes the new Config object and `on_params_changed` rebuilds what
the node derived from it, all on the executor thread. Services (`create_service`, bus/service.py)
answer on the executor thread too, like subscription callbacks, and always answer: a handler that
raises gets its caller an error reply with the reason (`service_stats()` counts them).

A subscription callback and the node's timers run on the node's own thread, one at a time, as in
rclpy's single-threaded executor, so node code needs no locks of its own. A callback that raises
is logged (rate-limited) and counted; the node keeps running. Work that takes long (VLM inference)
belongs on a worker thread that the node starts itself, so that the newest message always wins.

Time: every node has a `Clock` (bus/clock.py), `self.clock`, and reads time only through it:
`now()`/`stamp()`/`header()` for stamps, `self.clock.monotonic()` for timeouts and ages. With the
base parameter `use_sim_time` the clock follows `/clock` (rosgraph_msgs/Clock, read best-effort
keep-last 1 so that any publisher matches and only the newest time counts): the executor takes
/clock before the other subscriptions, so callbacks and timers see the newest time.
Timers run on the node's clock: a timer of period p fires once the clock reaches its due time. In
sim mode the executor wakes on each /clock; before the first one arrives time is 0 and timers do not
fire. Rule, in both modes: a timer fires at most once per executor pass; when the clock has passed
more than one due time (a slow pass, a sim at --fast outrunning this node), the missed periods are
skipped (counted in `Timer.skipped`), not fired in a burst, and the timer keeps its phase
(due times stay start + k * period). The first /clock, and a /clock that goes backwards (a restarted
sim), re-anchor every sim-time timer to now + period. `create_timer(..., wall=True)` makes a timer
on the steady wall clock whatever use_sim_time says, for watchdogs that must fire while /clock
stalls (the safety gate's).

Who sent it: `create_subscription(..., with_sender=True)` calls `callback(msg, sender)`, where
`sender` is the writer's `Endpoint` (its DDS GUID and its participant's GUID, from the sample's
publication handle), or None when the writer is already gone. `Subscription.writers()` lists the
writers matched with a subscription now. `discovery_info.directory()` names the node that owns a
GUID, where its process announces it on ros_discovery_info (ours and ROS 2's do).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, fields, is_dataclass
from typing import Any, ClassVar, TypeVar

from cyclonedds.core import GuardCondition, WaitSet
from cyclonedds.util import duration

from go2vlm.bus import discovery_info, domain
from go2vlm.bus.clock import Clock
from go2vlm.bus.endpoints import Publisher, RawSample, RawSubscription, Subscription
from go2vlm.bus.log import Logger
from go2vlm.bus.param_services import ParameterServer
from go2vlm.bus.params import core_params
from go2vlm.bus.qos import QOS_DEFAULT, QOS_SERVICES, QosProfile
from go2vlm.bus.service import Service, SrvType
from go2vlm.bus.topics import CLOCK
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.rcl_interfaces import PARAMETER_SERVICES
from go2vlm.msgs.rosgraph_msgs import Clock as ClockMsg
from go2vlm.msgs.sizes import SizeCaps
from go2vlm.msgs.std_msgs import Header

_PARAMETER_SRVS: frozenset[object] = frozenset(PARAMETER_SERVICES.values())  # every node has these
M = TypeVar("M")
S = TypeVar("S", bound=Subscription[Any])

# Sim times arrive in whole nanoseconds and due times are sums of float periods: a due time within
# this much of the clock counts as reached, so that a 50 ms timer on a 10 ms /clock fires at 0.15 s,
# not at 0.16 s because 0.05 + 0.05 + 0.05 > 0.15 in floating point.
DUE_EPS_S = 1e-6


@dataclass
class NoParams:
    """A node without parameters."""


@dataclass
class Timer:
    period_s: float
    callback: Callable[[], None]
    next_due: float  # on the node's clock (`clock.monotonic()`), or on time.monotonic() when `wall`
    wall: bool = False
    cancelled: bool = False
    skipped: int = 0  # periods skipped because the clock passed more than one due time at once

    def cancel(self) -> None:
        self.cancelled = True

    def advance(self, now: float) -> None:
        """After a call at `now`: the next due time, skipping missed periods but keeping the phase."""
        self.next_due += self.period_s
        if self.next_due <= now + DUE_EPS_S:
            missed = math.floor((now + DUE_EPS_S - self.next_due) / self.period_s) + 1
            self.next_due += missed * self.period_s
            while self.next_due <= now + DUE_EPS_S:  # float rounding
                self.next_due += self.period_s
                missed += 1
            self.skipped += missed

    def due(self, now: float) -> bool:
        return now + DUE_EPS_S >= self.next_due


class Node:
    """Base class of every go2vlm node. Subclasses set `name`, `Config` and build their
    publishers, subscriptions and timers in `__init__`; `close()` releases their own resources."""

    name: ClassVar[str] = "node"
    Config: ClassVar[type] = NoParams
    # True for a node that is itself the source of sim time (the sim): it feeds its clock with
    # `set_sim_time` instead of subscribing to /clock.
    provides_clock: ClassVar[bool] = False

    def __init__(
        self,
        config: Any = None,
        *,
        node_name: str | None = None,
        remap: dict[str, str] | None = None,
        domain_id: int | None = None,
        interface: str | None = None,
        use_sim_time: bool = False,
        parameter_services: bool = True,
    ) -> None:
        self.node_name = node_name or self.name
        self.config = config if config is not None else self.Config()
        self.remap = dict(remap or {})
        self.log = Logger(self.node_name)
        self.clock = Clock(sim=use_sim_time)
        self._clock_started_seen = False  # the executor has seen sim time start (timers re-anchored)
        self._jumps_seen = 0
        self.domain_id = domain.domain_id_from_env() if domain_id is None else domain_id
        self.participant = domain.participant(domain_id, interface)
        self.counters: dict[str, int] = {}
        # Size caps on what the node takes from the bus (msgs/sizes.py): its Config's, where it takes
        # them over (from_core(SizeCaps, ...)), the defaults otherwise.
        self.size_caps = core_params(SizeCaps, self.config) if is_dataclass(self.config) else SizeCaps()
        self._refused_seen: dict[int, int] = {}  # id(subscription) -> its refusals logged
        self.failure: BaseException | None = None  # set by fail(): the node cannot go on
        self.publishers: list[Publisher[Any]] = []
        self.subscriptions: list[Subscription[Any]] = []
        self.services: list[Service[Any, Any]] = []
        self._timers: list[Timer] = []
        self._soon: list[Callable[[], None]] = []  # call_soon: work handed in by other threads
        self._lock = threading.RLock()
        self._waitset = WaitSet(self.participant)
        self._guard = GuardCondition(self.participant)
        self._waitset.attach(self._guard)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        discovery_info.node_added(self)  # so `ros2 node list` sees us
        if use_sim_time and not self.provides_clock:
            # First subscription, so each executor pass takes /clock before anything else.
            CLOCK.subscription(self, self._node_clock_msg)
        # ROS 2's parameter services (~/list_parameters, ~/set_parameters, ...), as every rclcpp node
        # has them; tools (CLI helpers) turn them off as ros2cli does (start_parameter_services=False).
        self.parameter_server = ParameterServer(self) if parameter_services else None

    # -- graph -------------------------------------------------------------------------------
    @property
    def fully_qualified_name(self) -> str:
        """`/follower`: the name ROS 2 tools show (namespace `/`), as announced on ros_discovery_info."""
        return "/" + discovery_info.ros_node_name(self.node_name)

    def resolve(self, topic: str) -> str:
        name = topic if topic.startswith("/") else "/" + topic
        return self.remap.get(name, self.remap.get(topic, name))

    def create_publisher(self, msg_type: type[M], topic: str, qos: QosProfile = QOS_DEFAULT) -> Publisher[M]:
        return self._add_publisher(Publisher(self.participant, msg_type, self.resolve(topic), qos))

    def _add_publisher(self, pub: Publisher[M]) -> Publisher[M]:
        with self._lock:
            self.publishers.append(pub)
        discovery_info.endpoint_added(self, pub.guid, is_reader=False)
        return pub

    def create_subscription(
        self,
        msg_type: type[M],
        topic: str,
        callback: Callable[..., object],
        qos: QosProfile = QOS_DEFAULT,
        *,
        with_sender: bool = False,
    ) -> Subscription[M]:
        """`callback(msg)`; with `with_sender`, `callback(msg, sender)` (see the module docstring)."""
        sub = Subscription(self.participant, msg_type, self.resolve(topic), callback, qos, with_sender=with_sender)
        return self._add_subscription(sub)

    def _add_subscription(self, sub: S) -> S:
        sub.caps = self.size_caps
        with self._lock:
            self.subscriptions.append(sub)
            self._waitset.attach(sub.condition)
        discovery_info.endpoint_added(self, sub.guid, is_reader=True)
        self._wake()
        return sub

    def create_raw_subscription(
        self, msg_type: type, topic: str, callback: Callable[[RawSample], None], qos: QosProfile = QOS_DEFAULT
    ) -> RawSubscription:
        """Like `create_subscription`, but the callback gets the serialized bytes (`RawSample`)."""
        return self._add_subscription(RawSubscription(self.participant, msg_type, self.resolve(topic), callback, qos))

    def destroy_subscription(self, sub: Subscription[Any]) -> None:
        """Delete a subscription. Call it from the node's own thread (a callback or timer)."""
        with self._lock:
            if sub not in self.subscriptions:
                return
            self.subscriptions.remove(sub)
            self._waitset.detach(sub.condition)
        discovery_info.endpoint_removed(self, sub.guid, is_reader=True)
        sub.close()

    def create_service(
        self, srv_type: SrvType[Any, Any], name: str, handler: Callable[[Any], Any], qos: QosProfile = QOS_SERVICES
    ) -> Service[Any, Any]:
        """Serve `name` (`~/x` is `/<node>/x`) over DDS as rmw_cyclonedds_cpp does (bus/service.py);
        `handler(request) -> response` runs on this node's executor thread."""
        full = f"{self.fully_qualified_name}/{name[2:]}" if name.startswith("~/") else name
        svc: Service[Any, Any] = Service(self, srv_type, full if full.startswith("/") else "/" + full, handler, qos)
        # Writer first, then reader, as rmw_cyclonedds creates them.
        self._add_publisher(svc.reply_pub)
        self._add_subscription(svc.request_sub)
        with self._lock:
            self.services.append(svc)
        return svc

    def input_refusals(self) -> dict[str, dict[str, int | str]]:
        """Per topic where samples were dropped for their size (msgs/sizes.py): how many, and why the
        last one was. For the node's status."""
        with self._lock:
            subs = [s for s in self.subscriptions if s.refused]
        counts: dict[str, int] = {}
        last: dict[str, str] = {}
        for s in subs:  # one topic may have several subscriptions (QoS variants): their sum, the newest reason
            counts[s.topic] = counts.get(s.topic, 0) + s.refused
            last[s.topic] = s.last_refusal
        return {t: {"refused": n, "last": last[t]} for t, n in counts.items()}

    def service_stats(self) -> dict[str, dict[str, int | str]]:
        """Per service of this node (parameter services aside): requests answered, error replies
        (a handler that raised: bus/service.py), the last error. For the node's status."""
        with self._lock:
            services = [s for s in self.services if s.srv_type not in _PARAMETER_SRVS]
        return {s.name: s.stats() for s in services}

    def create_timer(self, period_s: float, callback: Callable[[], None], *, wall: bool = False) -> Timer:
        """Call `callback` every `period_s` seconds of the node's clock (sim time with use_sim_time).
        `wall=True`: of the steady wall clock whatever use_sim_time says (watchdogs of a stalled /clock)."""
        if not period_s > 0:
            raise ValueError(f"timer period must be positive, got {period_s}")
        # A wall timer is what it says: wall time even on a sim clock (see the module docstring).
        start = time.monotonic() if wall or not self.clock.sim else self.clock.monotonic()
        timer = Timer(period_s, callback, start + period_s, wall=wall)
        with self._lock:
            self._timers.append(timer)
        self._wake()
        return timer

    # -- time --------------------------------------------------------------------------------
    @property
    def use_sim_time(self) -> bool:
        return self.clock.sim

    def _node_clock_msg(self, msg: ClockMsg) -> None:  # a name no subclass uses for its own /clock
        self.clock.set(msg.clock.to_sec())

    def set_sim_time(self, t: float) -> None:
        """For a node that provides the clock (the sim): its sim time is `t` now. Any thread."""
        self.clock.set(t)
        if self._timers:
            self._wake()  # its sim-time timers may be due

    # -- helpers -----------------------------------------------------------------------------
    def now(self) -> float:
        """ROS time in seconds: the epoch, or sim time with use_sim_time (0.0 until /clock starts)."""
        return self.clock.now()

    def stamp(self, t: float | None = None) -> Time:
        return Time.from_sec(self.now() if t is None else t)

    def header(self, frame_id: str = "", t: float | None = None) -> Header:
        return Header(stamp=self.stamp(t), frame_id=frame_id)

    def count(self, name: str, n: int = 1) -> int:
        self.counters[name] = self.counters.get(name, 0) + n
        return self.counters[name]

    def params(self) -> dict[str, Any]:
        """The node's parameters: its Config's fields, then the base parameters every node has."""
        cfg = self.config
        own = {f.name: getattr(cfg, f.name) for f in fields(cfg)} if is_dataclass(cfg) else {}
        return {**own, "use_sim_time": self.clock.sim}

    # -- parameters at runtime (bus/param_services.py) -------------------------------------------
    def check_params(self, new: Any, changed: frozenset[str]) -> None:
        """Called before a runtime change of the `live` parameters in `changed` is applied, with the
        already validated new Config: raise ValueError to refuse it (the message is the reason the
        caller gets). Override where a rule depends on the current value (the safety gate)."""

    def on_params_changed(self, old: Any, changed: frozenset[str]) -> None:
        """Called on the executor thread right after `self.config` became the new Config: rebuild
        state derived from the parameters in `changed` (override where a node keeps such state)."""

    # -- execution ---------------------------------------------------------------------------
    def call_soon(self, fn: Callable[[], None]) -> None:
        """Run `fn()` on the executor thread at its next pass (after that pass's subscriptions); from
        any thread, e.g. a network link's own loop handing its messages to the node."""
        with self._lock:
            self._soon.append(fn)
        self._wake()

    def _wake(self) -> None:
        self._guard.set(True)

    def _timer_now(self, timer: Timer) -> float:
        # Wall timers, and every timer in wall mode, run on the steady clock (see the module docstring).
        return time.monotonic() if timer.wall or not self.clock.sim else self.clock.monotonic()

    def spin_once(self, timeout_s: float = 0.1) -> None:
        """Wait for data, /clock or the next timer (at most `timeout_s` wall seconds), then run what is due."""
        with self._lock:
            timers = [t for t in self._timers if not t.cancelled]
        wait = timeout_s
        if any(svc.pending for svc in self.services):
            wait = min(wait, 0.01)  # replies waiting for their client's reader to be discovered
        for t in timers:
            if t.wall or not self.clock.sim:
                wait = min(wait, t.next_due - time.monotonic())
            elif self.clock.started and t.due(self.clock.monotonic()):
                wait = 0.0  # due already (a clock fed from another thread); else a /clock wakes us
        if wait > 0:
            self._waitset.wait(duration(seconds=wait))
        self._guard.take()
        with self._lock:
            subs = list(self.subscriptions)
        for sub in subs:
            if self._stop.is_set():
                return
            try:
                msgs = sub.take()
            except Exception as exc:  # malformed bytes from the wire: count, keep going
                self.count("deserialize_errors")
                self.log.throttled("error", 2.0, f"cannot decode a message on {sub.topic}: {exc}")
                continue
            if (new := sub.refused - self._refused_seen.get(id(sub), 0)) > 0:
                self._refused_seen[id(sub)] = sub.refused
                n = self.count("refused_size", new)
                self.log.throttled("error", 2.0, f"dropped a sample on {sub.topic} ({n} so far): {sub.last_refusal}",
                                   key=f"size:{sub.topic}")  # fmt: skip
            for msg in msgs:
                if sub.with_sender:
                    self._call(sub.callback, msg, sub.topic, sub.sender(msg))
                else:
                    self._call(sub.callback, msg, sub.topic)
        for svc in self.services:
            if svc.pending:
                svc.flush()
        with self._lock:
            soon, self._soon = self._soon, []
        for fn in soon:
            try:
                fn()
            except Exception as exc:
                self.count("callback_errors")
                self.log.throttled(
                    "error", 2.0, f"call_soon {fn!r:.60} failed: {type(exc).__name__}: {exc}", key="soon"
                )
        if self.clock.sim:
            self._check_time_jump(timers)
        for t in timers:
            if t.cancelled or (self.clock.sim and not t.wall and not self.clock.started):
                continue  # sim time has not started: sim-time timers wait for the first /clock
            now = self._timer_now(t)
            if t.due(now):
                t.advance(now)  # at most once per pass: missed periods are skipped, not burst
                self._call(t.callback, None, "timer")

    def _check_time_jump(self, timers: list[Timer]) -> None:
        """Re-anchor sim-time timers when sim time starts or goes backwards (a restarted sim)."""
        if not self.clock.started:
            return
        back = self.clock.jumps_back != self._jumps_seen
        if self._clock_started_seen and not back:
            return
        now = self.clock.monotonic()
        if back:
            self.log.warning(f"sim time went back to {now:.3f} s: timers restart from there")
        for t in timers:
            if not t.wall:
                t.next_due = now + t.period_s
        self._clock_started_seen = True
        self._jumps_seen = self.clock.jumps_back

    def _call(self, fn: Callable[..., object], arg: Any, where: str, *more: Any) -> None:
        try:
            fn() if arg is None and where == "timer" else fn(arg, *more)
        except Exception as exc:
            self.count("callback_errors")
            self.log.throttled(
                "error", 2.0, f"callback for {where} failed: {type(exc).__name__}: {exc}", key=f"cb:{where}"
            )

    def fail(self, exc: BaseException) -> None:
        """The node cannot do its job at all (e.g. a model that cannot load at start): from any
        thread, ask whoever runs it to stop. `spin` (go2vlm run) then shuts every node down and
        raises `exc`, which cli/main.py turns into one line and the exit code (2 for a ConfigError)."""
        if self.failure is None:
            self.failure = exc
            self._wake()

    def start(self) -> Node:
        """Run the executor on a background thread."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=f"node:{self.node_name}", daemon=True)
            self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.is_set():
            self.spin_once(0.2)

    def spin(self) -> None:
        """Run the executor on the calling thread until `shutdown()`."""
        self._run()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def close(self) -> None:
        """Release the node's own resources (worker threads, devices). Override as needed."""

    def shutdown(self, timeout_s: float = 2.0) -> None:
        if self._stop.is_set():
            return
        self._stop.set()
        self._wake()
        self.clock.wake()  # worker threads waiting on sim time see their stop events now
        discovery_info.node_removed(self)
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)
        try:
            self.close()
        except Exception as exc:
            self.log.error(f"close failed: {exc}")
        with self._lock:
            for sub in self.subscriptions:
                try:
                    self._waitset.detach(sub.condition)
                except Exception:
                    pass
                sub.close()
            for pub in self.publishers:
                pub.close()
            self.subscriptions.clear()
            self.publishers.clear()
            self.services.clear()
            self._timers.clear()
