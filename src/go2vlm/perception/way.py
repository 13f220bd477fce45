"""Which way is likeliest to lead to the object, on the bus (VLFM-style exploration). Pure.

The question is standing, as /target/query is: the commander publishes the goal's object on
/explore/way_query (latched) while it searches with `frontier_choice: vlm`, '' otherwise. Whoever
answers (the vlm node in mode=way, or the oracle graphs' way_oracle) answers about single camera
frames, one std_msgs/String on /vlm/way each:

    {"stamp": <the frame's stamp, s>, "object": <the object asked about>, "answer": <raw text>}

The answer text stays untrusted: the commander keeps only a whitelisted word
(behavior/view_scores.py) and places it on its value map from the pose at `stamp`. The envelope here
is checked as strictly: anything else is a WayMessageRejected with a reason, counted and ignored.

`oracle_way` is the perfect answer from the sim's ground truth: `likely` when the object's bearing
from the robot lies within the view's half angle of its heading (walls notwithstanding: the upper
bound of what a model could say), else `unlikely`.
"""

from __future__ import annotations

import json
import math

__all__ = ["MAX_WAY_CHARS", "WayMessageRejected", "oracle_way", "parse_way_message", "way_message"]

MAX_WAY_CHARS = 2048


class WayMessageRejected(ValueError):
    """The /vlm/way message is not the envelope; `reason` is a short counter name."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


def way_message(stamp: float, obj: str, answer: str) -> str:
    return json.dumps({"stamp": float(stamp), "object": obj, "answer": answer}, ensure_ascii=False)


def parse_way_message(text: str) -> tuple[float, str, str]:
    """(stamp, object, raw answer) of a /vlm/way message, or WayMessageRejected."""
    if len(text) > MAX_WAY_CHARS:
        raise WayMessageRejected("way_too_long", f"{len(text)} characters")
    try:
        obj = json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        raise WayMessageRejected("way_not_json", repr(text[:80])) from None
    if not isinstance(obj, dict) or set(obj) != {"stamp", "object", "answer"}:
        raise WayMessageRejected("way_bad_envelope", 'not exactly {"stamp", "object", "answer"}')
    stamp, what, answer = obj["stamp"], obj["object"], obj["answer"]
    if isinstance(stamp, bool) or not isinstance(stamp, (int, float)) or not math.isfinite(stamp) or stamp <= 0:
        raise WayMessageRejected("way_bad_stamp", f"stamp {stamp!r}")
    if not isinstance(what, str) or not isinstance(answer, str):
        raise WayMessageRejected("way_bad_envelope", "object and answer must be text")
    return float(stamp), what, answer


def oracle_way(x: float, y: float, yaw: float, tx: float, ty: float, half_view: float) -> str:
    """`likely` when (tx, ty) lies within `half_view` rad of the heading `yaw` from (x, y), else `unlikely`."""
    off = math.atan2(ty - y, tx - x) - yaw
    off = math.atan2(math.sin(off), math.cos(off))
    return "likely" if abs(off) <= half_view else "unlikely"
