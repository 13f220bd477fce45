"""Kinematic mode: exact command integration and determinism."""

from __future__ import annotations

import numpy as np
import pytest

from go2vlm.sim import Go2Sim, SimConfig


def _run() -> Go2Sim:
    sim = Go2Sim(SimConfig(world="follow_ball", mode="kinematic"))
    sim.set_command(0.5, 0.1, 0.3)
    sim.advance(2.0)
    sim.set_command(-0.3, 0.0, -0.2)
    sim.advance(1.0)
    return sim


def test_deterministic() -> None:
    a, b = _run(), _run()
    assert np.array_equal(a.data.qpos, b.data.qpos)
    assert np.array_equal(a.data.mocap_pos, b.data.mocap_pos)


def test_straight_line_matches_command() -> None:
    sim = Go2Sim(SimConfig(world="vision_test", mode="kinematic", spawn=(0.0, 0.0, 0.0)))
    sim.set_command(0.8, 0.0, 0.0)
    sim.advance(2.5)
    s = sim.state()
    assert s.position[0] == pytest.approx(2.0, abs=1e-6)
    assert s.mode == "walking"
    assert np.allclose(s.lin_vel_body, [0.8, 0.0, 0.0], atol=1e-6)
    # legs really move (animated gait), feet alternate contact
    assert np.ptp(s.joint_pos) > 0.5
    assert 0 < s.foot_contact.sum() < 4


def test_yaw_integration_and_postures() -> None:
    sim = Go2Sim(SimConfig(world="vision_test", mode="kinematic", spawn=(0.0, 0.0, 0.0)))
    sim.set_command(0.0, 0.0, 1.0)
    sim.advance(1.0)
    assert sim.state().imu_rpy[2] == pytest.approx(1.0, abs=1e-6)
    sim.lie_down()
    sim.advance(2.0)
    assert sim.mode == "lying" and sim.state().position[2] < 0.15
    sim.stand_up()
    sim.advance(1.5)
    assert sim.mode == "standing" and not sim.fell
