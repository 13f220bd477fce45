"""Pure HSV colour detection (the follow article's color_detector.py, section 5.2) on the VLM article's
test pattern (section 3.3) and on drawn images, and the colour detector's colour parameters."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from go2vlm.bus import ParamError, build_config
from go2vlm.perception.color import PRESETS, annotate, detect_color, resolve_ranges
from go2vlm.perception.color_detector_node import ColorDetectorConfig
from go2vlm.sources.test_pattern_node import draw_pattern


def test_detects_the_seed_red_circle() -> None:
    det = detect_color(draw_pattern(0), "red")
    assert det is not None
    assert (det.cx, det.cy) == pytest.approx((450, 150), abs=1.0)
    assert det.radius == pytest.approx(80, abs=1.0)
    assert det.bbox == pytest.approx((370, 70, 161, 161), abs=2)
    assert det.area == pytest.approx(np.pi * 80**2, rel=0.03)
    x, y, z = det.normalized()
    assert (x, y, z) == pytest.approx((130 / 320, -90 / 240, 80 / 320), abs=0.005)


def test_green_preset_finds_the_rectangle_and_blue_finds_nothing() -> None:
    det = detect_color(draw_pattern(3), "green")
    assert det is not None and (det.cx, det.cy) == pytest.approx((200, 300), abs=1.5)
    assert detect_color(draw_pattern(3), "blue") is None
    assert detect_color(np.zeros((480, 640, 3), np.uint8), "red") is None


def test_red_wraps_around_hue_zero() -> None:
    img = np.zeros((200, 200, 3), np.uint8)
    hsv_hi = np.uint8([[[175, 255, 255]]])  # hue 175: only the upper red range sees it
    bgr = cv2.cvtColor(hsv_hi, cv2.COLOR_HSV2BGR)[0, 0].tolist()
    cv2.circle(img, (100, 100), 30, bgr, -1)
    det = detect_color(img, "red")
    assert det is not None and det.cx == pytest.approx(100, abs=1)
    assert detect_color(img, [((0, 120, 70), (10, 255, 255))]) is None


def test_small_blobs_are_ignored_and_largest_wins() -> None:
    img = np.zeros((240, 320, 3), np.uint8)
    cv2.circle(img, (40, 40), 6, (0, 0, 255), -1)  # radius <= 10 after erode/dilate: noise
    assert detect_color(img, "red") is None
    cv2.circle(img, (200, 120), 30, (0, 0, 255), -1)
    cv2.circle(img, (60, 180), 15, (0, 0, 255), -1)
    det = detect_color(img, "red")
    assert det is not None and (det.cx, det.cy) == pytest.approx((200, 120), abs=1)
    out = annotate(img, det)
    assert out.shape == img.shape and not np.array_equal(out, img)


def test_custom_ranges_and_their_errors() -> None:
    assert resolve_ranges([[0, 120, 70, 10, 255, 255]]) == (((0, 120, 70), (10, 255, 255)),)
    assert resolve_ranges("RED") == PRESETS["red"]
    for bad in ("purple", [[0, 0, 0]], [[10, 0, 0, 5, 255, 255]], [[0, 0, 0, 300, 255, 255]], []):
        with pytest.raises(ValueError):
            resolve_ranges(bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        detect_color(np.zeros((10, 10), np.uint8), "red")
    cfg = build_config(ColorDetectorConfig, {"color": "custom", "hsv_ranges": "[[100,120,60,130,255,255]]"})
    assert cfg.ranges() == (((100, 120, 60), (130, 255, 255)),)
    with pytest.raises(ParamError):
        build_config(ColorDetectorConfig, {"color": "custom"})
