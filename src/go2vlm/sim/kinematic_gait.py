"""Kinematic mode: the base follows the command exactly; legs are animated.

No dynamics: the base pose is integrated from (vx, vy, vyaw) and the joint
angles come from a trot foot pattern through inverse kinematics.  Fully
deterministic and cheap, meant for perception tests.
"""

from __future__ import annotations

import numpy as np

from go2vlm.sim import legs
from go2vlm.sim.controller import TROT_OFFSETS
from go2vlm.sim.go2_model import FOOT_RADIUS, HIP_OFFSETS, LEG_SIDE, THIGH_OFFSET


class KinematicGait:
    def __init__(self, period: float = 0.36, duty: float = 0.5, swing_height: float = 0.07) -> None:
        self.period, self.duty, self.swing_height = period, duty, swing_height
        self.phase = 0.0
        self.nominal = HIP_OFFSETS.copy()
        self.nominal[:, 1] += LEG_SIDE * THIGH_OFFSET

    def step(self, dt: float, cmd: np.ndarray, moving: bool) -> None:
        if moving:
            self.phase = (self.phase + dt / self.period) % 1.0
        else:
            self.phase = 0.0

    def joint_positions(self, cmd: np.ndarray, height: float, moving: bool) -> np.ndarray:
        """Joint angles (12,) for the current phase at base height ``height``."""
        feet = self.nominal.copy()
        feet[:, 2] = -height + FOOT_RADIUS
        if moving:
            t_stance = self.duty * self.period
            # Foot velocity relative to the base during stance: -(v + w x r_hip).
            v_hip = np.stack([cmd[0] - cmd[2] * self.nominal[:, 1], cmd[1] + cmd[2] * self.nominal[:, 0]], axis=1)
            stride = v_hip * t_stance
            leg_phase = (self.phase + TROT_OFFSETS) % 1.0
            for i in range(4):
                ph = leg_phase[i]
                if ph < self.duty:
                    u = ph / self.duty
                    feet[i, :2] += stride[i] * (0.5 - u)
                else:
                    u = (ph - self.duty) / (1.0 - self.duty)
                    b = u**2 * (3 - 2 * u)
                    feet[i, :2] += stride[i] * (b - 0.5)
                    feet[i, 2] += self.swing_height * np.sin(np.pi * u)
        return legs.inverse_kinematics(feet).ravel()
