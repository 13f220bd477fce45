"""The colour-shape grounder on drawn images: colour and shape found, wrong ones not, clear errors."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from go2vlm.perception.grounding import ground

BGR = {"red": (0, 0, 255), "green": (0, 200, 0), "blue": (255, 0, 0), "yellow": (0, 230, 255)}


def scene() -> np.ndarray:
    img = np.full((480, 640, 3), 40, np.uint8)
    cv2.circle(img, (450, 150), 70, BGR["red"], -1)  # red ball
    cv2.rectangle(img, (80, 220), (240, 380), BGR["green"], -1)  # green box
    cv2.rectangle(img, (300, 230), (360, 440), BGR["blue"], -1)  # blue cylinder (tall)
    cv2.rectangle(img, (500, 330), (600, 430), BGR["red"], -1)  # red box
    return img


@pytest.mark.parametrize(
    ("color", "shape", "center"),
    [
        ("red", "ball", (450, 150)),
        ("red", "box", (550, 380)),
        ("green", "box", (160, 300)),
        ("blue", "cylinder", (330, 335)),
        (None, "cylinder", (330, 335)),
    ],
)
def test_grounds_colour_and_shape(color: str | None, shape: str, center: tuple[int, int]) -> None:
    cands = ground(scene(), color, shape)
    assert cands, f"no {color} {shape}"
    x1, y1, x2, y2 = cands[0].xyxy
    assert abs((x1 + x2) / 2 - center[0]) < 6 and abs((y1 + y2) / 2 - center[1]) < 6
    assert cands[0].shape == shape


def test_wrong_shape_or_colour_finds_nothing() -> None:
    assert ground(scene(), "green", "ball") == []
    assert ground(scene(), "blue", "box") == []
    assert ground(scene(), "yellow", None) == []


def test_a_ball_cut_by_the_image_border_is_still_a_ball() -> None:
    img = np.full((480, 640, 3), 40, np.uint8)
    cv2.circle(img, (10, 200), 90, BGR["red"], -1)
    cands = ground(img, "red", "ball")
    assert cands and cands[0].shapes.clipped


def test_bad_arguments_are_clear_errors() -> None:
    with pytest.raises(ValueError, match="colour"):
        ground(scene(), "purple", None)
    with pytest.raises(ValueError, match="shape"):
        ground(scene(), "red", "pyramid")
