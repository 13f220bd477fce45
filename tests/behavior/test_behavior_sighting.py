"""The commander's one box conversion (behavior/sighting.py): any TrackedTarget becomes a Sighting
without raising; a bad box, image size or state says `lost` with a reason; a good box inside the image
gives the offset x of its centre in -1..1 (geometry/target.py), + right."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from go2vlm.behavior.sighting import sighting_of
from go2vlm.msgs.go2vlm_msgs import STATE_NAMES, TrackedTarget
from go2vlm.msgs.vision_msgs import BoundingBox2D, Point2D, Pose2D

TRACKING = next(k for k, v in STATE_NAMES.items() if v == "tracking")
anyf = st.floats(allow_nan=True, allow_infinity=True)


@given(
    state=st.integers(0, 255), cx=anyf, cy=anyf, sx=anyf, sy=anyf, w=st.integers(0, 200_000),
    h=st.integers(0, 200_000), d=anyf, b=anyf,
)  # fmt: skip
def test_any_report_becomes_a_sighting_and_bad_ones_say_lost(
    state: int, cx: float, cy: float, sx: float, sy: float, w: int, h: int, d: float, b: float
) -> None:
    box = BoundingBox2D(Pose2D(Point2D(cx, cy)), sx, sy)
    msg = TrackedTarget(label="red ball", state=state, bbox=box, image_width=w, image_height=h, distance_m=d,
                        bearing_rad=b)  # fmt: skip
    s, bad = sighting_of(msg, 1.0)
    assert s.t == 1.0 and s.label == "red ball"
    if state not in STATE_NAMES:
        assert s.state == "lost" and bad is not None and "state" in bad
    if s.state == "tracking":
        assert bad is None and math.isfinite(s.x)
        assert s.distance is None or 0.0 <= s.distance < 1000.0
        assert math.isnan(s.bearing) or abs(s.bearing) < math.pi
        assert math.isnan(s.width) or 0.0 < s.width < math.pi
    elif bad is not None:
        assert s.state == "lost" and not s.tracked


@given(w=st.integers(16, 4000), h=st.integers(16, 4000), fx=st.floats(0.0, 1.0), fy=st.floats(0.0, 1.0))
def test_a_box_in_the_image_gives_its_centre_offset(w: int, h: int, fx: float, fy: float) -> None:
    box = BoundingBox2D(Pose2D(Point2D(fx * w, fy * h)), 10.0, 12.0)
    msg = TrackedTarget(label="red ball", state=TRACKING, bbox=box, image_width=w, image_height=h, distance_m=2.0)
    s, bad = sighting_of(msg, 0.0)
    assert bad is None and s.tracked
    assert abs(s.x - (2.0 * fx - 1.0)) < 1e-9  # -1 at the left edge, +1 at the right


def test_a_box_gives_its_angular_width() -> None:
    """A box across the whole image of a 73 degree camera is 73 degrees wide; a centred tenth of it, by
    the pinhole, 2 atan(tan(36.5 deg) / 10)."""
    hfov = math.radians(73)
    for sx, want in ((640.0, hfov), (64.0, 2 * math.atan(math.tan(hfov / 2) / 10))):
        box = BoundingBox2D(Pose2D(Point2D(320.0, 240.0)), sx, 12.0)
        msg = TrackedTarget(label="tray", state=TRACKING, bbox=box, image_width=640, image_height=480, hfov_rad=hfov)
        s, _ = sighting_of(msg, 0.0)
        assert abs(s.width - want) < 1e-9
