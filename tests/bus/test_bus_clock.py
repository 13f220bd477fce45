"""The node clock (bus/clock.py), use_sim_time as a base parameter of every node, and timers on sim
time: they fire when sim time passes their due time, not before sim time starts, once per pass with
missed periods skipped (phase kept), and re-anchor when sim time goes back. Wall timers run on."""

from __future__ import annotations

import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from busutil import wait_for

from go2vlm.bus import BASE_PARAMS, Clock, Node, ParamError, Timer, build_node_config, describe_params, param
from go2vlm.launch.launcher import check_entries, parse_entries
from go2vlm.launch.registry import NODES, make_node, node_class

# -- the clock -------------------------------------------------------------------------------------


def test_wall_clock_is_epoch_for_stamps_and_steady_for_elapsed_time() -> None:
    c = Clock()
    assert not c.sim and c.started
    assert abs(c.now() - time.time()) < 60.0  # epoch seconds
    a = c.monotonic()
    assert c.monotonic() >= a  # steady: never goes back, whatever the wall clock does
    with pytest.raises(RuntimeError):
        c.set(5.0)  # a wall clock is not fed


def test_sim_clock_is_zero_until_set_then_follows_set() -> None:
    c = Clock(sim=True)
    assert c.sim and not c.started and c.now() == 0.0 and c.monotonic() == 0.0
    c.set(12.5)
    assert c.started and c.now() == c.monotonic() == 12.5
    c.set(13.0)
    assert c.now() == 13.0 and c.jumps_back == 0
    c.set(1.0)  # a restarted sim: time follows it, and the jump is counted
    assert c.now() == 1.0 and c.jumps_back == 1


def test_sim_clock_wait_until_wakes_on_time_and_on_stop() -> None:
    c = Clock(sim=True)
    done: list[bool] = []
    waiter = threading.Thread(target=lambda: done.append(c.wait_until(2.0)))
    waiter.start()
    c.set(1.0)
    c.set(2.5)
    waiter.join(10.0)
    assert done == [False], "wait_until returns once sim time passes t"
    stop = threading.Event()
    stopped: list[bool] = []
    waiter = threading.Thread(target=lambda: stopped.append(c.sleep(100.0, stop)))
    waiter.start()
    stop.set()
    waiter.join(10.0)
    assert stopped == [True], "a stop ends a sim-time wait that sim time never ends"


def test_wall_clock_wait_until_returns_at_once_when_due_and_on_stop() -> None:
    c = Clock()
    assert c.wait_until(c.monotonic() - 1.0) is False
    stop = threading.Event()
    stop.set()
    assert c.sleep(100.0, stop) is True


def test_timer_skips_missed_periods_and_keeps_its_phase() -> None:
    t = Timer(0.05, lambda: None, next_due=10.05)
    t.advance(10.05)
    assert t.next_due == pytest.approx(10.10) and t.skipped == 0
    t.advance(10.52)  # the clock jumped over 8 due times (10.10 .. 10.50): one call, no burst
    assert t.next_due == pytest.approx(10.55) and t.skipped == 8
    t.advance(10.55 - 1e-9)  # whole-nanosecond stamps vs float sums: within DUE_EPS_S counts as due
    assert t.next_due == pytest.approx(10.60)


# -- use_sim_time: a base parameter of every node -----------------------------------------------------


@dataclass
class _Cfg:
    gain: float = param(1.0, help="a gain")


def test_use_sim_time_is_split_off_every_node_config() -> None:
    cfg, base = build_node_config(_Cfg, {"gain": "2.5", "use_sim_time": "true"}, node="n")
    assert cfg.gain == 2.5 and base.use_sim_time is True
    cfg, base = build_node_config(_Cfg, {}, node="n")
    assert base.use_sim_time is False
    with pytest.raises(ParamError, match="use_sim_time"):  # the unknown-name error lists it as known
        build_node_config(_Cfg, {"gian": 1.0}, node="n")
    with pytest.raises(ParamError, match="not a bool"):
        build_node_config(_Cfg, {"use_sim_time": "maybe"}, node="n")
    assert "use_sim_time" in BASE_PARAMS
    rows = {r[0]: r for r in describe_params(_Cfg, base=True)}
    assert rows["use_sim_time"][1:3] == ("bool", "False")


