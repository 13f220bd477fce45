"""Plain data returned by :class:`go2vlm.sim.Go2Sim`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Pose:
    position: np.ndarray  # (3,) world, metres
    quaternion: np.ndarray  # (4,) w, x, y, z


@dataclass(frozen=True)
class RobotState:
    time: float
    mode: str
    fell: bool
    position: np.ndarray  # base origin, world
    quaternion: np.ndarray  # w, x, y, z (base -> world)
    lin_vel_world: np.ndarray
    lin_vel_body: np.ndarray
    ang_vel_body: np.ndarray
    ang_vel_world: np.ndarray
    imu_gyro: np.ndarray  # rad/s, IMU frame (= base frame)
    imu_acc: np.ndarray  # m/s^2, specific force (reads +9.81 z at rest)
    imu_rpy: np.ndarray  # roll, pitch, yaw (rad)
    joint_names: tuple[str, ...]
    joint_pos: np.ndarray  # (12,) Unitree order FR, FL, RR, RL x (hip, thigh, calf)
    joint_vel: np.ndarray
    joint_torque: np.ndarray  # applied motor torques, N*m
    foot_names: tuple[str, ...]
    foot_contact: np.ndarray  # (4,) bool
    foot_force: np.ndarray  # (4,) normal contact force, N
    command: np.ndarray  # (3,) clamped vx, vy, vyaw in effect
