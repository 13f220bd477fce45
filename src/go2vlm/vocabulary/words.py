"""The words, written once: colours, shapes and postures, with their synonyms and what each stands for.

Every module that reads or writes one of these words takes it from here: the goal parser
(behavior/goals.py), the colour-shape grounder and the HSV presets (perception/grounding.py, color.py),
the tracker's labels (perception/tracking.py), ranging's sizes, the object memory's labels and markers
(world/), the MCP rules and the robot ends' posture commands (robots/go2/protocol.py, the sim).
tests/vocabulary/test_vocabulary_words.py fails when a module keeps a word list of its own.

Pure data and string functions: imports nothing of the project, so every floor may use it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Final

__all__ = [
    "BODY_SHAPE_WORDS",
    "COLORS",
    "COLOR_HSV",
    "COLOR_RGB",
    "EN_COLOR_WORDS",
    "EN_SHAPE_WORDS",
    "POSTURES",
    "POSTURE_HELP",
    "ROUND_SHAPES",
    "SHAPES",
    "ZH_COLOR_WORDS",
    "ZH_SHAPE_WORDS",
    "Hsv",
    "HsvRange",
    "Label",
    "label_match",
    "label_words",
    "parse_label",
]

Hsv = tuple[int, int, int]
HsvRange = tuple[Hsv, Hsv]

# -- colours: name -> OpenCV HSV ranges (hue 0..179) and a marker's RGB ------------------------
# Red is the follow article's pair of ranges (it wraps around hue 0); the others are common
# starting points to tune on site.
COLOR_HSV: Final[Mapping[str, tuple[HsvRange, ...]]] = MappingProxyType({
    "red": (((0, 120, 70), (10, 255, 255)), ((170, 120, 70), (180, 255, 255))),
    "green": (((35, 80, 60), (85, 255, 255)),),
    "blue": (((100, 120, 60), (130, 255, 255)),),
    "yellow": (((20, 120, 100), (35, 255, 255)),),
})  # fmt: skip
COLORS: Final[tuple[str, ...]] = tuple(COLOR_HSV)
COLOR_RGB: Final[Mapping[str, tuple[float, float, float]]] = MappingProxyType({
    "red": (0.9, 0.1, 0.1), "green": (0.1, 0.8, 0.1), "blue": (0.1, 0.3, 0.95), "yellow": (0.95, 0.85, 0.1),
})  # fmt: skip
# What a goal may call a colour (English words, Chinese characters) -> the colour.
EN_COLOR_WORDS: Final[Mapping[str, str]] = MappingProxyType({
    "red": "red", "crimson": "red", "scarlet": "red",
    "green": "green", "lime": "green",
    "blue": "blue", "navy": "blue",
    "yellow": "yellow", "golden": "yellow",
})  # fmt: skip
ZH_COLOR_WORDS: Final[Mapping[str, str]] = MappingProxyType(
    {"红": "red", "绿": "green", "綠": "green", "蓝": "blue", "藍": "blue", "黄": "yellow", "黃": "yellow"}
)

# -- shapes: the colour-shape grounder's shapes ------------------------------------------------
SHAPES: Final[tuple[str, ...]] = ("ball", "box", "cylinder")
ROUND_SHAPES: Final[tuple[str, ...]] = ("ball", "cylinder")  # round seen from any side: sized by a radius
EN_SHAPE_WORDS: Final[Mapping[str, str]] = MappingProxyType({
    "ball": "ball", "balls": "ball", "sphere": "ball", "spheres": "ball", "orb": "ball", "circle": "ball",
    "box": "box", "boxes": "box", "cube": "box", "cubes": "box", "block": "box", "blocks": "box",
    "crate": "box", "square": "box",
    "cylinder": "cylinder", "cylinders": "cylinder", "pillar": "cylinder", "column": "cylinder",
    "can": "cylinder", "tube": "cylinder", "pole": "cylinder", "post": "cylinder",
})  # fmt: skip
# Chinese: longest first so 圆柱体 wins over 圆柱, 圆球 over 球.
ZH_SHAPE_WORDS: Final[tuple[tuple[str, str], ...]] = (
    ("圆柱体", "cylinder"), ("圆柱", "cylinder"), ("柱子", "cylinder"), ("柱体", "cylinder"), ("罐子", "cylinder"),
    ("立方体", "box"), ("正方体", "box"), ("箱子", "box"), ("盒子", "box"), ("方块", "box"), ("方盒", "box"),
    ("圆球", "ball"), ("球体", "ball"), ("小球", "ball"), ("球", "ball"), ("箱", "box"), ("盒", "box"),
)  # fmt: skip
# A label (an answer's, a body name such as `red_sphere`) reads only these synonyms: a VLM's "post"
# or "block" is free text there, not a shape.
BODY_SHAPE_WORDS: Final[Mapping[str, str]] = MappingProxyType({"sphere": "ball", "cube": "box"})

# -- postures: the words on /go2/command (bus/topics.py GO2_COMMAND) ---------------------------
# Every robot end (the go2 driver, the sim) takes exactly these; robots/go2/protocol.py maps each to
# sport API calls and refuses to load if the two lists differ. Goals "sit" and "stand" send two of them.
POSTURE_HELP: Final[Mapping[str, str]] = MappingProxyType({
    "stand": "stand up and balance (accepts velocity commands)",
    "balance": "balance stand",
    "sit": "sit down",
    "rise": "rise from sitting",
    "standdown": "lie down (joints locked)",
    "damp": "damp all joints (the robot sinks)",
    "recover": "recovery stand (after a fall)",
    "hello": "wave hello",
    "stop": "stop moving",
})  # fmt: skip
POSTURES: Final[tuple[str, ...]] = tuple(POSTURE_HELP)


@dataclass(frozen=True)
class Label:
    """What a query or an answer names: the grounder's colour and shape words, if any, and the text."""

    text: str
    color: str | None = None
    shape: str | None = None

    @property
    def classical(self) -> bool:
        """The colour-shape grounder can find it (it names a colour or a shape it knows)."""
        return self.color is not None or self.shape is not None


def label_words(text: str) -> list[str]:
    """Lower-case words, with `_` and punctuation as spaces ("red_sphere" -> ["red", "sphere"])."""
    return re.sub(r"[\W_]+", " ", text.lower()).split()


def parse_label(text: str) -> Label:
    """ "blue cylinder" (or "blue_cylinder") -> Label(color="blue", shape="cylinder"); "person" -> free text."""
    words = label_words(text)
    color = next((w for w in words if w in COLOR_HSV), None)
    shape = next((BODY_SHAPE_WORDS.get(w, w) for w in words if BODY_SHAPE_WORDS.get(w, w) in SHAPES), None)
    return Label(" ".join(text.split()), color, shape)


def label_match(query: Label, label: str) -> int:
    """How well an answer's label names the query: 2 exactly, 1 compatibly, 0 not at all. With a
    colour or shape in the query, the answer's must agree ("red box" is not "red ball", "box" is not
    "red box"); free text matches when all its words are in the answer's label."""
    if not label.strip():
        return 0
    other = parse_label(label)
    if query.classical:
        if query.color is not None and other.color != query.color:
            return 0
        if query.shape is not None and other.shape != query.shape:
            return 0
        return 2 if (other.color, other.shape) == (query.color, query.shape) else 1
    want, have = set(label_words(query.text)), set(label_words(label))
    if not want or not want <= have:
        return 0
    return 2 if have == want else 1
