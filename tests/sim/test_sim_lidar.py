"""The sim's ray-cast L1 lidar (sim/lidar.py): it sees walls at their distance, never the robot itself,
and always the floor (so a working sensor never sends an empty cloud)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from go2vlm.geometry.scan import cloud_to_ranges, to_base
from go2vlm.robot_profile.go2 import GO2
from go2vlm.sim import Go2Sim, SimConfig
from go2vlm.sim.lidar import Lidar


def test_lidar_sees_the_wall_ahead_and_the_floor() -> None:
    sim = Go2Sim(SimConfig(world="obstacles", spawn=(3.0, 1.5, 0.0), mode="kinematic"))
    sim.step(10)
    lidar = Lidar(sim.model, sim.model.body("base").id)
    cloud = lidar.scan(sim.data)
    assert len(cloud) > lidar.rays // 4
    base = to_base(cloud, (lidar.mount_r, lidar.mount_t))
    assert (base[:, 2] < -0.25).any()  # floor returns
    s = GO2.scan_spec()
    r = cloud_to_ranges(base, s)
    ahead = int(round(-s.angle_min / s.angle_increment))
    x = sim.state().position[0]
    assert r[ahead] == pytest.approx(4.9 - x, abs=0.03)  # wall_east's face at x = 4.9
    # Nothing within the robot's own body: the nearest return is outside the footprint.
    assert np.min(np.hypot(base[:, 0], base[:, 1])) > GO2.footprint_width / 2
    assert math.isinf(r[0]) or r[0] > 1.0  # behind: open ground for over a metre
