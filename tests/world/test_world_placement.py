"""A grounded box lands in the world where the object is, at the pose of the frame it describes,
however the robot has moved since (world/placement.py over world/poses.py)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from worldutil import CAM, MOUNT, cylinder_box, cylinder_scan

from go2vlm.perception.ranging import RangeEstimator
from go2vlm.world.placement import PlacementError, check_box, place
from go2vlm.world.poses import Pose2D, PoseHistory

R, H = 0.3, 1.5  # the vision_test world's blue cylinder


def ranger() -> RangeEstimator:
    return RangeEstimator("cylinder", camera_height=MOUNT.height_m, default_sizes={"cylinder": R})


poses = st.builds(Pose2D, st.floats(-5, 5), st.floats(-5, 5), st.floats(-math.pi, math.pi))


def _object_in_view(pose: Pose2D, dist: float, bearing: float) -> tuple[float, float]:
    cx, cy = pose.to_world(MOUNT.forward_m, MOUNT.left_m)
    return cx + dist * math.cos(pose.yaw + bearing), cy + dist * math.sin(pose.yaw + bearing)


@settings(max_examples=200, deadline=None)
@given(pose=poses, dist=st.floats(1.0, 6.0), bearing=st.floats(-0.5, 0.5))
def test_a_box_lands_on_the_object(pose: Pose2D, dist: float, bearing: float) -> None:
    obj = _object_in_view(pose, dist, bearing)
    box = cylinder_box(pose, obj, R, H)
    assume(box is not None)
    p = place("blue cylinder", box, 7.0, pose, CAM, MOUNT, ranger())
    assert p.method == "bottom"
    assert math.hypot(p.x - obj[0], p.y - obj[1]) < 0.01
    assert p.size[0] == pytest.approx(2 * R, abs=0.05) and p.size[2] == pytest.approx(H, abs=0.05)


@settings(max_examples=200, deadline=None)
@given(pose=poses, dist=st.floats(1.0, 5.0), bearing=st.floats(-0.5, 0.5), turn=st.floats(-20, 20),
       late=st.floats(0.05, 20.0), walk=st.floats(0.0, 0.5))  # fmt: skip
def test_turning_after_the_frame_changes_nothing(
    pose: Pose2D, dist: float, bearing: float, turn: float, late: float, walk: float
) -> None:
    """The robot turns by any angle (and walks) after the frame; the answer, placed at the pose of its
    frame's stamp, lands in the same world place as one placed at once."""
    obj = _object_in_view(pose, dist, bearing)
    box = cylinder_box(pose, obj, R, H)
    assume(box is not None)
    history = PoseHistory(horizon_s=60.0)
    t_frame = 100.0
    history.add(t_frame - 1.0, pose.x, pose.y, pose.yaw)
    history.add(t_frame, pose.x, pose.y, pose.yaw)
    steps = 100
    for k in range(1, steps + 1):  # then: turn by `turn` rad and walk, over `late` seconds
        a = k / steps
        yaw = pose.yaw + a * turn
        history.add(t_frame + a * late, pose.x + a * walk * math.cos(yaw), pose.y + a * walk * math.sin(yaw), yaw)
    now = place("blue cylinder", box, t_frame, pose, CAM, MOUNT, ranger())
    later = place("blue cylinder", box, t_frame, history.at(t_frame), CAM, MOUNT, ranger())
    assert (later.x, later.y) == pytest.approx((now.x, now.y), abs=1e-6)
    assert math.hypot(later.x - obj[0], later.y - obj[1]) < 0.01


