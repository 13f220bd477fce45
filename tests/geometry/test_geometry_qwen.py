"""Qwen smart resize and coordinate conventions (pure functions shared by both backends)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.geometry.qwen import (
    CoordSystem,
    box_to_original,
    coord_system_for,
    smart_resize,
    visual_tokens,
)


def test_camera_frame_sizes() -> None:
    # 640x480: round to multiples of 28 -> 476x644, 17*23 = 391 visual tokens
    assert smart_resize(480, 640, min_pixels=3136, max_pixels=401408) == (476, 644)
    assert visual_tokens((476, 644)) == 391
    # capped: area <= max_pixels, both sides multiples of 28, aspect kept
    h, w = smart_resize(1080, 1920, min_pixels=3136, max_pixels=200704)
    assert h % 28 == 0 and w % 28 == 0 and h * w <= 200704
    assert abs((w / h) - 1920 / 1080) < 0.1
    # tiny image is scaled up to min_pixels
    h, w = smart_resize(20, 30, min_pixels=3136, max_pixels=401408)
    assert h * w >= 3136


def test_rejects_bad_sizes() -> None:
    with pytest.raises(ValueError):
        smart_resize(0, 10)
    with pytest.raises(ValueError):
        smart_resize(10, 5000)  # aspect > 200
    with pytest.raises(ValueError):
        smart_resize(100, 100, min_pixels=5000, max_pixels=4000)


@settings(max_examples=300, deadline=None)
@given(
    h=st.integers(1, 4000),
    w=st.integers(1, 4000),
    lo=st.integers(1, 64),
    span=st.integers(0, 4096),
)
def test_matches_transformers(h: int, w: int, lo: int, span: int) -> None:
    """The openai backend's prediction equals what a transformers processor does."""
    pytest.importorskip("transformers")
    from transformers.models.qwen2_vl.image_processing_qwen2_vl import smart_resize as hf_smart_resize

    if max(h, w) / min(h, w) > 200:
        return
    min_pixels = lo * 784
    max_pixels = min_pixels + span * 784
    ours = smart_resize(h, w, min_pixels=min_pixels, max_pixels=max_pixels)
    assert ours == hf_smart_resize(h, w, factor=28, min_pixels=min_pixels, max_pixels=max_pixels)
    assert ours[0] % 28 == 0 and ours[1] % 28 == 0


def test_coords_by_family() -> None:
    assert coord_system_for("qwen2_5_vl") is CoordSystem.RESIZED_PIXELS
    assert coord_system_for("qwen2_vl") is CoordSystem.NORM_1000
    assert coord_system_for("qwen3_vl") is CoordSystem.NORM_1000
    assert coord_system_for("qwen3_vl_moe") is CoordSystem.NORM_1000
    assert coord_system_for(None) is CoordSystem.RESIZED_PIXELS


def test_box_to_original() -> None:
    # Qwen2.5-VL: pixels of the 476x644 resized image -> 480x640 original
    x1, y1, x2, y2 = box_to_original(
        (0, 0, 644, 476), coords=CoordSystem.RESIZED_PIXELS, resized_hw=(476, 644), original_hw=(480, 640)
    )
    assert (x1, y1) == (0, 0) and x2 == pytest.approx(640) and y2 == pytest.approx(480)
    # Qwen2-VL/Qwen3-VL: 0..1000 grid, independent of the resize
    box = box_to_original(
        (500, 250, 1000, 1000), coords=CoordSystem.NORM_1000, resized_hw=(476, 644), original_hw=(480, 640)
    )
    assert box == pytest.approx((320, 120, 640, 480))
