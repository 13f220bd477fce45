"""Image geometry shared by both backends: Qwen's smart resize and box rescaling.

Qwen2-VL/2.5-VL resize every image to (H', W') with both sides multiples of 28
(patch 14 x spatial merge 2) and H'*W' within [min_pixels, max_pixels]; the model
then sees (H'/28)*(W'/28) visual tokens. Qwen2.5-VL answers boxes in absolute pixels
of that *resized* image; Qwen2-VL and Qwen3-VL answer on a 0..1000 grid. Either
way boxes must be mapped back to the original camera image before they are
published, and the openai backend, which never sees the server's processor, needs
the same resize arithmetic -- hence one pure module.
"""

from __future__ import annotations

import math
from enum import Enum

__all__ = [
    "DEFAULT_MAX_PIXELS",
    "DEFAULT_MIN_PIXELS",
    "QWEN_FACTOR",
    "CoordSystem",
    "box_to_original",
    "coord_system_for",
    "smart_resize",
    "visual_tokens",
]

QWEN_FACTOR = 28  # patch_size 14 * spatial_merge_size 2
DEFAULT_MIN_PIXELS = 4 * QWEN_FACTOR * QWEN_FACTOR  # 3136, Qwen's own minimum (56*56)
# 512 visual tokens: a 640x480 camera frame (476x644 after resize, 391 tokens) is kept at
# full resolution; bigger frames are scaled down instead of costing Qwen's default 16384.
DEFAULT_MAX_PIXELS = 512 * QWEN_FACTOR * QWEN_FACTOR
_MAX_ASPECT = 200.0


class CoordSystem(str, Enum):
    """How a model family writes box coordinates."""

    RESIZED_PIXELS = "resized_pixels"  # Qwen2.5-VL: absolute pixels of the (H', W') image
    NORM_1000 = "norm_1000"  # Qwen2-VL, Qwen3-VL: 0..1000 on both axes


def coord_system_for(model_type: str | None) -> CoordSystem:
    """Coordinate convention from ``config.model_type`` (unknown -> Qwen2.5-VL's)."""
    mt = (model_type or "").lower()
    if mt.startswith("qwen2_5_vl") or mt.startswith("qwen2.5"):
        return CoordSystem.RESIZED_PIXELS
    if mt.startswith("qwen2_vl") or mt.startswith("qwen3_vl") or mt.startswith("qwen3"):
        return CoordSystem.NORM_1000
    return CoordSystem.RESIZED_PIXELS


def smart_resize(
    height: int,
    width: int,
    *,
    factor: int = QWEN_FACTOR,
    min_pixels: int = DEFAULT_MIN_PIXELS,
    max_pixels: int = DEFAULT_MAX_PIXELS,
) -> tuple[int, int]:
    """Qwen2-VL's resize rule: (H', W') multiples of ``factor``, area in [min, max], aspect kept.

    Same arithmetic as ``transformers``' ``Qwen2VLImageProcessor`` (and qwen-vl-utils),
    so a client can predict what a remote server's processor will do.
    """
    if height <= 0 or width <= 0:
        raise ValueError(f"image size must be positive, got {height}x{width}")
    if factor <= 0:
        raise ValueError("factor must be positive")
    if min_pixels <= 0 or min_pixels > max_pixels:
        raise ValueError(f"need 0 < min_pixels <= max_pixels, got {min_pixels}, {max_pixels}")
    if max(height, width) / min(height, width) > _MAX_ASPECT:
        raise ValueError(f"absolute aspect ratio must be smaller than {_MAX_ASPECT:g}, got {height}x{width}")
    h_bar = round(height / factor) * factor
    w_bar = round(width / factor) * factor
    if h_bar * w_bar > max_pixels:
        beta = math.sqrt((height * width) / max_pixels)
        h_bar = max(factor, math.floor(height / beta / factor) * factor)
        w_bar = max(factor, math.floor(width / beta / factor) * factor)
    elif h_bar * w_bar < min_pixels:
        beta = math.sqrt(min_pixels / (height * width))
        h_bar = math.ceil(height * beta / factor) * factor
        w_bar = math.ceil(width * beta / factor) * factor
    return h_bar, w_bar


def visual_tokens(resized_hw: tuple[int, int], factor: int = QWEN_FACTOR) -> int:
    """Number of LLM tokens the image costs after patch merging: (H'/28)*(W'/28)."""
    return (resized_hw[0] // factor) * (resized_hw[1] // factor)


def box_to_original(
    box: tuple[float, float, float, float],
    *,
    coords: CoordSystem,
    resized_hw: tuple[int, int],
    original_hw: tuple[int, int],
) -> tuple[float, float, float, float]:
    """Map an (x1, y1, x2, y2) box from the model's coordinates to original-image pixels."""
    oh, ow = original_hw
    if coords is CoordSystem.NORM_1000:
        sx, sy = ow / 1000.0, oh / 1000.0
    else:
        rh, rw = resized_hw
        sx, sy = ow / rw, oh / rh
    x1, y1, x2, y2 = box
    return (x1 * sx, y1 * sy, x2 * sx, y2 * sy)
