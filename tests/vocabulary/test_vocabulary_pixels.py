"""The colour-in-box check the target_tracker and the object memory share."""

from __future__ import annotations

import numpy as np
import pytest

from go2vlm.vocabulary.pixels import box_fraction, color_in_box, label_color_mask
from go2vlm.vocabulary.words import COLORS

BGR = {"red": (0, 0, 230), "green": (0, 200, 0), "blue": (230, 60, 0), "yellow": (0, 220, 240)}


@pytest.mark.parametrize("color", COLORS)
def test_a_box_on_the_colour_passes_and_one_beside_it_is_refused(color: str) -> None:
    img = np.full((60, 80, 3), 128, np.uint8)
    img[10:30, 10:30] = BGR[color]  # a KeyError here: a colour was added without a test patch
    mask = label_color_mask(img, color)
    assert box_fraction(mask, (10, 10, 30, 30)) == pytest.approx(1.0)
    frac, why = color_in_box(mask, (10, 10, 30, 30), label=f"{color} ball", color=color, min_fraction=0.15)
    assert frac == pytest.approx(1.0) and why == ""
    frac, why = color_in_box(
        mask, (40, 30, 80, 60), label=f"{color} ball", color=color, min_fraction=0.15, shown=(40.4, 30, 90, 60)
    )
    assert frac == 0.0 and why == f"'{color} ball' box (40, 30, 90, 60) is 0 % {color}"


def test_a_box_outside_the_image_holds_nothing() -> None:
    mask = np.full((10, 10), 255, np.uint8)
    assert box_fraction(mask, (-5, -5, 0, 0)) == 0.0
    assert box_fraction(mask, (0, 0, 5, 10)) == pytest.approx(1.0)
