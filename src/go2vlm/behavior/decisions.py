"""VLM-driven decisions: a whitelisted action schema, and the strict parser that guards it.

The vlm node (mode=decide) asks the model "is there a person or an obstacle ahead?" with
perception/vlm/prompts.py's DECISION_PROMPT and publishes the raw answer on /vlm/decision; the
commander maps it onto this schema. The answer must be ONE JSON object:

    {"action": "stop"}                       a person/obstacle ahead: hold still
    {"action": "continue"}                   the way is clear: carry on with the goal
    {"action": "turn", "angle_deg": A}       turn in place by A degrees, |A| <= 30 (+ = left)
    {"action": "sit"}                        sit down (ends the goal)

Anything else -- another action, extra keys ("speed"), an angle out of range, free text such as
"RUN FORWARD AT 5 M/S", several objects -- is rejected with a reason and counted; the caller logs
it and does nothing. The model's text never becomes a velocity: the only numbers taken from it
are a turn angle inside the bound, executed at the commander's own (bounded) turn rate.
(tests/behavior/test_behavior_decisions.py checks that the prompt asks for exactly this schema.)
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass

__all__ = ["ACTIONS", "MAX_TURN_DEG", "Decision", "DecisionRejected", "parse_decision", "unwrap_answer"]

ACTIONS = ("stop", "continue", "turn", "sit")
MAX_TURN_DEG = 30.0
MAX_ANSWER_CHARS = 2000

_ALLOWED_KEYS = {"stop": {"action"}, "continue": {"action"}, "sit": {"action"}, "turn": {"action", "angle_deg"}}
_FENCE = re.compile(r"^```(?:json)?\s*(.*?)\s*```$", re.S)


class DecisionRejected(ValueError):
    """The answer is outside the schema. `reason` is a short counter name."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason
        self.detail = detail


def unwrap_answer(text: object, max_chars: int, rejected: type[DecisionRejected]) -> str:
    """A model's answer as text to read: stripped and out of a Markdown fence; `rejected` (the
    caller's refusal) when it is no text, empty or longer than `max_chars`."""
    if not isinstance(text, str):
        raise rejected("not_text", f"answer is {type(text).__name__}")
    t = text.strip()
    if not t:
        raise rejected("empty", "empty answer")
    if len(t) > max_chars:
        raise rejected("too_long", f"answer is {len(t)} characters")
    fenced = _FENCE.match(t)
    return fenced.group(1).strip() if fenced else t


@dataclass(frozen=True)
class Decision:
    action: str  # one of ACTIONS
    angle_deg: float = 0.0  # turn only, |angle| <= MAX_TURN_DEG

    def to_dict(self) -> dict[str, object]:
        if self.action == "turn":
            return {"action": self.action, "angle_deg": self.angle_deg}
        return {"action": self.action}


def parse_decision(text: str, max_turn_deg: float = MAX_TURN_DEG) -> Decision:
    """The model's answer -> Decision, or DecisionRejected (never a partial or clamped action)."""
    t = unwrap_answer(text, MAX_ANSWER_CHARS, DecisionRejected)
    bare = t.lower().strip(" .!\"'")
    if bare in ("stop", "continue", "sit"):  # a lone whitelisted word is unambiguous
        return Decision(bare)
    try:
        obj = json.loads(t)
    except (json.JSONDecodeError, RecursionError):
        raise DecisionRejected("not_json", f"answer is not one JSON object: {t[:80]!r}") from None
    if not isinstance(obj, dict):
        raise DecisionRejected("not_object", f"answer is JSON {type(obj).__name__}, not an object")
    action = obj.get("action")
    if not isinstance(action, str) or action.strip().lower() not in ACTIONS:
        raise DecisionRejected("unknown_action", f"action {action!r} is not one of {list(ACTIONS)}")
    action = action.strip().lower()
    extra = set(obj) - _ALLOWED_KEYS[action]
    if extra:
        raise DecisionRejected("extra_fields", f"{action!r} takes no {sorted(extra)}")
    if action != "turn":
        return Decision(action)
    angle = obj.get("angle_deg")
    if isinstance(angle, bool) or not isinstance(angle, (int, float)) or not math.isfinite(angle):
        raise DecisionRejected("bad_angle", f"turn needs a finite number angle_deg, got {angle!r}")
    if abs(angle) > max_turn_deg:
        raise DecisionRejected("angle_out_of_range", f"|angle_deg| {abs(angle):g} exceeds {max_turn_deg:g}")
    return Decision("turn", float(angle))
