"""Prompts the VLM node sends.

``describe`` mode sends the user's prompt (the VLM article's Chinese scene
description prompt by default). ``detect`` mode asks for Qwen2.5-VL's native
grounding format -- a JSON list of ``{"bbox_2d": [x1, y1, x2, y2], "label": ...}``
-- which the model was trained to emit, so no custom output grammar is needed.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["DEFAULT_PROMPT", "build_prompt", "detect_prompt"]

# From the VLM article's node (section 3.2): "describe the scene, point out object colours, shapes, positions".
DEFAULT_PROMPT = "描述图片中的场景,指出物体颜色、形状和位置。"


def detect_prompt(labels: Sequence[str]) -> str:
    """Qwen2.5-VL grounding prompt, for the given labels or for every object."""
    clean = [lab.strip() for lab in labels if lab and lab.strip()]
    if clean:
        what = "Locate every object of these categories in the image: " + ", ".join(clean) + "."
    else:
        what = "Detect all objects in the image."
    return what + " Output their bounding boxes as JSON: a list of objects with bbox_2d [x1, y1, x2, y2] and label."


def build_prompt(mode: str, prompt: str, labels: Sequence[str]) -> str:
    """The text part of the user message for ``mode`` (``describe`` or ``detect``)."""
    if mode == "detect":
        return detect_prompt(labels)
    return prompt or DEFAULT_PROMPT