@pytest.mark.parametrize("kind", sorted(set(NODES) - {"vlm", "sim", "go2", "video_source"}))
def test_every_light_node_kind_takes_use_sim_time(kind: str) -> None:
    """make_node (go2vlm run, launch, params files) passes it to Node, and params() lists it."""
    if node_class(kind).provides_clock:
        pytest.skip(f"{kind} is a clock source: it publishes /clock, it does not follow it")

    def required() -> dict:  # the recorder needs what to record and a new folder each time
        return {"all": True, "out": str(Path(tempfile.mkdtemp()) / "bag")} if kind == "recorder" else {}

    node = make_node(kind, params={"use_sim_time": True, **required()})
    try:
        assert node.use_sim_time and node.clock.sim and node.params()["use_sim_time"] is True
        assert node.now() == 0.0, "no /clock yet: time is 0"
        assert any(s.topic == "/clock" for s in node.subscriptions)
    finally:
        node.shutdown()
    node = make_node(kind, params=required())
    try:
        assert node.params()["use_sim_time"] is False and not any(s.topic == "/clock" for s in node.subscriptions)
    finally:
        node.shutdown()


def test_heavy_node_kinds_and_launch_files_accept_use_sim_time(tmp_path: Path) -> None:
    required = {"vlm": {"model": "m"}}
    for kind in ("vlm", "sim", "go2", "video_source"):  # configs only: these nodes are heavy to start
        _, base = build_node_config(node_class(kind).Config, {"use_sim_time": True, **required.get(kind, {})}, kind)
        assert base.use_sim_time
    entries = parse_entries([{"node": "follower", "params": {"use_sim_time": True, "rate_hz": 10}}])
    check_entries(entries)
    params_file = tmp_path / "p.yaml"
    params_file.write_text("follower:\n  ros__parameters:\n    use_sim_time: true\n")
    node = make_node("follower", params_file=str(params_file))
    try:
        assert node.use_sim_time
    finally:
        node.shutdown()


# -- timers on sim time ------------------------------------------------------------------------------


class _ClockedNode(Node):
    """A node fed its sim time directly (as the sim feeds itself), so no stray /clock can move it."""

    name = "clock_test"
    provides_clock = True

    def __init__(self) -> None:
        super().__init__(use_sim_time=True)
        self.lock = threading.Lock()
        self.fired: list[float] = []
        self.wall_ticks = 0
        self.timer = self.create_timer(0.05, self._fire)
        self.create_timer(0.01, self._wall, wall=True)

    def _fire(self) -> None:
        with self.lock:
            self.fired.append(self.now())

    def _wall(self) -> None:
        with self.lock:
            self.wall_ticks += 1

    def times(self) -> list[float]:
        with self.lock:
            return [round(t, 6) for t in self.fired]


@pytest.fixture
def clocked() -> Iterator[_ClockedNode]:
    node = _ClockedNode().start()
    yield node
    node.shutdown()


def _step_to(node: _ClockedNode, t: float, expect_fire: bool) -> None:
    node.set_sim_time(t)
    if expect_fire:
        assert wait_for(lambda: round(t, 6) in node.times(), 10.0), (t, node.times())


def _start_at(node: _ClockedNode, t: float) -> None:
    """Sim time (re)starts at `t`: wait until the executor has anchored the timer there."""
    node.set_sim_time(t)
    assert wait_for(lambda: abs(node.timer.next_due - (t + 0.05)) < 1e-9, 10.0), node.timer


def test_sim_time_timers_wait_for_the_clock_then_fire_on_its_due_times(clocked: _ClockedNode) -> None:
    # Wall timers run while sim time has not started; sim-time timers do not.
    assert wait_for(lambda: clocked.wall_ticks >= 20, 10.0)
    assert clocked.times() == []
    # Sim time starts at 10.0: timers are anchored there (first due 10.05), then follow the clock.
    _start_at(clocked, 10.0)
    for i in range(1, 21):  # 10.01 .. 10.20 in 10 ms steps, as the sim publishes /clock
        t = 10.0 + i * 0.01
        _step_to(clocked, t, expect_fire=(i % 5 == 0))
    assert clocked.times() == [10.05, 10.1, 10.15, 10.2], "once per period, at the due times, none between"


def test_sim_time_jumps_skip_periods_without_a_burst_and_back_jumps_re_anchor(clocked: _ClockedNode) -> None:
    _start_at(clocked, 10.0)
    _step_to(clocked, 10.05, expect_fire=True)
    _step_to(clocked, 10.52, expect_fire=True)  # a sim at --fast, or a slow pass: 8 due times at once
    _step_to(clocked, 10.55, expect_fire=True)  # the phase is kept: 10.55, not 10.57
    assert clocked.times() == [10.05, 10.52, 10.55]
    assert clocked.timer.skipped == 8
    _start_at(clocked, 3.0)  # the sim restarted: timers restart from 3.0
    _step_to(clocked, 3.05, expect_fire=True)
    assert clocked.times()[-1] == 3.05 and clocked.clock.jumps_back == 1
