"""The /detected_target convention (the follow article's colour detector, section 5.2): a box's
normalised centre and size."""

from __future__ import annotations

import pytest

from go2vlm.geometry.target import normalized_target


def test_normalised_target_matches_the_colour_detector_convention() -> None:
    x, y, z = normalized_target((320 - 50, 240 - 50, 320 + 50, 240 + 50), 640, 480)
    assert (x, y) == (0.0, 0.0) and z == pytest.approx(50 / 320)
    x, _, _ = normalized_target((600, 0, 640, 40), 640, 480)
    assert x == pytest.approx((620 - 320) / 320)
