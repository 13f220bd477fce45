"""Labels as the object memory compares them: one spelling per object, and how well a question names it.

The words are the vocabulary's (go2vlm/vocabulary/words.py: the colour-shape grounder's colours and
shapes, body names such as `red_sphere` read as "red ball"), so that an answer, a goal and a
remembered object mean the same thing by the same words.
"""

from __future__ import annotations

from go2vlm.vocabulary.words import BODY_SHAPE_WORDS, COLOR_HSV, label_match, label_words, parse_label

__all__ = ["label_fits", "normalize_label"]

MAX_LABEL = 200  # characters: a label longer than this is cut
ARTICLES = frozenset({"a", "an", "the"})  # not part of an object's name


def normalize_label(text: str) -> str:
    """One spelling per object: "<colour> <shape>" for the grounder's words alone ("red_sphere" ->
    "red ball", "Blue  Cylinder" -> "blue cylinder"); a label with more words keeps them all ("blue_mug"
    -> "blue mug", not "blue": a mug is not every blue thing); else the lower-cased words ("Person" ->
    "person")."""
    lab = parse_label(str(text)[:MAX_LABEL])
    if lab.classical:
        words = [w for w in label_words(lab.text) if w not in ARTICLES]
        if all(w in COLOR_HSV or BODY_SHAPE_WORDS.get(w, w) == lab.shape for w in words):
            return " ".join(w for w in (lab.color, lab.shape) if w)
        return " ".join(words)
    return " ".join(lab.text.lower().split())


def label_fits(query: str, label: str) -> int:
    """How well a question ("where is the ball?") names a remembered label: 2 exactly, 1 compatibly
    ("ball" fits "red ball"), 0 not at all; an empty question fits everything (1)."""
    q = normalize_label(query)
    if not q:
        return 1
    return label_match(parse_label(q), label)
