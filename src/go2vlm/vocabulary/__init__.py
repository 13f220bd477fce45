"""One vocabulary: the colour, shape and posture words (:mod:`.words`), a VLM's answer text -> boxes
(:mod:`.answers`) and the colour-in-box check (:mod:`.pixels`, which needs OpenCV).

A low floor: it imports nothing of the project above ``geometry/``, so perception, world, behaviour,
the robots, MCP and the benchmarks all take their words from here.
"""

from go2vlm.vocabulary.words import (
    COLOR_HSV,
    COLOR_RGB,
    COLORS,
    POSTURES,
    SHAPES,
    Label,
    label_match,
    parse_label,
)

__all__ = ["COLORS", "COLOR_HSV", "COLOR_RGB", "POSTURES", "SHAPES", "Label", "label_match", "parse_label"]
