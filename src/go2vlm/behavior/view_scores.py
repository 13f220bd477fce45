"""Which way is likeliest to lead to the object: the model's answers about views, VLFM-style, for
exploration's `frontier_choice: vlm` (behavior/strategies/explore.py). Pure.

The model is shown one camera view and asked how likely walking that way leads to the object. The
answer must be ONE of a whitelist, a bare word or one JSON object:

    likely | maybe | unlikely          or   {"way": "likely"}    (any case; a code fence is stripped)

Anything else (another word, a number, extra keys, free text such as "go left through the door at
2 m/s") is rejected with a reason and counted, as decisions are (behavior/decisions.py): the text
never becomes a motion, only one of three scores (1.0, 0.5, 0.0) for the view.

The score is placed in the world by world/value_map.py (VLFM's value map: spread over what the
view could see, blended by confidence), and exploration takes the frontier it values highest, the
nearest by path cost among equals.
"""

from __future__ import annotations

import json

from go2vlm.behavior.decisions import DecisionRejected, unwrap_answer

__all__ = ["SCORES", "ViewAnswerRejected", "parse_view_answer"]

SCORES = {"likely": 1.0, "maybe": 0.5, "unlikely": 0.0}
MAX_ANSWER_CHARS = 200


class ViewAnswerRejected(DecisionRejected):
    """The answer is outside the whitelist; `reason` is a short counter name."""


def parse_view_answer(text: object) -> float:
    """The model's answer -> its score (1.0 likely, 0.5 maybe, 0.0 unlikely), or ViewAnswerRejected."""
    t = unwrap_answer(text, MAX_ANSWER_CHARS, ViewAnswerRejected)
    bare = t.lower().strip(" .!\"'")
    if bare in SCORES:
        return SCORES[bare]
    try:
        obj = json.loads(t)
    except (json.JSONDecodeError, RecursionError):
        raise ViewAnswerRejected("not_whitelisted", f"not one of {list(SCORES)}: {t[:80]!r}") from None
    if not isinstance(obj, dict) or set(obj) != {"way"}:
        raise ViewAnswerRejected("bad_object", 'an object must be exactly {"way": <word>}')
    way = obj["way"]
    if not isinstance(way, str) or way.strip().lower() not in SCORES:
        raise ViewAnswerRejected("not_whitelisted", f"way {way!r} is not one of {list(SCORES)}")
    return SCORES[way.strip().lower()]