@settings(max_examples=100, deadline=None)
@given(pose=poses, dist=st.floats(1.0, 6.0), bearing=st.floats(-0.5, 0.5), bias=st.floats(0.6, 1.6))
def test_the_lidar_ranges_where_it_covers_the_box(pose: Pose2D, dist: float, bearing: float, bias: float) -> None:
    """A scan at the frame's stamp that covers the box's bearings ranges it (cm), even when the
    monocular reading is off (the ranger told a wrong size, the box's bottom cut off)."""
    obj = _object_in_view(pose, dist, bearing)
    box = cylinder_box(pose, obj, R, H)
    assume(box is not None)
    scan = cylinder_scan(pose, obj, R)
    p = place("blue cylinder", box, 1.0, pose, CAM, MOUNT, ranger(), scan)
    assert p.method == "lidar"
    assert math.hypot(p.x - obj[0], p.y - obj[1]) < 0.05
    cut = (box[0], box[1], box[2], CAM.height - 1.0)  # bottom out of the picture: size ranging
    wrong = RangeEstimator("cylinder", camera_height=MOUNT.height_m, default_sizes={"cylinder": R * bias})
    q = place("blue cylinder", cut, 1.0, pose, CAM, MOUNT, wrong, scan)
    if q.method == "lidar":
        assert math.hypot(q.x - obj[0], q.y - obj[1]) < 0.05 + abs(bias - 1) * R


def test_a_scan_return_outside_the_box_is_not_its_range() -> None:
    pose = Pose2D(0, 0, 0)
    obj = _object_in_view(pose, 3.0, 0.0)
    box = cylinder_box(pose, obj, R, H)
    assert box is not None
    wall = np.array([[1.0, -2.0], [1.0, 2.0]])  # beside the box's bearings
    p = place("blue cylinder", box, 1.0, pose, CAM, MOUNT, ranger(), wall)
    assert p.method == "bottom"


@pytest.mark.parametrize(
    "box",
    [
        (math.nan, 1, 2, 3),
        (1, 2, math.inf, 4),
        (10, 10, 5, 20),
        (0, 0, 5000, 5000),
        (700, 10, 800, 50),
        (1, 1, 1.5, 1.5),
    ],
)
def test_bad_boxes_are_refused(box: tuple[float, float, float, float]) -> None:
    with pytest.raises(PlacementError) as e:
        check_box(box, CAM)
    assert e.value.reason == "bad_box"


def test_a_box_without_a_range_is_a_bearing_only_sighting() -> None:
    """An object that fills the view (both sides cut) has no monocular range; no scan: bearing only."""
    p = place("green box", (0, 100, 640, 479), 1.0, Pose2D(0, 0, 0), CAM, MOUNT, RangeEstimator("box"))
    assert not p.ranged and p.method == "fills_view" and math.isnan(p.x)
    assert p.span[0] < 0 < p.span[1]


@settings(max_examples=100, deadline=None)
@given(pose=poses, dist=st.floats(1.2, 4.0), bearing=st.floats(-0.5, 0.5), cut=st.floats(0.1, 0.45),
       left=st.booleans())  # fmt: skip
def test_a_round_object_cut_by_the_image_lands_on_it(
    pose: Pose2D, dist: float, bearing: float, cut: float, left: bool
) -> None:
    """A cylinder more than half in view but cut by one side of the image: its centre is a half-angle
    inside the uncut edge (a few cm); less than half in view, or a box, it places nothing."""
    obj = _object_in_view(pose, dist, bearing)
    box = cylinder_box(pose, obj, R, H)
    assume(box is not None)
    x1, y1, x2, y2 = box
    shift = cut * (x2 - x1)  # the image's side moves this many pixels into the box
    if left:  # the same camera, its image starting `shift` px inside the box's left edge
        clipped = (0.0, y1, x2 - x1 - shift, y2)
        cam = dataclasses.replace(CAM, cx=CAM.cx - x1 - shift)
    else:  # ... or ending `shift` px inside its right edge
        clipped = (x1, y1, x2 - shift, y2)
        cam = dataclasses.replace(CAM, width=int(round(x2 - shift)))
    p = place("blue cylinder", clipped, 1.0, pose, cam, MOUNT, ranger())
    assert p.ranged, p
    assert math.hypot(p.x - obj[0], p.y - obj[1]) < 0.06
    q = place("green box", clipped, 1.0, pose, cam, MOUNT, RangeEstimator("box"))
    assert not q.ranged and q.method == "cut"


