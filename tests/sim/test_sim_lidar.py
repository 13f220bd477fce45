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


def scan_ahead(sim: Go2Sim) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The cloud in the base frame, the /scan ranges the sim publishes of it (the band measured from
    the floor with the robot's stance), the bin straight ahead, and how many rays the lidar casts."""
    lidar = Lidar(sim.model, sim.model.body("base").id)
    base = to_base(lidar.scan(sim.data), (lidar.mount_r, lidar.mount_t))
    s = GO2.scan_spec()
    return (
        base,
        cloud_to_ranges(base, s, lidar.stance(sim.data)),
        int(round(-s.angle_min / s.angle_increment)),
        lidar.rays,
    )


def test_lidar_sees_the_wall_ahead_and_the_floor() -> None:
    sim = Go2Sim(SimConfig(world="obstacles", spawn=(3.0, 1.5, 0.0), mode="kinematic"))
    sim.step(10)
    base, r, ahead, rays = scan_ahead(sim)
    assert len(base) > rays // 4
    assert (base[:, 2] < -0.25).any()  # floor returns
    x = sim.state().position[0]
    assert r[ahead] == pytest.approx(4.9 - x, abs=0.03)  # wall_east's face at x = 4.9
    # Nothing within the robot's own body: the nearest return is outside the footprint.
    assert np.min(np.hypot(base[:, 0], base[:, 1])) > GO2.footprint_width / 2
    assert math.isinf(r[0]) or r[0] > 1.0  # behind: open ground for over a metre


@pytest.mark.parametrize("gap", [0.55, 0.8, 1.2])
def test_lidar_keeps_a_table_top_in_the_scan_as_the_robot_comes_near(gap: float) -> None:
    """The household's coffee table (top 0.51 m off the floor, its edge at x = -2.3): facing it from
    `gap` m, the scan ahead ends at the table, not under it at the wall beyond (the rows above the
    horizon; with the +8 row alone, rays passed under it from 1.5 m on)."""
    sim = Go2Sim(SimConfig(world="household", spawn=(-2.3 + gap, 0.2, math.pi), mode="kinematic"))
    sim.step(10)
    base, r, ahead, _ = scan_ahead(sim)
    x = sim.state().position[0]
    assert x + 2.3 == pytest.approx(gap, abs=0.05)  # where it was put, facing the table
    assert r[ahead] <= (x + 2.3) + 0.4, r[ahead - 2 : ahead + 3]  # the edge, or the top just beyond it


@pytest.mark.parametrize("gap", [0.15, 0.25, 0.5, 0.8, 1.1])
def test_lidar_sees_a_low_object_near_the_robot(gap: float) -> None:
    """House 1006's lego brick (0.16 m tall, 0.16 m across, at (6.125, 2.128)), `gap` m ahead of the
    robot's nose, the robot facing it from the north: the scan ahead ends at it. With the lowest row
    at -12 degrees the rays passed over the brick from 0.82 m from the base centre in, the map
    cleared it, and the robot walked over it."""
    bx, by = 6.125, 2.128
    y0 = by + 0.08 + gap + GO2.footprint_length / 2  # the nose `gap` m short of the brick's north face
    sim = Go2Sim(SimConfig(world="house:1006", spawn=(bx, y0, -math.pi / 2), mode="kinematic"))
    sim.step(10)
    base, r, ahead, _ = scan_ahead(sim)
    face = sim.state().position[1] - (by + 0.08)
    assert min(r[ahead - 1 : ahead + 2]) == pytest.approx(face, abs=0.08), r[ahead - 2 : ahead + 3]


@pytest.mark.parametrize("heading", [0.0, -math.pi / 4])
def test_lidar_keeps_a_tray_on_the_floor_in_the_scan_all_the_way_in(heading: float) -> None:
    """House 1004's tray (a 7 cm rim round a 0.3 m square, centre (7.568, 4.841)), the robot facing it
    from 1.4 m to 0.6 m off its centre: the scan ahead ends at the tray at every distance. With low
    rows at -20, -30 and -45 degrees only it flickered out at 0.6, 0.9 and 1.3 m, each free ray
    cleared it from the map, and the robot walked into it (houses 004 at 1ceeeb5)."""
    tx, ty = 7.568, 4.841
    for d in np.arange(1.4, 0.55, -0.1):
        x, y = tx - d * math.cos(heading), ty - d * math.sin(heading)
        sim = Go2Sim(SimConfig(world="house:1004", spawn=(x, y, heading), mode="kinematic"))
        sim.step(2)
        _, r, ahead, _ = scan_ahead(sim)
        p = sim.state().position
        centre = math.hypot(p[0] - tx, p[1] - ty)
        assert min(r[ahead - 2 : ahead + 3]) == pytest.approx(centre, abs=0.22), (centre, r[ahead - 2 : ahead + 3])
