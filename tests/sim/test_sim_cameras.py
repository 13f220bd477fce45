"""Rendering: head camera sees the ball but never the robot; world camera sees the objects."""

from __future__ import annotations

import numpy as np
import pytest

from go2vlm.sim import Go2Sim, SimConfig


def _mask(img: np.ndarray, channel: int) -> np.ndarray:
    """Pixels where ``channel`` clearly dominates (saturated primary colours)."""
    f = img.astype(np.int32)
    others = [c for c in range(3) if c != channel]
    return (
        (f[:, :, channel] > 120)
        & (f[:, :, channel] > 2 * f[:, :, others[0]] + 20)
        & (f[:, :, channel] > 2 * f[:, :, others[1]] + 20)
    )


def _centroid(mask: np.ndarray) -> np.ndarray:
    ys, xs = np.nonzero(mask)
    return np.array([xs.mean(), ys.mean()])


def test_head_frame_shape_and_default_size() -> None:
    # One config for the sim and its node: the default head camera is the node's 640x480.
    assert (SimConfig().camera_width, SimConfig().camera_height) == (640, 480)
    with Go2Sim(SimConfig(world="follow_ball", mode="kinematic", camera_width=1280, camera_height=720)) as sim:
        img = sim.render_head()
        assert img.shape == (720, 1280, 3) and img.dtype == np.uint8
        small = sim.render_head(320, 240)
        assert small.shape == (240, 320, 3)
        k = sim.head_intrinsics(320, 240)
        assert (k.cx, k.cy) == (160.0, 120.0)


@pytest.mark.parametrize("mode", ["kinematic", "dynamic"])
def test_head_camera_sees_red_ball(mode: str) -> None:
    with Go2Sim(SimConfig(world="follow_ball", mode=mode, camera_width=320, camera_height=180)) as sim:
        sim.advance(0.2)
        img = sim.render_head()
        red = _mask(img, 0)
        assert red.sum() > 200
        # ball is ahead on the optical axis at start: roughly centred horizontally
        assert abs(_centroid(red)[0] - 160) < 40


def test_ball_moves_at_configured_speed() -> None:
    with Go2Sim(SimConfig(world="follow_ball", mode="kinematic", ball_speed=0.5)) as sim:
        p0 = sim.object_poses()["red_ball"].position.copy()
        sim.advance(1.0)
        p1 = sim.object_poses()["red_ball"].position
        assert np.linalg.norm(p1 - p0) == pytest.approx(0.5, rel=0.02)


def test_head_camera_never_sees_robot() -> None:
    """Empty world, walking fast with large leg swings: no robot geom in the head image."""
    with Go2Sim(SimConfig(world="empty", camera_width=320, camera_height=180)) as sim:
        robot = sim.robot_geom_ids()
        sim.advance(0.2)
        sim.set_command(1.0, 0.0, 0.5)
        for _ in range(6):
            sim.advance(0.07)
            seg = sim.render_head_segmentation()
            assert not np.isin(seg, robot).any()
            img = sim.render_head()
            # ground and sky are unsaturated greys/blues; the robot's black parts would show as dark pixels
            assert (img.max(axis=2) < 60).sum() == 0


def test_world_camera_sees_three_objects() -> None:
    with Go2Sim(SimConfig(world="vision_test", mode="kinematic")) as sim:
        img = sim.render_world_camera()
        assert img.shape == (480, 640, 3)
        red, green, blue = (_mask(img, c) for c in range(3))
        assert red.sum() > 500 and green.sum() > 500 and blue.sum() > 500
        # seen from (-5, -5): blue cylinder left of the red sphere, green box behind (higher in image)
        assert _centroid(blue)[0] < _centroid(red)[0]
        assert _centroid(green)[1] < _centroid(blue)[1]


def test_projection_matches_rendered_ball() -> None:
    with Go2Sim(SimConfig(world="follow_ball", mode="kinematic", camera_width=320, camera_height=240)) as sim:
        sim.set_command(0.2, 0.0, 0.3)  # turn a little so the ball is off-centre
        sim.advance(0.8)
        ball = sim.object_poses()["red_ball"].position
        uv, in_front = sim.project_to_head(ball)
        assert in_front[0]
        centre = _centroid(_mask(sim.render_head(), 0))
        assert np.linalg.norm(uv[0] - centre) < 6.0
        # optical frame: z axis of the camera is the robot's forward axis
        pose = sim.head_camera_pose()
        assert pose.position.shape == (3,) and np.isclose(np.linalg.norm(pose.quaternion), 1.0)
