"""Analytic Go2 leg kinematics (all four legs vectorised, base frame).

Leg joint angles ``q`` are (4, 3) arrays (hip, thigh, calf) in Unitree leg order
FR, FL, RR, RL.  Positions are of the foot centre relative to the base origin.
"""

from __future__ import annotations

import numpy as np

from go2vlm.sim.go2_model import CALF_LEN, HIP_OFFSETS, LEG_SIDE, THIGH_LEN, THIGH_OFFSET

L1 = LEG_SIDE * THIGH_OFFSET  # signed lateral offset per leg
L2, L3 = THIGH_LEN, CALF_LEN


def foot_positions(q: np.ndarray) -> np.ndarray:
    """Foot centres (4, 3) in the base frame."""
    q1, q2, q3 = q[:, 0], q[:, 1], q[:, 2]
    x = -L2 * np.sin(q2) - L3 * np.sin(q2 + q3)
    z = -L2 * np.cos(q2) - L3 * np.cos(q2 + q3)
    c1, s1 = np.cos(q1), np.sin(q1)
    p = np.stack([x, L1 * c1 - z * s1, L1 * s1 + z * c1], axis=1)
    return p + HIP_OFFSETS


def jacobians(q: np.ndarray) -> np.ndarray:
    """d(foot position)/dq per leg, shape (4, 3, 3), base frame."""
    q1, q2, q3 = q[:, 0], q[:, 1], q[:, 2]
    s2, c2 = np.sin(q2), np.cos(q2)
    s23, c23 = np.sin(q2 + q3), np.cos(q2 + q3)
    c1, s1 = np.cos(q1), np.sin(q1)
    z = -L2 * c2 - L3 * c23
    dx2, dx3 = -L2 * c2 - L3 * c23, -L3 * c23
    dz2, dz3 = L2 * s2 + L3 * s23, L3 * s23
    J = np.zeros((4, 3, 3))
    J[:, 0, 1], J[:, 0, 2] = dx2, dx3
    J[:, 1, 0], J[:, 1, 1], J[:, 1, 2] = -L1 * s1 - z * c1, -s1 * dz2, -s1 * dz3
    J[:, 2, 0], J[:, 2, 1], J[:, 2, 2] = L1 * c1 - z * s1, c1 * dz2, c1 * dz3
    return J


def inverse_kinematics(p: np.ndarray) -> np.ndarray:
    """Joint angles (4, 3) placing the feet at ``p`` (4, 3, base frame); knees bend backwards."""
    r = p - HIP_OFFSETS
    px, py, pz = r[:, 0], r[:, 1], r[:, 2]
    yz2 = np.maximum(py**2 + pz**2 - L1**2, 1e-6)
    z = -np.sqrt(yz2)
    q1 = np.arctan2(pz, py) - np.arctan2(z, L1)
    q1 = (q1 + np.pi) % (2 * np.pi) - np.pi
    d2 = px**2 + z**2
    c3 = np.clip((d2 - L2**2 - L3**2) / (2 * L2 * L3), -1.0, 1.0)
    q3 = -np.arccos(c3)
    q2 = np.arctan2(-px, -z) - np.arctan2(L3 * np.sin(q3), L2 + L3 * np.cos(q3))
    return np.stack([q1, q2, q3], axis=1)
