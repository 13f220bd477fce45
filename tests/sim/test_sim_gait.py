"""Dynamic trot: velocity tracking (10 %), start/stop, posture changes, falls."""

from __future__ import annotations

import numpy as np
import pytest
from sim_helpers import mean_velocity

from go2vlm.sim import Go2Sim, SimConfig
from go2vlm.sim import go2_model as gm
from go2vlm.sim.ball import follow_command

SETTLE_S = 2.0
MEASURE_S = 3.0


def _walk(cmd: tuple[float, float, float]) -> tuple[np.ndarray, Go2Sim]:
    sim = Go2Sim(SimConfig(world="empty"))
    sim.advance(0.2)
    sim.set_command(*cmd)
    mean_velocity(sim, SETTLE_S)
    return mean_velocity(sim, MEASURE_S), sim


@pytest.mark.parametrize(
    "cmd",
    [
        (1.0, 0.0, 0.0),
        (0.0, 0.0, 1.5),
        (0.6, 0.0, 0.8),
        # The rest of the sweep in the full suite only: each is 5 s of dynamic physics.
        *(
            pytest.param(c, marks=pytest.mark.slow)
            for c in (
                (-0.5, 0.0, 0.0),
                (0.0, 0.4, 0.0),
                (0.0, -0.4, 0.0),
                (0.0, 0.0, -1.5),
                (0.5, 0.3, 0.0),
                (0.3, -0.2, -0.5),
                (2.0, 0.0, 0.0),
            )
        ),
    ],
)
def test_velocity_tracking(cmd: tuple[float, float, float]) -> None:
    measured, sim = _walk(cmd)
    target = np.array(cmd)
    for axis in range(3):
        if target[axis] != 0.0:
            assert abs(measured[axis] - target[axis]) <= 0.1 * abs(target[axis]), (axis, measured, cmd)
        else:  # an uncommanded axis must stay small relative to the command
            assert abs(measured[axis]) <= 0.05 + 0.05 * np.linalg.norm(target), (axis, measured, cmd)
    s = sim.state()
    assert s.mode == "walking"
    assert np.all(np.abs(s.joint_torque) <= gm.TORQUE_LIMITS + 1e-6)
    assert abs(s.imu_rpy[0]) < 0.3 and abs(s.imu_rpy[1]) < 0.3


def test_start_and_stop() -> None:
    sim = Go2Sim(SimConfig(world="empty"))
    sim.advance(0.3)
    start = sim.state().position.copy()
    sim.set_command(1.0, 0.0, 0.0)
    sim.advance(3.0)
    assert sim.mode == "walking" and not sim.fell
    sim.stop()
    sim.advance(2.0)
    s = sim.state()
    assert s.mode == "standing" and not sim.fell
    assert np.linalg.norm(s.lin_vel_world[:2]) < 0.05
    assert s.position[0] - start[0] > 2.0
    assert abs(s.position[2] - gm.STAND_HEIGHT) < 0.04
    assert np.all(s.foot_contact)


def test_lie_down_and_stand_up() -> None:
    sim = Go2Sim(SimConfig(world="empty"))
    sim.advance(0.3)
    sim.lie_down()
    assert sim.mode == "lying_down"
    sim.advance(2.0)
    s = sim.state()
    assert s.mode == "lying" and s.position[2] < 0.15 and not s.fell
    sim.stand_up()
    sim.advance(2.0)
    s = sim.state()
    assert s.mode == "standing" and not s.fell
    assert abs(s.position[2] - gm.STAND_HEIGHT) < 0.04
    sim.set_command(0.5, 0.0, 0.0)
    sim.advance(1.5)
    assert sim.mode == "walking" and not sim.fell


def test_start_lying_then_stand() -> None:
    sim = Go2Sim(SimConfig(world="empty", start_standing=False))
    sim.advance(0.5)
    assert sim.mode == "lying" and sim.state().position[2] < 0.15
    sim.stand_up()
    sim.advance(2.0)
    assert sim.mode == "standing"


def _advance_until(sim: Go2Sim, modes: tuple[str, ...], limit_s: float) -> None:
    t0 = sim.time
    while sim.mode not in modes and sim.time - t0 < limit_s:
        sim.advance(0.1)


@pytest.mark.parametrize("kick", [(30.0, 0.0, 0.0), (0.0, 25.0, 0.0)])
def test_fall_detection_and_recovery(kick: tuple[float, float, float]) -> None:
    """A violent kick throws it on its back/side: reported as a fall, then it rolls over and stands."""
    sim = Go2Sim(SimConfig(world="empty"))
    sim.advance(0.3)
    sim.push((0.0, 0.0, 0.0), kick)
    sim.advance(2.0)
    s = sim.state()
    assert s.fell and s.mode == "fallen"
    assert np.all(np.abs(s.joint_torque) < 10.0)  # fallen: joints only damped
    assert sim.recovery_stand()
    assert sim.mode == "recovering"
    _advance_until(sim, ("standing", "fallen"), 10.0)
    sim.advance(0.5)
    s = sim.state()
    assert s.mode == "standing" and not s.fell
    assert abs(s.imu_rpy[0]) < 0.1 and abs(s.position[2] - gm.STAND_HEIGHT) < 0.04


def test_small_push_is_absorbed() -> None:
    sim = Go2Sim(SimConfig(world="empty"))
    sim.advance(0.3)
    sim.push((0.6, 0.4, 0.0))
    sim.advance(3.0)
    assert not sim.fell
    assert sim.mode == "standing"


def test_damp_and_recovery_stand() -> None:
    sim = Go2Sim(SimConfig(world="empty"))
    sim.advance(0.3)
    sim.damp()
    sim.advance(2.0)
    s = sim.state()
    assert s.mode == "damped" and s.position[2] < 0.15 and not s.fell
    assert sim.recovery_stand()
    _advance_until(sim, ("standing", "fallen"), 6.0)
    assert sim.mode == "standing" and not sim.fell


@pytest.mark.slow
@pytest.mark.parametrize("cmd", [(1.0, 0.0, 0.0), (0.0, 0.0, 1.5)])
def test_velocity_tracking_500hz_controller(cmd: tuple[float, float, float]) -> None:
    sim = Go2Sim(SimConfig(world="empty", control_decimation=1))
    sim.advance(0.2)
    sim.set_command(*cmd)
    mean_velocity(sim, SETTLE_S)
    measured = mean_velocity(sim, MEASURE_S)
    nz = np.array(cmd) != 0
    assert np.all(np.abs(measured[nz] - np.array(cmd)[nz]) <= 0.1 * np.abs(np.array(cmd)[nz]))


def test_imu_at_rest() -> None:
    sim = Go2Sim(SimConfig(world="empty"))
    sim.advance(0.5)
    s = sim.state()
    assert s.imu_acc[2] == pytest.approx(9.81, abs=0.3)
    assert np.linalg.norm(s.imu_gyro) < 0.05
    assert np.all(s.foot_contact) and s.foot_force.sum() == pytest.approx(15.0 * 9.81, rel=0.1)


def test_follow_moving_ball_with_changing_commands() -> None:
    """A crude ground-truth follower: commands change every 0.1 s, the robot must keep up and stay up."""
    sim = Go2Sim(SimConfig(world="follow_ball", ball_speed=0.5))
    dists = []
    for _ in range(100):
        cmd, dist = follow_command(sim, "red_ball")
        sim.set_command(*cmd)
        sim.advance(0.1)
        assert not sim.fell
        dists.append(dist)
    assert max(dists[30:]) < 1.6
