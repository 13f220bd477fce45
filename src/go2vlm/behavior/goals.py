"""Language goals -> a small typed `Goal`: follow / go to / look for an object, stop, sit, stand,
and a bounded turn in place ("turn left 20 degrees", 向左转20度: |angle| <= MAX_TURN_DEG, the VLM
decisions' whitelisted turn).

English and Chinese, common phrasings ("follow the red ball", "find the yellow ball", 跟着红球,
走到蓝色圆柱, 找一下绿色盒子, 停下, 坐下, 站起来). Anything else is a `GoalParseError` whose
message says what was understood and what is accepted; the commander then replies and does not move.

A negated command ("don't go", 别动, 不要走) is read as `stop`: when in doubt, the safe reading.
"""

from __future__ import annotations

import re
import unicodedata
from dataclasses import dataclass

from go2vlm.behavior.decisions import MAX_TURN_DEG
from go2vlm.errors import UsageError
from go2vlm.vocabulary.words import (
    COLORS,
    EN_COLOR_WORDS,
    EN_SHAPE_WORDS,
    POSTURES,
    SHAPES,
    ZH_COLOR_WORDS,
    ZH_SHAPE_WORDS,
)

__all__ = [
    "COLORS",
    "GOAL_KINDS",
    "MOTION_KINDS",
    "POSTURE_GOALS",
    "SHAPES",
    "TIMED_KINDS",
    "Goal",
    "GoalParseError",
    "Target",
    "parse_goal",
    "parse_target",
    "unknown_words",
]

GOAL_KINDS = ("follow", "go_to", "look_for", "stop", "sit", "stand", "turn")
MOTION_KINDS = ("follow", "go_to", "look_for")  # kinds that need a target
TIMED_KINDS = (*MOTION_KINDS, "turn")  # kinds that run for a while (the commander is busy)
# The words are the vocabulary's (go2vlm/vocabulary/words.py), the same objects.
_EN_COLORS = EN_COLOR_WORDS
_EN_SHAPES = EN_SHAPE_WORDS
_ZH_COLORS = ZH_COLOR_WORDS
_ZH_SHAPES = ZH_SHAPE_WORDS
POSTURE_GOALS = ("sit", "stand")  # goal kinds sent as they are on /go2/command: words of POSTURES
if not set(POSTURE_GOALS) <= set(POSTURES):
    raise ImportError(f"posture goals {POSTURE_GOALS} are not all robot postures {POSTURES}")

_EN_FILLER = {
    "the", "a", "an", "that", "this", "some", "one", "please", "robot", "dog", "go2", "object", "thing",
    "colored", "coloured", "color", "colour", "me", "my", "it", "now", "there", "again", "then",
}  # fmt: skip
# (regex on the normalised English text, kind); first match wins, so multi-word verbs come first.
_EN_VERBS: list[tuple[str, str]] = [
    (r"(?:keep )?follow(?:ing)?|track|chase|keep up with|go after|come after|stay with", "follow"),
    (r"look(?:ing)? (?:for|around for)|search(?:ing)? (?:for)?|find|locate|seek|scan for|where is", "look_for"),
    (
        r"(?:go|walk|move|run|head|navigate|drive|come|get)(?: over)? (?:to|towards?|up to|close to|near)"
        r"|approach|reach",
        "go_to",
    ),
]
_EN_STOP = re.compile(
    r"^(?:stop(?: moving| walking| now| it| there| everything)?|halt|freeze|stay(?: there| put| still)?|wait|"
    r"hold(?: on| still| position)?|cancel|abort|enough|emergency stop|e stop|estop)$"
)
_EN_SIT = re.compile(r"^(?:sit(?: down)?|lie down|lay down|down)$")
_EN_STAND = re.compile(r"^(?:stand(?: up)?|get up|rise|stand still up)$")
_EN_NEG = re.compile(r"^(?:do not|dont|don t|never|no)\b")
_EN_POLITE = re.compile(
    r"^(?:(?:please|ok|okay|hey|robot|go2|dog|now|and|then|so)\s+|(?:can|could|would|will) you\s+|"
    r"i want you to\s+|i d like you to\s+|try to\s+|go and\s+|you should\s+)+"
)

