"""Model figures, kinematics, worlds and camera conversions (no stepping)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from go2vlm.geometry.camera import PinholeCamera, hfov_to_fovy_deg
from go2vlm.sim import Go2Sim, SimConfig, available_worlds, legs
from go2vlm.sim import go2_model as gm
from go2vlm.sim.worlds import gazebo_rpy_to_xyaxes


@pytest.fixture(scope="module")
def sim() -> Go2Sim:
    return Go2Sim(SimConfig(world="vision_test"))


def test_worlds_available() -> None:
    assert {"vision_test", "follow_ball", "obstacles", "empty"} <= set(available_worlds())


def test_mass_and_limits(sim: Go2Sim) -> None:
    m = sim.model
    base = m.body("base").id
    assert m.body_subtreemass[base] == pytest.approx(15.0, abs=0.3)
    assert np.allclose(m.actuator_ctrlrange[:, 1], gm.TORQUE_LIMITS)
    fr_thigh = m.joint("FR_thigh_joint").id
    rl_thigh = m.joint("RL_thigh_joint").id
    assert m.jnt_range[fr_thigh] == pytest.approx([-1.5708, 3.4907])
    assert m.jnt_range[rl_thigh] == pytest.approx([-0.5236, 4.5379])
    assert m.jnt_range[m.joint("FL_calf_joint").id] == pytest.approx([-2.7227, -0.83776])
    assert m.jnt_range[m.joint("RR_hip_joint").id] == pytest.approx([-1.0472, 1.0472])


def test_leg_kinematics_match_mujoco(sim: Go2Sim) -> None:
    m = sim.model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    q = np.stack([rng.uniform(-0.5, 0.5, 4), rng.uniform(0.2, 1.5, 4), rng.uniform(-2.5, -0.9, 4)], 1)
    d.qpos[3] = 1.0
    for i, name in enumerate(gm.JOINT_NAMES):
        d.qpos[m.jnt_qposadr[m.joint(name).id]] = q.ravel()[i]
    mujoco.mj_kinematics(m, d)
    feet = np.array([d.geom_xpos[m.geom(g).id] for g in gm.FOOT_GEOMS]) - d.qpos[:3]
    assert np.allclose(legs.foot_positions(q), feet, atol=1e-9)
    assert np.allclose(legs.inverse_kinematics(feet), q, atol=1e-9)


def test_gazebo_camera_conversion(sim: Go2Sim) -> None:
    xy = gazebo_rpy_to_xyaxes(0.0, 0.5, 0.8)
    cam = sim.model.camera("world_camera").id
    mat = sim.data.cam_xmat[cam].reshape(3, 3)
    assert np.allclose(mat[:, 0], xy[:3], atol=1e-5)
    assert np.allclose(mat[:, 1], xy[3:], atol=1e-5)
    assert np.allclose(sim.data.cam_xpos[cam], [-5, -5, 3])
    # looks down towards the objects: optical axis (-z) has a negative z component
    assert -mat[2, 2] < 0
    assert sim.model.cam_fovy[cam] == pytest.approx(hfov_to_fovy_deg(1.047, 640, 480), abs=1e-3)


def test_intrinsics() -> None:
    k = PinholeCamera.from_fovy(640, 480, 46.817)
    assert k.cx == 320 and k.cy == 240 and k.fx == k.fy
    hfov = 2 * math.atan(320 / k.fx)
    assert hfov == pytest.approx(1.047, abs=1e-3)


def test_head_camera_pose(sim: Go2Sim) -> None:
    m, d = sim.model, sim.data
    cam = m.camera("head_camera").id
    assert np.allclose(m.cam_pos[cam], gm.HEAD_CAMERA_POS)
    rot = d.xmat[m.body("base").id].reshape(3, 3)
    optical_axis = -d.cam_xmat[cam].reshape(3, 3)[:, 2]
    assert np.allclose(optical_axis, rot[:, 0], atol=1e-9)


def test_state_fields(sim: Go2Sim) -> None:
    s = sim.state()
    assert len(s.joint_names) == 12 and s.joint_pos.shape == (12,)
    assert s.quaternion.shape == (4,) and np.isclose(np.linalg.norm(s.quaternion), 1.0)
    assert s.mode == "standing" and not s.fell
    poses = sim.object_poses()
    assert {"go2", "red_sphere", "green_box", "blue_cylinder"} <= set(poses)
    assert np.allclose(poses["red_sphere"].position, [2, 0, 0.5])


def test_command_clamping(sim: Go2Sim) -> None:
    assert np.allclose(sim.set_command(5.0, -3.0, 9.0), [3.8, -1.0, 4.0])
    assert np.allclose(sim.set_command(-5.0, 0.2, -9.0), [-2.5, 0.2, -4.0])
    sim.stop()


def test_spawn_pose_is_configurable() -> None:
    sim = Go2Sim(SimConfig(world="obstacles", spawn=(1.0, -2.5, 1.2)))
    s = sim.state()
    assert np.allclose(s.position[:2], [1.0, -2.5])
    assert s.imu_rpy[2] == pytest.approx(1.2)
    default = Go2Sim(SimConfig(world="obstacles", mode="kinematic"))
    assert np.allclose(default.state().position[:2], [-3.5, -3.5])
    names = set(default.object_poses())
    assert {"red_ball", "wall_east", "crate_1", "pillar", "green_box"} <= names


def test_walking_into_a_crate_does_not_crash() -> None:
    """Obstacles collide with the robot (it is pushed back or stumbles, but the sim stays sane)."""
    sim = Go2Sim(SimConfig(world="obstacles", spawn=(1.2, -3.0, 1.5708)))
    sim.set_command(0.5, 0.0, 0.0)
    sim.advance(3.0)
    s = sim.state()
    assert np.all(np.isfinite(s.position))
    # the crate at (1.2, -2.0) (half size 0.25) blocks the way: the base does not pass through it
    assert s.position[1] < -2.0
