"""Prompts the VLM node sends.

``describe`` mode sends the user's prompt (the VLM article's Chinese scene
description prompt by default). ``detect`` mode asks for Qwen2.5-VL's native
grounding format -- a JSON list of ``{"bbox_2d": [x1, y1, x2, y2], "label": ...}``
-- which the model was trained to emit, so no custom output grammar is needed; with a
query (/target/query) it grounds exactly that label. ``decide`` mode asks the scene
question whose answer schema behavior/decisions.py enforces (the commander parses it). ``way`` mode
asks whether walking the way the camera faces is likely to lead to the object the commander looks for
(/explore/way_query); the commander keeps only likely / maybe / unlikely (behavior/view_scores.py).
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["DECISION_PROMPT", "DEFAULT_PROMPT", "build_prompt", "detect_prompt", "way_prompt"]

# From the VLM article's node (section 3.2): "describe the scene, point out object colours, shapes, positions".
DEFAULT_PROMPT = "描述图片中的场景,指出物体颜色、形状和位置。"

# decide mode: one whitelisted action as JSON (the schema of behavior/decisions.py, |angle| <= 30 deg).
DECISION_PROMPT = (
    "You watch the camera of a walking quadruped robot. Is there a person or an obstacle ahead? "
    "Answer with exactly one JSON object and nothing else: "
    '{"action": "stop"} if a person or an obstacle is close ahead, '
    '{"action": "continue"} if the way ahead is clear, '
    '{"action": "turn", "angle_deg": A} with A between -30 and 30 (positive = left) to steer around it, '
    'or {"action": "sit"}.'
)


def way_prompt(obj: str) -> str:
    """way mode: one whitelisted word about walking the way this view faces (VLFM-style exploration)."""
    return (
        f"You see the camera of a robot in a house, searching for: {obj}. If the robot walks the way this "
        f"view faces, how likely is it to find the {obj}? Think of which room this way leads to and what is "
        "usually found there. Answer with exactly one word: likely, maybe or unlikely."
    )


def detect_prompt(labels: Sequence[str]) -> str:
    """Qwen2.5-VL grounding prompt, for the given labels or for every object."""
    clean = [lab.strip() for lab in labels if lab and lab.strip()]
    if clean:
        what = "Locate every object of these categories in the image: " + ", ".join(clean) + "."
    else:
        what = "Detect all objects in the image."
    return what + " Output their bounding boxes as JSON: a list of objects with bbox_2d [x1, y1, x2, y2] and label."


def build_prompt(mode: str, prompt: str, labels: Sequence[str]) -> str:
    """The text part of the user message for ``mode`` (``describe``, ``detect``, ``decide`` or ``way``)."""
    if mode == "detect":
        return detect_prompt(labels)
    if mode == "decide":
        return DECISION_PROMPT
    if mode == "way":
        return way_prompt(labels[0] if labels else "the object")
    return prompt or DEFAULT_PROMPT