_ZH_POLITE = ("请你", "请", "麻烦你", "麻烦", "帮我", "给我", "你去", "你", "现在", "机器狗", "小狗", "狗狗", "然后")
_ZH_TAIL = ("一下", "好吗", "好不好", "可以吗", "吧", "啊", "呀", "了", "哦", "呢", "喔")
_ZH_STOP: tuple[str, ...] = ("停下来", "停下", "停止", "停住", "停", "别动", "不要动", "站住", "别走", "不要走")
_ZH_STOP += ("等一下", "等等", "急停", "刹车")
_ZH_SIT = ("坐下来", "坐下", "坐好", "坐", "趴下")
_ZH_STAND = ("站起来", "站起", "站立", "起立", "起来", "站好")
# Matched before _normalise_en, which would drop a minus sign and a decimal point.
_EN_TURN = re.compile(
    r"^(?:please )?turn(?: in place)?(?: to the)?(?: (?P<side>left|right))?(?: by)? ?(?P<num>[+-]?\d+(?:\.\d+)?)"
    r" ?(?:°|degrees?|deg)?(?: to the)?(?: (?P<side2>left|right))?(?: please)?[.!]?$"
)
# Matched before the punctuation is stripped, which would make 1.5 度 into 15.
_ZH_TURN = re.compile(r"^(?:请|请你)?(?:向|往)?(?P<side>左|右)?转(?:身)?(?P<num>[+-]?\d+(?:\.\d+)?)度?[。.!]?$")
_ZH_VERBS: list[tuple[str, str]] = [
    ("跟着", "follow"), ("跟随", "follow"), ("跟踪", "follow"), ("追着", "follow"), ("追踪", "follow"),
    ("追", "follow"), ("跟", "follow"),
    ("去找", "look_for"), ("找一下", "look_for"), ("找找", "look_for"), ("寻找", "look_for"),
    ("搜索", "look_for"), ("查找", "look_for"),
    ("找到", "look_for"), ("找", "look_for"), ("看看", "look_for"),
    ("走到", "go_to"), ("走向", "go_to"), ("走去", "go_to"), ("走过去", "go_to"), ("移动到", "go_to"),
    ("前往", "go_to"), ("靠近", "go_to"), ("接近", "go_to"), ("过去", "go_to"), ("跑到", "go_to"),
    ("到", "go_to"), ("去", "go_to"),
]  # fmt: skip
_ZH_NEG = ("不要", "别", "不准", "不许", "禁止")
_ZH_OBJ_FILLER = ("那个", "这个", "一个", "颜色", "色的", "色", "的", "个", "那", "这", "在哪里", "在哪儿", "在哪")

MAX_GOAL_CHARS = 200


class GoalParseError(UsageError):
    """The goal text was not understood; the message is the reply for /commander/status."""


@dataclass(frozen=True)
class Target:
    """What to look for. `color`/`shape` are from COLORS/SHAPES or None (any); `label` is free
    text for a VLM ("red ball", "person")."""

    label: str
    color: str | None = None
    shape: str | None = None

    @property
    def classical(self) -> bool:
        """True if the colour-shape grounder can find it (a known colour, shape optional)."""
        return self.color is not None or self.shape is not None


@dataclass(frozen=True)
class Goal:
    kind: str  # one of GOAL_KINDS
    target: Target | None = None
    text: str = ""
    angle_deg: float = 0.0  # turn: + = left, |angle| <= MAX_TURN_DEG

    @property
    def moves(self) -> bool:
        return self.kind in MOTION_KINDS

    def describe(self) -> str:
        if self.kind == "turn":
            return f"turn {self.angle_deg:+g} deg"
        return f"{self.kind} {self.target.label}" if self.target else self.kind


def _is_cjk(text: str) -> bool:
    return any("\u4e00" <= ch <= "\u9fff" for ch in text)


def _normalise_en(text: str) -> str:
    t = unicodedata.normalize("NFKC", text).lower()
    t = re.sub(r"[^a-z0-9\s]", " ", t)
    return re.sub(r"\s+", " ", t).strip()