@settings(max_examples=100, deadline=None)
@given(pose=poses, dist=st.floats(1.0, 6.0), bearing=st.floats(-0.4, 0.4), behind=st.floats(-2 * R, 3.0))
def test_a_wall_behind_the_object_is_not_its_range(pose: Pose2D, dist: float, bearing: float, behind: float) -> None:
    """A small object below the scan's reach, a wall `behind` m past its far side on its bearing (at
    its near surface at worst): the wall's return is farther than the object's near surface, or it runs
    on past both sides of the box, so it is not the object's and the object is placed by its own bottom
    edge, never on the wall (the lidar's return put ducks and trays on the walls behind them)."""
    obj = _object_in_view(pose, dist, bearing)
    box = cylinder_box(pose, obj, R, H)
    assume(box is not None)
    ox, oy = pose.to_local(*obj)
    dx, dy = ox - MOUNT.forward_m, oy - MOUNT.left_m
    d = math.hypot(dx, dy)
    ux, uy = dx / d, dy / d
    t = np.linspace(-1.5, 1.5, 61)  # a wall across the bearing, `behind` m past the object's far side
    far = d + R + behind
    wall = np.column_stack([MOUNT.forward_m + far * ux - t * uy, MOUNT.left_m + far * uy + t * ux])
    p = place("blue cylinder", box, 1.0, pose, CAM, MOUNT, ranger(), wall)
    assert p.method == "bottom"
    assert math.hypot(p.x - obj[0], p.y - obj[1]) < 0.1


def test_a_wall_across_the_view_is_placed_on_its_face_not_behind_it() -> None:
    """A thing of no known shape that spans the image's width is known by its face only: it is placed
    on it, not half its visible width behind it (walls were remembered metres beyond themselves)."""
    pose = Pose2D(0.0, 0.0, 0.0)
    face = 3.0
    ys = np.linspace(-4.0, 4.0, 161)
    scan = np.column_stack([np.full_like(ys, MOUNT.forward_m + face), ys])
    wall = (0.0, 0.0, float(CAM.width), CAM.cy + CAM.fy * MOUNT.height_m / face)  # its foot 3 m ahead
    r = RangeEstimator(None, camera_height=MOUNT.height_m)
    p = place("wall", wall, 1.0, pose, CAM, MOUNT, r, scan)
    assert p.x - MOUNT.forward_m == pytest.approx(face, abs=0.1) and abs(p.y) < 0.05
    narrow = (CAM.cx - 50.0, CAM.cy - 80.0, CAM.cx + 50.0, wall[3])  # seen whole: as deep as it is wide at most
    q = place("crate", narrow, 1.0, pose, CAM, MOUNT, r, scan)
    assert face < q.x - MOUNT.forward_m <= face + q.size[0] / 2 + 0.1


def test_a_range_by_size_is_as_unsure_as_its_box_is_narrow() -> None:
    """A mug 6 m ahead, its bottom out of the picture: ranged by its size over the box's width. A box
    a few pixels wide read one pixel narrow puts it metres farther (a mug 6 m away read at 19 m), so
    the range's sigma grows as the box narrows; so unsure, the memory starts no object from it."""
    from go2vlm.world.memory import MemoryParams

    mug = RangeEstimator("cylinder", camera_height=MOUNT.height_m, default_sizes={"cylinder": 0.045})
    sigmas = []
    for width in (16.0, 10.0, 6.0, 3.0):  # 6.5 px is the mug at 6 m (CAM)
        box = (CAM.cx - width / 2, 200.0, CAM.cx + width / 2, CAM.height - 1.0)
        p = place("mug", box, 1.0, Pose2D(0.0, 0.0, 0.0), CAM, MOUNT, mug)
        assert p.method in ("size", "default_size") and p.range_m is not None
        sigmas.append(math.sqrt(p.cov[0]))  # along the ray (the camera faces +x)
        assert sigmas[-1] >= p.range_m * math.sqrt(2.0) / width  # one pixel per side, over the width
    assert sigmas == sorted(sigmas) and sigmas[-1] > MemoryParams().new_max_sigma_m
