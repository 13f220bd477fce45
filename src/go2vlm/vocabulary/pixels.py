"""Colour words -> pixels: a colour's HSV mask, and the colour-in-box check.

The check is the one both the target_tracker (perception/tracking.py) and the object memory
(world/object_memory_node.py) apply to an answer's box before they believe it: a box labelled
"red ball" must hold at least a fraction of red pixels. Same words, same test, same refusal text.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from go2vlm.vocabulary.words import COLOR_HSV, HsvRange

__all__ = ["box_fraction", "color_in_box", "color_mask", "label_color_mask"]

Box = tuple[float, float, float, float]  # x1, y1, x2, y2 in pixels

_KERNEL = np.ones((3, 3), np.uint8)  # OpenCV's default for erode and dilate


def color_mask(bgr: np.ndarray, ranges: Sequence[HsvRange], iterations: int = 2) -> np.ndarray:
    """The cleaned binary mask (uint8 0/255) of pixels inside any of the ranges."""
    if bgr.ndim != 3 or bgr.shape[2] != 3 or bgr.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 BGR image, got shape {bgr.shape} dtype {bgr.dtype}")
    hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)
    mask = cv2.inRange(hsv, ranges[0][0], ranges[0][1])
    for lo, hi in ranges[1:]:
        mask = cv2.bitwise_or(mask, cv2.inRange(hsv, lo, hi))
    if iterations > 0:
        mask = cv2.erode(mask, _KERNEL, iterations=iterations)
        mask = cv2.dilate(mask, _KERNEL, iterations=iterations)
    return mask


def label_color_mask(bgr: np.ndarray, color: str) -> np.ndarray:
    """The raw (not cleaned) mask of a colour word's pixels, for the colour-in-box check."""
    return color_mask(bgr, COLOR_HSV[color], iterations=0)


def box_fraction(mask: np.ndarray, box: Box) -> float:
    """Fraction of a box's pixels set in a mask (0..1)."""
    x1, y1, x2, y2 = (int(round(v)) for v in box)
    roi = mask[max(0, y1) : max(0, y2), max(0, x1) : max(0, x2)]
    return float(cv2.countNonZero(roi)) / max(1, roi.size)


def color_in_box(
    mask: np.ndarray, box: Box, *, label: str, color: str, min_fraction: float, shown: Box | None = None
) -> tuple[float, str]:
    """(the fraction of `box` set in `mask`, '' or why the box is refused: it holds less than
    `min_fraction` of `color`). `shown` is the box as the answer gave it, for the message."""
    frac = box_fraction(mask, box)
    if frac >= min_fraction:
        return frac, ""
    where = tuple(round(v) for v in (shown if shown is not None else box))
    return frac, f"{label!r} box {where} is {100 * frac:.0f} % {color}"