def _target_from_words(words: list[str], raw: str) -> Target:
    color = shape = None
    rest = []
    for w in words:
        if w in _EN_COLORS and color is None:
            color = _EN_COLORS[w]
        elif w in _EN_SHAPES and shape is None:
            shape = _EN_SHAPES[w]
        elif w not in _EN_FILLER:
            rest.append(w)
    if color is None and shape is None and not rest:
        raise GoalParseError(f"no object named in {raw!r}; say e.g. 'the red ball' or 'the blue cylinder'")
    if rest:
        # A category or a referring phrase ("teddy bear", "soccer ball", "ball under the table", "red
        # object nearest the door") is kept whole for a VLM; the colour and shape it names, if any,
        # are what the colour-shape grounder can still try.
        lo, hi = 0, len(words)
        while words[lo] in _EN_FILLER:
            lo += 1
        while words[hi - 1] in _EN_FILLER:
            hi -= 1
        return Target(label=" ".join(words[lo:hi]), color=color, shape=shape)
    label = " ".join(x for x in (color, shape) if x)
    return Target(label=label, color=color, shape=shape)


def _target_zh(phrase: str, raw: str) -> Target:
    p = phrase
    color = shape = None
    for ch, name in _ZH_COLORS.items():
        if ch in p:
            color = name
            p = p.replace(ch, "", 1)
            break
    for word, name in _ZH_SHAPES:
        if word in p:
            shape = name
            p = p.replace(word, "", 1)
            break
    for filler in _ZH_OBJ_FILLER:
        p = p.replace(filler, "")
    p = p.strip()
    if color is None and shape is None:
        if not p:
            raise GoalParseError(f"no object named in {raw!r}; say e.g. 红球 or 蓝色圆柱")
        return Target(label=p)
    label = " ".join(x for x in (color, shape) if x)
    return Target(label=label, color=color, shape=shape)


def parse_target(phrase: str) -> Target:
    """An object phrase alone ("red ball", 蓝色圆柱) -> Target."""
    if _is_cjk(phrase):
        return _target_zh(re.sub(r"\s+", "", phrase), phrase)
    return _target_from_words(_normalise_en(phrase).split(), phrase)


def unknown_words(phrase: str) -> list[str]:
    """Words of an English object phrase that are no colour, shape or filler: "purple" in "purple ball",
    which parse_target passes over (it finds "ball"). Chinese phrases: none."""
    if _is_cjk(phrase):
        return []
    return [
        w for w in _normalise_en(phrase).split() if w not in _EN_COLORS and w not in _EN_SHAPES and w not in _EN_FILLER
    ]


def _parse_zh(raw: str) -> Goal:
    t = unicodedata.normalize("NFKC", raw)
    t = re.sub(r"[\s,.!?;:\"'\u3001\u3002\uff01\uff0c\uff1a\uff1b\uff1f\u201c\u201d\u2018\u2019~]+", "", t)
    changed = True
    while changed:
        changed = False
        for p in _ZH_POLITE:
            if t.startswith(p) and len(t) > len(p):
                t, changed = t[len(p) :], True
        for s in _ZH_TAIL:
            if t.endswith(s) and len(t) > len(s):
                t, changed = t[: -len(s)], True
    if not t:
        raise GoalParseError(f"empty goal {raw!r}")
    if t.startswith(_ZH_NEG):
        return Goal("stop", None, raw)
    if t in _ZH_STOP or t.startswith(("停", "急停", "别动", "站住")):
        return Goal("stop", None, raw)
    if t in _ZH_SIT:
        return Goal("sit", None, raw)
    if t in _ZH_STAND:
        return Goal("stand", None, raw)
    turn = _ZH_TURN.match(re.sub(r"\s+", "", unicodedata.normalize("NFKC", raw)))
    if turn:
        return _turn_goal(turn["num"], {"左": "left", "右": "right"}.get(turn["side"] or ""), raw)
    # The verb starts the command, after at most a short lead-in (我要你, 快): earliest, then longest.
    found = [(t.find(v), -len(v), v, k) for v, k in _ZH_VERBS if 0 <= t.find(v) <= 3]
    if found:
        idx, _, verb, kind = min(found)
        obj = t[idx + len(verb) :]
        for s in _ZH_TAIL:
            if obj.startswith(s):
                obj = obj[len(s) :]
        if not obj:
            raise GoalParseError(f"{verb}什么? no object named in {raw!r}; say e.g. {verb}红球")
        return Goal(kind, _target_zh(obj, raw), raw)
    raise GoalParseError(f"不理解 {raw!r}: {_ACCEPTED}")


