"""Which way is likeliest to lead to the object: the model's answers about views, VLFM-style, for
exploration's `frontier_choice: vlm` (behavior/strategies/explore.py). Pure.

The model is shown one camera view and asked how likely walking that way leads to the object. The
answer must be ONE of a whitelist, a bare word or one JSON object:

    likely | maybe | unlikely          or   {"way": "likely"}    (any case; a code fence is stripped)

Anything else (another word, a number, extra keys, free text such as "go left through the door at
2 m/s") is rejected with a reason and counted, as decisions are (behavior/decisions.py): the text
never becomes a motion, only one of three scores (1.0, 0.5, 0.0) for the heading the view was taken at.

`ViewScores` keeps the scored headings (world yaw, the newest answer per `bin_deg` sector); a
frontier's score is that of the sector its bearing from the robot falls in (`unscored` where no
view was scored there). Exploration takes the highest score first, the nearest by path cost among
equals.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

from go2vlm.behavior.decisions import DecisionRejected, unwrap_answer

__all__ = ["SCORES", "ViewAnswerRejected", "ViewScores", "parse_view_answer"]

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


@dataclass
class ViewScores:
    bin_deg: float = 30.0  # headings within one sector share a score (the camera's view is ~73 deg)
    unscored: float = 0.5  # a sector no view was scored in counts as maybe
    scores: dict[int, tuple[float, float]] = field(default_factory=dict)  # sector -> (score, when)

    def _sector(self, yaw: float) -> int:
        return int(math.floor(((yaw + math.pi) % (2 * math.pi)) / math.radians(self.bin_deg)))

    def observe(self, yaw: float, score: float, t: float) -> None:
        """A scored view taken facing world `yaw` at time `t` (an older answer never overwrites a newer)."""
        if not (math.isfinite(yaw) and math.isfinite(score) and 0.0 <= score <= 1.0):
            return
        k = self._sector(yaw)
        old = self.scores.get(k)
        if old is None or t >= old[1]:
            self.scores[k] = (score, t)

    def clear(self) -> None:
        self.scores.clear()

    def score(self, yaw: float) -> float:
        hit = self.scores.get(self._sector(yaw))
        return self.unscored if hit is None else hit[0]

    def toward(self, x: float, y: float, gx: float, gy: float) -> float:
        """The score of the way from (x, y) towards (gx, gy)."""
        return self.score(math.atan2(gy - y, gx - x))
