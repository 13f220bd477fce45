"""The /detected_target convention (the article's colour detector, section 5.2): a target's centre
as x, y in [-1, 1] from the image centre, and its size as z = radius / (w/2), bigger = closer."""

from __future__ import annotations

__all__ = ["circle_target", "normalized_target"]


def circle_target(cx: float, cy: float, radius: float, width: int, height: int) -> tuple[float, float, float]:
    """(x, y, z) of a circle centred at (cx, cy) pixels in a width x height image."""
    half_w, half_h = width / 2.0, height / 2.0
    return (cx - half_w) / half_w, (cy - half_h) / half_h, radius / half_w


def normalized_target(xyxy: tuple[float, float, float, float], width: int, height: int) -> tuple[float, float, float]:
    """(x, y, z) of a box: its centre, and radius = half its larger side."""
    x1, y1, x2, y2 = xyxy
    return circle_target((x1 + x2) / 2.0, (y1 + y2) / 2.0, max(x2 - x1, y2 - y1) / 2.0, width, height)
