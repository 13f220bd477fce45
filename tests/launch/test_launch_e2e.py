"""Acceptance: the follow pipeline (the VLM article's test pattern, section 3.3, then the follow article's
colour detector and follower, sections 5.2/5.3, then the safety gate) as four real processes over real DDS.

test_pattern -> color_detector -> follower -> safety -> /cmd_vel, observed by an in-process probe.
Deadlines are measured from the event (just before the kill / publish) to the probe's receipt of
the first all-zero /cmd_vel, so they include DDS delivery to the probe; no extra slack is added.
"""

from __future__ import annotations

import json
import time

import pytest
from busutil import wait_for
from pipeutil import Probe, is_zero, logs_tail, start, wait_settled, wait_up

from go2vlm.msgs.std_msgs import Bool, String

# Slow: the whole pipeline as four processes, started and stopped per test.
pytestmark = pytest.mark.slow


def _status(probe: Probe) -> dict:
    msgs = probe.status.msgs()
    assert msgs, "no /safety/status received"
    return json.loads(msgs[-1].data)


def test_camera_first_settles_then_estop_latches_until_release(procs, probe, tmp_path) -> None:
    start(procs, "test_pattern", tmp_path)
    wait_up(lambda: len(probe.images) > 0, "camera")
    start(procs, "color_detector", tmp_path)
    wait_up(lambda: len(probe.targets) > 0, "color_detector")
    start(procs, "follower", tmp_path)
    wait_up(lambda: probe.follower_sub.publisher_count > 0, "follower")
    start(procs, "safety", tmp_path)
    try:
        wait_settled(probe)
    except AssertionError:
        raise AssertionError(logs_tail(tmp_path)) from None
    target = probe.targets.msgs()[-1]
    assert target.header.frame_id == "camera"
    assert target.point.x == pytest.approx(0.40625, abs=0.005)
    assert target.point.z == pytest.approx(0.25, abs=0.01)

    # E-stop: from the first zero after it on, every /cmd_vel is exactly zero, and the output keeps
    # going (a latched gate publishes zero at its rate; it does not fall silent).
    t_estop = time.monotonic()
    probe.estop_pub.publish(Bool(data=True))
    assert wait_for(lambda: probe.first_zero_after(t_estop) is not None, 5.0), "no zero /cmd_vel after the e-stop"
    first_zero = probe.first_zero_after(t_estop)
    print(f"e-stop -> first zero /cmd_vel: {first_zero:.3f} s")
    assert wait_for(lambda: _status(probe)["estop"] is True, 5.0)
    # `false` and a wrong token do not release it.
    probe.estop_pub.publish(Bool(data=False))
    probe.release_pub.publish(String(data="please"))
    assert wait_for(lambda: _status(probe)["counters"].get("release_refused", 0) >= 1, 5.0)
    assert wait_for(lambda: len(probe.items_after(t_estop + first_zero)) >= 40, 10.0), "the latched gate fell silent"
    held = probe.items_after(t_estop + first_zero)
    assert all(is_zero(m) for _, m in held), [m for _, m in held if not is_zero(m)][:3]
    st = _status(probe)
    assert st["last_zero_reason"] == "estop" and st["active"] is None
    assert st["counters"].get("release_refused", 0) >= 1

    # The documented release resumes the loop.
    t_release = time.monotonic()
    probe.release_pub.publish(String(data="RELEASE"))
    assert wait_for(lambda: any(not is_zero(m) for _, m in probe.items_after(t_release)), 3.0), "no resume"
    wait_settled(probe, timeout=5.0)
    assert wait_for(lambda: _status(probe)["estop"] is False, 5.0)


def test_reverse_start_order_safety_first_camera_last(procs, probe, tmp_path) -> None:
    start(procs, "safety", tmp_path)
    wait_up(lambda: len(probe.cmd) >= 5, "safety")
    assert all(is_zero(m) for m in probe.cmd.msgs()), "the gate must output zero while no input is live"
    start(procs, "follower", tmp_path)
    wait_up(lambda: probe.follower_sub.publisher_count > 0, "follower")
    start(procs, "color_detector", tmp_path)
    wait_up(lambda: probe.targets_sub.publisher_count > 0, "color_detector")
    time.sleep(0.5)
    assert all(is_zero(m) for m in probe.cmd.msgs()), "nothing may move before there is a camera"
    start(procs, "test_pattern", tmp_path)
    try:
        wait_settled(probe)
    except AssertionError:
        raise AssertionError(logs_tail(tmp_path)) from None


def _pipeline(procs, probe, tmp_path) -> dict:
    ps = {kind: start(procs, kind, tmp_path) for kind in ("safety", "follower", "color_detector", "test_pattern")}
    try:
        wait_settled(probe)
    except AssertionError:
        raise AssertionError(logs_tail(tmp_path)) from None
    return ps


def test_camera_stop_zeroes_cmd_vel_within_1_1_s(procs, probe, tmp_path) -> None:
    ps = _pipeline(procs, probe, tmp_path)
    t_stop = time.monotonic()
    ps["test_pattern"].kill()
    assert wait_for(lambda: probe.first_zero_after(t_stop) is not None, 3.0), "no zero /cmd_vel after camera stop"
    dt = probe.first_zero_after(t_stop)
    print(f"camera stop -> first zero /cmd_vel: {dt:.3f} s")
    assert dt is not None and dt <= 1.1, f"camera stopped, first zero /cmd_vel after {dt:.3f} s (> 1.1 s)"
    time.sleep(0.5)
    after = probe.items_after(t_stop + dt)
    assert all(is_zero(m) for _, m in after), "the robot must stay stopped while the camera is gone"


def test_follower_killed_zeroes_cmd_vel_within_0_6_s(procs, probe, tmp_path) -> None:
    ps = _pipeline(procs, probe, tmp_path)
    t_kill = time.monotonic()
    ps["follower"].kill()
    assert wait_for(lambda: probe.first_zero_after(t_kill) is not None, 3.0), "no zero /cmd_vel after the kill"
    dt = probe.first_zero_after(t_kill)
    print(f"follower killed -> first zero /cmd_vel: {dt:.3f} s")
    assert dt is not None and dt <= 0.6, f"follower killed, first zero /cmd_vel after {dt:.3f} s (> 0.6 s)"
    time.sleep(0.5)
    assert all(is_zero(m) for _, m in probe.items_after(t_kill + dt))
    st = _status(probe)
    assert st["active"] is None and "follower" in st["last_zero_reason"]
