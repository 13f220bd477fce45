"""The target's fused range (world/ranging.py): the tracker's range, the scan's return on its bearing
and the memory's place, as one estimator. Property tests over arbitrary readings, scans and memories,
and the rules one by one."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.world.objects_msg import Remembered
from go2vlm.world.poses import Pose2D
from go2vlm.world.ranging import SIZE_METHODS, RangingParams, TargetRanging, as_wide, is_surface, remembered_on

CF = 0.3  # the camera ahead of the base centre (m)
P = RangingParams()
METHODS = ("bottom", "size", "default_size", "fills_view", "none")


@dataclasses.dataclass(frozen=True)
class Seen:
    distance: float | None
    range_method: str = "bottom"
    bearing: float = 0.0
    width: float = math.nan
    hfov: float = math.radians(70.0)


def face(at: float, half_width: float = 0.4, n: int = 17) -> np.ndarray:
    """A flat face `at` m ahead of the camera (base frame), `half_width` each side."""
    ys = np.linspace(-half_width, half_width, n)
    return np.column_stack([np.full_like(ys, CF + at), ys])


def shelf(x: float, y: float = 0.0, conf: float = 0.9, seen: float = 9.5, label: str = "shelf") -> Remembered:
    return Remembered("s1", label, x, y, 0.5, (1.0, 1.0, 1.0), conf, seen, (0.01, 0.0, 0.01))


def test_every_threshold_is_a_declared_parameter_with_help_and_bounds() -> None:
    for f in dataclasses.fields(RangingParams):
        meta = f.metadata
        assert meta.get("help") and meta.get("min") is not None and meta.get("max") is not None, f.name
        assert meta["min"] <= f.default <= meta["max"], f.name


readings = st.builds(
    Seen,
    st.one_of(st.none(), st.floats(0.0, 30.0)),
    st.sampled_from(METHODS),
    st.one_of(st.just(math.nan), st.floats(-0.6, 0.6)),
    st.one_of(st.just(math.nan), st.floats(0.0, 1.0)),
)
scans = st.one_of(
    st.none(),
    st.lists(st.tuples(st.floats(-1.0, 4.0), st.floats(-2.0, 2.0)), max_size=30).map(
        lambda p: np.array(p, dtype=float).reshape(-1, 2)
    ),
)


@settings(max_examples=300, deadline=None)
@given(s=readings, scan=scans, mem=st.one_of(st.none(), st.floats(0.0, 30.0)))
def test_the_range_is_the_tracker_s_the_scan_s_or_the_memory_s_and_says_which(
    s: Seen, scan: np.ndarray | None, mem: float | None
) -> None:
    r = TargetRanging()
    d = r.base_distance(P, s, 10.0, scan, CF, mem)
    own = None if s.distance is None else s.distance + CF
    if d is None:
        assert own is None
        return
    assert r.ranged_by in (*METHODS, "lidar", "memory")
    if r.ranged_by == "memory":
        assert mem is not None and d == mem
    elif r.ranged_by == "lidar":
        # the scan's return on the bearing: within scan_range_m, never farther than the tracker's
        assert math.isfinite(s.bearing) and CF <= d <= CF + P.scan_range_m + 1e-9
        if own is not None and s.range_method != "fills_view":
            assert P.scan_agree * own - 1e-9 <= d < own
    else:
        assert r.ranged_by == s.range_method and d == own
    if mem is not None and math.isfinite(s.bearing) and r.ranged_by != "memory":  # it overrules a range far short
        assert not (mem > P.memory_far * d and mem > d + P.memory_gap_m)


def test_without_a_bearing_the_tracker_s_range_stands() -> None:
    r = TargetRanging()
    assert r.base_distance(P, Seen(1.0, bearing=math.nan), 1.0, face(0.5), CF, 20.0) == 1.0 + CF
    assert r.base_distance(P, Seen(None, bearing=math.nan), 1.0, face(0.5), CF) is None


def test_a_near_return_as_wide_as_the_box_ranges_it_and_a_thin_one_or_a_far_one_does_not() -> None:
    r = TargetRanging()
    wide = math.radians(10.0)
    box = face(0.75, 0.75 * math.tan(wide / 2), 9)  # the object's face: as wide as its box
    assert r.base_distance(P, Seen(1.2, "size", 0.0, wide), 1.0, box, CF) == pytest.approx(0.75 + CF)
    assert r.ranged_by == "lidar"
    leg = np.array([[CF + 0.75, 0.0], [CF + 0.76, 0.005]])
    assert r.base_distance(P, Seen(1.2, "size", 0.0, wide), 1.0, leg, CF) == pytest.approx(1.2 + CF)
    assert r.ranged_by == "size"
    # farther than the tracker's range, beyond scan_range_m, or far below its share: not the target
    for at, own in ((1.9, 1.2), (P.scan_range_m + 0.1, 5.0), (0.5, 10.0)):
        assert r.base_distance(P, Seen(own, "bottom"), 1.0, face(at), CF) == pytest.approx(own + CF), at
    # no range of its own, or "fills the view": the return is the range; without one, fills_view is 0
    assert r.base_distance(P, Seen(None, "none"), 1.0, face(0.6), CF) == pytest.approx(0.6 + CF)
    assert r.base_distance(P, Seen(0.0, "fills_view", 0.0, 1.1), 1.0, face(0.9, 1.0, 41), CF) == pytest.approx(0.9 + CF)
    assert r.base_distance(P, Seen(0.0, "fills_view"), 1.0, np.zeros((0, 2)), CF) == pytest.approx(CF)


def test_a_return_of_a_surface_that_runs_on_past_the_box_is_not_the_objects() -> None:
    """A toy chest behind the end of a bed: the nearest return on its bearing is the bed's, which runs
    on past the chest's box; taken for the chest, the robot stopped 0.84 m from the bed, 1.7 m from the
    chest (houses 002). A box cut by the image's border may run on that side: the object goes on out
    of view."""
    r = TargetRanging()
    wide = math.radians(12.0)
    bed = face(1.0, 1.0, 41)  # 2 m across, 1 m ahead of the camera
    assert r.base_distance(P, Seen(1.6, "bottom", 0.0, wide), 1.0, bed, CF) == pytest.approx(1.6 + CF)
    assert r.ranged_by == "bottom"
    chest = face(1.0, math.tan(wide / 2), 9)
    assert r.base_distance(P, Seen(1.2, "bottom", 0.0, wide), 1.0, chest, CF) == pytest.approx(1.0 + CF)
    assert r.ranged_by == "lidar"
    half = math.radians(35.0)  # the box's left edge at the image's border: the face may go on past it
    cut = Seen(1.2, "bottom", half - wide / 2, wide)
    b_r, b_l = half - wide, half
    side = np.column_stack([np.full(30, CF + 1.0), np.linspace(math.tan(b_r), 2.0, 30)])  # from its right edge on
    d = r.base_distance(P, cut, 1.0, side, CF)
    assert r.ranged_by == "lidar" and d is not None and d < 1.2 + CF
    assert is_surface(P, side, (CF, 0.0), d - CF, b_r, b_l, (False, True))
    assert not is_surface(P, side, (CF, 0.0), d - CF, b_r, b_l)


def test_the_memory_overrules_a_range_far_short_and_holds_a_while() -> None:
    r = TargetRanging()
    assert r.base_distance(P, Seen(1.0), 10.0, None, CF, 8.0) == 8.0 and r.ranged_by == "memory"
    # off its cone a moment later: still the memory's, while the tracker's is as far short
    assert r.base_distance(P, Seen(0.5), 10.0 + P.memory_hold_s, None, CF) == 8.0
    assert r.base_distance(P, Seen(6.0), 11.0, None, CF) == 6.0 + CF  # not far short: the tracker's
    assert r.base_distance(P, Seen(0.5), 10.1 + P.memory_hold_s, None, CF) == 0.5 + CF  # the hold is over
    r.base_distance(P, Seen(1.0), 20.0, None, CF, 8.0)
    r.forget()
    assert r.overruled is None and r.base_distance(P, Seen(1.0), 20.5, None, CF) == 1.0 + CF
    assert r.base_distance(P, Seen(1.0), 21.0, None, CF, 2.2) == 1.0 + CF  # near: not far beyond


def test_remembered_on_takes_the_nearest_confident_fresh_object_of_the_label_on_the_bearing() -> None:
    at = Pose2D(0.0, 0.0, 0.0)
    s = Seen(1.0, width=math.radians(8))
    assert remembered_on(P, s, 10.0, at, [shelf(8.5), shelf(6.0)], "shelf", 0.7) == pytest.approx(5.5)
    late = 10.0 - P.memory_fresh_s - 0.5
    for o in (shelf(8.5, conf=0.3), shelf(8.5, seen=late), shelf(8.5, y=4.0), shelf(8.5, label="duck")):
        assert remembered_on(P, s, 10.0, at, [o], "shelf", 0.7) is None, o
    turned = Pose2D(0.0, 0.0, math.pi / 2)  # the bearing is the camera's: the pose's yaw turns it
    assert remembered_on(P, s, 10.0, turned, [shelf(0.0, 8.5)], "shelf", 0.7) == pytest.approx(8.0)
    wide = Seen(1.0, width=1.2)  # a wide box: its half is the cone
    assert remembered_on(P, wide, 10.0, at, [shelf(8.5, y=4.0)], "shelf", 0.7) is not None


def test_a_far_range_by_size_counts_once_it_has_held() -> None:
    r, cap = TargetRanging(), 25.0
    assert "size" in SIZE_METHODS and "bottom" not in SIZE_METHODS
    assert r.capped(P, 72.5, "size", cap, 1.0) is None
    assert r.capped(P, 40.0, "default_size", cap, 1.0 + P.far_hold_s / 2) is None
    assert r.capped(P, 8.0, "size", cap, 1.6) == 8.0  # within the cap: the hold starts again
    assert r.capped(P, 72.5, "size", cap, 2.0) is None
    assert r.capped(P, 72.5, "size", cap, 2.0 + P.far_hold_s) == 72.5
    assert r.capped(P, 30.0, "bottom", cap, 4.0) == 30.0
    assert r.capped(P, None, "size", cap, 5.0) is None


@settings(max_examples=200, deadline=None)
@given(cover=st.floats(0.0, 1.0), width=st.floats(math.radians(7.0), 1.0), d=st.floats(0.3, 3.0))
def test_as_wide_says_whether_the_returns_span_the_share_of_the_box(cover: float, width: float, d: float) -> None:
    a = np.linspace(-cover * width / 2, cover * width / 2, 50)
    pts = np.column_stack([d * np.cos(a), d * np.sin(a)])
    covered = cover * width + (a[1] - a[0])  # each return stands for its bin (the scan's step)
    if abs(covered - P.scan_cover * width) > 1e-6:
        assert as_wide(P, pts, (0.0, 0.0), d, 0.0, width) == (covered > P.scan_cover * width)
    behind = pts * (d + P.scan_depth_m + 0.05) / d  # wide, but beyond the depth behind the nearest return
    assert not as_wide(P, np.vstack([[d, 0.0], behind]), (0.0, 0.0), d, 0.0, width)
    assert as_wide(P, pts[:0], (0.0, 0.0), d, 0.0, math.nan)  # unknown width: passes
