"""Shared measurement helpers for the sim tests."""

from __future__ import annotations

import numpy as np

from go2vlm.sim import Go2Sim


def heading_frame_velocity(sim: Go2Sim) -> np.ndarray:
    """(vx, vy, vyaw) of the base in its yaw (heading) frame."""
    s = sim.state()
    yaw = s.imu_rpy[2]
    c, sn = np.cos(yaw), np.sin(yaw)
    v = s.lin_vel_world
    return np.array([c * v[0] + sn * v[1], -sn * v[0] + c * v[1], s.ang_vel_world[2]])


def mean_velocity(sim: Go2Sim, duration: float, every: int = 5) -> np.ndarray:
    """Average heading-frame velocity over ``duration`` seconds of simulation."""
    samples = []
    steps = int(round(duration / sim.dt))
    for i in range(steps):
        sim.step()
        assert not sim.fell, f"fell at t={sim.time:.2f}"
        if i % every == 0:
            samples.append(heading_frame_velocity(sim))
    return np.mean(samples, axis=0)
