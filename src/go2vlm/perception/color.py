"""Pure HSV colour detection, the follow article's color_detector.py (section 5.2) without ROS.

    det = detect_color(bgr, "red")             # a preset
    det = detect_color(bgr, [((0, 120, 70), (10, 255, 255))])  # custom HSV ranges
    if det is not None:
        x, y, z = det.normalized()             # what /detected_target carries

The article's steps, in order: BGR -> HSV; one mask per HSV range, OR-ed (red wraps around hue 0, so it
is two ranges); erode then dilate with OpenCV's default 3x3 kernel, 2 iterations each; external
contours; the largest by area; its minimum enclosing circle; kept only if the radius is > 10 px.
OpenCV hue runs 0..179, saturation and value 0..255.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from go2vlm.geometry.target import circle_target
from go2vlm.vocabulary.pixels import color_mask
from go2vlm.vocabulary.words import COLOR_HSV, Hsv, HsvRange

# Presets: the vocabulary's colours (red is the follow article's pair of ranges).
PRESETS = COLOR_HSV


@dataclass(frozen=True)
class Detection:
    """The largest blob of the colour, in pixels of the image it was found in."""

    cx: float
    cy: float
    radius: float  # minimum enclosing circle
    area: float  # contour area in px^2
    bbox: tuple[int, int, int, int]  # x, y, w, h
    contour: np.ndarray  # (N, 1, 2) int32, as cv2.findContours returns it
    width: int  # image size, for normalisation
    height: int

    def normalized(self) -> tuple[float, float, float]:
        """The /detected_target point (geometry/target.py)."""
        return circle_target(self.cx, self.cy, self.radius, self.width, self.height)


def _check_hsv(value: Sequence[Any], what: str) -> Hsv:  # a parameter's value, checked here
    if len(value) != 3:
        raise ValueError(f"{what} {tuple(value)!r} must have 3 values (H, S, V)")
    h, s, v = (int(x) for x in value)
    if not (0 <= h <= 180 and 0 <= s <= 255 and 0 <= v <= 255):
        raise ValueError(f"{what} {(h, s, v)!r} is outside H 0..180, S 0..255, V 0..255")
    return h, s, v


def resolve_ranges(preset_or_ranges: str | Sequence[Sequence[Sequence[int]] | Sequence[int]]) -> tuple[HsvRange, ...]:
    """A preset name, or ranges given as ((h,s,v), (h,s,v)) pairs or flat [h,s,v,h,s,v] lists."""
    if isinstance(preset_or_ranges, str):
        key = preset_or_ranges.strip().lower()
        if key not in PRESETS:
            raise ValueError(f"colour preset {preset_or_ranges!r} is unknown; use one of {sorted(PRESETS)}")
        return PRESETS[key]
    out: list[HsvRange] = []
    for i, item in enumerate(preset_or_ranges):
        flat = [v for part in item for v in (part if isinstance(part, (list, tuple)) else [part])]
        if len(flat) != 6:
            raise ValueError(f"HSV range #{i} {item!r} must be [h, s, v, h, s, v] or ((h, s, v), (h, s, v))")
        lo = _check_hsv(flat[:3], f"HSV range #{i} lower")
        hi = _check_hsv(flat[3:], f"HSV range #{i} upper")
        if any(a > b for a, b in zip(lo, hi, strict=True)):
            raise ValueError(f"HSV range #{i}: lower {lo} exceeds upper {hi} (for red use two ranges)")
        out.append((lo, hi))
    if not out:
        raise ValueError("no HSV ranges given")
    return tuple(out)


def detect_color(
    bgr: np.ndarray,
    preset_or_ranges: str | Sequence[HsvRange] = "red",
    *,
    min_radius: float = 10.0,
    iterations: int = 2,
) -> Detection | None:
    """The largest blob of the colour, or None when there is none with radius > `min_radius` px."""
    ranges = resolve_ranges(preset_or_ranges)
    mask = color_mask(bgr, ranges, iterations)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return None
    c = max(contours, key=cv2.contourArea)
    (x, y), radius = cv2.minEnclosingCircle(c)
    if not radius > min_radius:
        return None
    h, w = bgr.shape[:2]
    bx, by, bw, bh = cv2.boundingRect(c)
    return Detection(
        cx=float(x),
        cy=float(y),
        radius=float(radius),
        area=float(cv2.contourArea(c)),
        bbox=(int(bx), int(by), int(bw), int(bh)),
        contour=c,
        width=int(w),
        height=int(h),
    )


def annotate(bgr: np.ndarray, det: Detection | None) -> np.ndarray:
    """A copy of the image with the follow article's yellow circle (and the bbox) drawn on the detection."""
    out = bgr.copy()
    if det is not None:
        cv2.circle(out, (int(det.cx), int(det.cy)), int(det.radius), (0, 255, 255), 2)
        x, y, w, h = det.bbox
        cv2.rectangle(out, (x, y), (x + w, y + h), (255, 255, 0), 1)
        cv2.drawMarker(out, (int(det.cx), int(det.cy)), (0, 255, 255), cv2.MARKER_CROSS, 12, 2)
    return out
