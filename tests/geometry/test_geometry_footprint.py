"""A mesh's floor footprint is its convex hull (what MuJoCo collides), not its bounding box: the
episodes' collisions and clearances, and the distance to a target's surface, are measured to it."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.geometry.footprint import Footprint, clearance, hull_distance, hull_outline, surface_distance
from go2vlm.robot_profile.go2 import FOOTPRINT_LENGTH, FOOTPRINT_WIDTH

DIAMOND = ((0.2, 0.0), (0.0, 0.2), (-0.2, 0.0), (0.0, -0.2))  # counter-clockwise


def diamond(x: float = 0.0, y: float = 0.0, yaw: float = 0.0) -> Footprint:
    return Footprint("hull", x, y, yaw, hx=0.2, hy=0.2, pts=DIAMOND)


@settings(max_examples=80, deadline=None)
@given(x=st.floats(-1.0, 1.0), y=st.floats(-1.0, 1.0), yaw=st.floats(-math.pi, math.pi))
def test_the_distance_to_a_hull_is_the_distance_to_its_nearest_edge(x: float, y: float, yaw: float) -> None:
    """Against a dense sampling of the outline, with the sign of inside (the diamond |u| + |v| < 0.2)."""
    sh = diamond(0.3, -0.1, yaw)
    verts = hull_outline(sh)
    f = np.linspace(0.0, 1.0, 400, endpoint=False)[:, None]
    dense = np.concatenate([a + f * (b - a) for a, b in zip(verts, np.roll(verts, -1, axis=0), strict=True)])
    d = float(hull_distance(np.array(x), np.array(y), verts))
    near = float(np.hypot(dense[:, 0] - x, dense[:, 1] - y).min())
    c, s = math.cos(yaw), math.sin(yaw)
    u, v = c * (x - 0.3) + s * (y + 0.1), -s * (x - 0.3) + c * (y + 0.1)
    inside = abs(u) + abs(v) < 0.2
    assert abs(abs(d) - near) < 2e-3
    assert (d < 0) == inside or abs(d) < 1e-6
    assert surface_distance(x, y, sh) == d


def test_a_robot_beside_a_hulls_bounding_box_corner_is_clear_of_it() -> None:
    """The robot's corner inside the diamond's bounding box, where the diamond is not: no overlap, and
    the gap is the corner's distance to the diamond's edge; pushed into the diamond, an overlap."""
    corner = (0.15, 0.15)  # in the box (|x|, |y| <= 0.2), outside the diamond (0.3 > 0.2)
    robot = Footprint.rect(corner[0] + FOOTPRINT_LENGTH / 2, corner[1] + FOOTPRINT_WIDTH / 2, 0.0,
                           FOOTPRINT_LENGTH, FOOTPRINT_WIDTH)  # fmt: skip
    box = Footprint("rect", 0.0, 0.0, 0.0, hx=0.2, hy=0.2)
    assert clearance(robot, box) < 0
    gap = clearance(robot, diamond())
    assert abs(gap - (0.3 - 0.2) / math.sqrt(2)) < 0.01, gap
    pushed = Footprint.rect(0.05 + FOOTPRINT_LENGTH / 2, 0.05 + FOOTPRINT_WIDTH / 2, 0.0, FOOTPRINT_LENGTH,
                            FOOTPRINT_WIDTH)  # fmt: skip
    assert clearance(pushed, diamond()) < 0


def test_a_household_mesh_is_footprinted_by_its_hull() -> None:
    """The houses' teddy bear: its hull lies within its bounding box and covers about two thirds of it."""
    from go2vlm.sim.worlds import world_footprints, world_model

    sh = world_footprints(world_model("house:1040")[0])["teddy_bear"]
    assert sh.kind == "hull" and len(sh.pts) >= 3
    v = np.asarray(sh.pts)
    assert (np.abs(v[:, 0]) <= sh.hx + 1e-9).all() and (np.abs(v[:, 1]) <= sh.hy + 1e-9).all()
    area = 0.5 * abs(float(np.dot(v[:, 0], np.roll(v[:, 1], -1)) - np.dot(v[:, 1], np.roll(v[:, 0], -1))))
    assert 0.4 < area / (4 * sh.hx * sh.hy) < 0.95