_ACCEPTED = (
    "accepted goals: follow <object>, go to <object>, look for <object>, stop, sit, stand, turn left|right "
    f"<0-{MAX_TURN_DEG:g}> degrees (跟着/走到/找 <物体>, 停, 坐下, 站起来, 向左转20度); objects: "
    "red/green/blue/yellow ball/box/cylinder"
)


def _turn_goal(number: str, side: str | None, raw: str) -> Goal:
    """A turn of `number` degrees (+ = left, or unsigned with a side), bounded like a VLM decision's turn."""
    if side is not None and number[:1] in "+-":
        raise GoalParseError(f"say left or right, or give a signed angle, not both ({raw!r})")
    angle = -float(number) if side == "right" else float(number)
    if not abs(angle) <= MAX_TURN_DEG:
        raise GoalParseError(f"a turn is at most {MAX_TURN_DEG:g} degrees either way, not {angle:g} ({raw!r})")
    return Goal("turn", None, raw, angle_deg=angle)


def _parse_en(raw: str) -> Goal:
    t = _normalise_en(raw)
    t = t.replace("don t", "dont").replace("can t", "cant")
    t = _EN_POLITE.sub("", t).strip()
    if not t:
        raise GoalParseError(f"empty goal {raw!r}; {_ACCEPTED}")
    if _EN_NEG.match(t):
        return Goal("stop", None, raw)
    if _EN_STOP.match(t) or re.match(r"^(?:stop|halt|freeze|abort|cancel)\b", t):
        return Goal("stop", None, raw)
    if _EN_SIT.match(t):
        return Goal("sit", None, raw)
    if _EN_STAND.match(t):
        return Goal("stand", None, raw)
    if t == "turn" or t.startswith("turn "):
        lite = _EN_POLITE.sub("", re.sub(r"\s+", " ", unicodedata.normalize("NFKC", raw).lower()).strip())
        turn = _EN_TURN.match(lite)
        if turn is None:
            raise GoalParseError(
                f"turn how far? say e.g. 'turn left 20 degrees' (at most {MAX_TURN_DEG:g}); got {raw!r}"
            )
        sides = {turn["side"], turn["side2"]} - {None}
        if len(sides) > 1:
            raise GoalParseError(f"turn left or right, not both ({raw!r})")
        return _turn_goal(turn["num"], sides.pop() if sides else None, raw)
    for pattern, kind in _EN_VERBS:
        m = re.match(rf"^(?:{pattern})\b\s*(.*)$", t)
        if m:
            obj = m.group(1).strip()
            if not obj:
                raise GoalParseError(f"{kind.replace('_', ' ')} what? no object named in {raw!r}")
            return Goal(kind, _target_from_words(obj.split(), raw), raw)
    raise GoalParseError(f"cannot understand {raw!r}; {_ACCEPTED}")


def parse_goal(text: str) -> Goal:
    """Parse one goal. Raises GoalParseError (with the reply text) if it is not understood."""
    if not isinstance(text, str):
        raise GoalParseError(f"goal must be text, got {type(text).__name__}")
    raw = text.strip()
    if not raw:
        raise GoalParseError(f"empty goal; {_ACCEPTED}")
    if len(raw) > MAX_GOAL_CHARS:
        raise GoalParseError(f"goal is {len(raw)} characters long; at most {MAX_GOAL_CHARS} are accepted")
    if any(unicodedata.category(ch) == "Cc" and ch not in "\t\n\r" for ch in raw):
        raise GoalParseError("goal contains control characters")
    return _parse_zh(raw) if _is_cjk(raw) else _parse_en(raw)
