"""Turn a VLM's answer into boxes (the one answer text -> boxes path). The answer is untrusted input.

`answer_boxes(gen, labels)` is what every reader of an answer calls (the vlm node, the tiny grounder's
evaluation, the VLM benchmarks): parse, then map to the original image's pixels.

A model (or a compromised/odd server) can answer anything: fenced or bare JSON,
JSON cut off by ``max_new_tokens``, prose around it, ``NaN``, ``1e999``, a dict instead
of a list, strings where numbers belong, corners swapped, boxes outside the image,
labels nobody asked for. Every such case is sanitised or dropped and counted under
one of the ``C_*`` counter names below; nothing here raises on any input string.

Qwen2.5-VL's grounding format::

    [{"bbox_2d": [x1, y1, x2, y2], "label": "red ball"}, ...]   # optional "score"/"confidence"
"""

from __future__ import annotations

import json
import math
import re
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from go2vlm.geometry.qwen import CoordSystem, box_to_original

__all__ = [
    "COUNTERS",
    "Box",
    "ParseResult",
    "answer_boxes",
    "finalize_boxes",
    "normalise_label",
    "parse_grounding",
    "sanitize_text",
]

# Counter names (stable: they appear in /vlm/status and in tests).
C_TEXT_TOO_LONG = "parse.text_too_long"  # answer longer than max_chars, tail ignored
C_NO_JSON = "parse.no_json"  # no JSON at all in the answer
C_JSON_REPAIRED = "parse.json_repaired"  # invalid/truncated JSON, complete objects salvaged
C_NON_LIST = "parse.non_list_json"  # top level was not a list (dict wrapped, scalars dropped)
C_TOO_MANY = "parse.too_many_items"  # items beyond max_items dropped
C_ITEM_NOT_OBJECT = "parse.item_not_object"  # list element not a JSON object
C_NO_BBOX = "parse.missing_bbox"  # object without bbox_2d/bbox
C_BAD_BBOX = "parse.bad_bbox"  # bbox not 4 numbers
C_COERCED = "parse.coerced_number"  # number given as a numeric string
C_NONFINITE = "parse.nonfinite_coord"  # NaN/inf coordinate
C_HUGE = "parse.huge_coord"  # |coordinate| > MAX_ABS_COORD
C_BAD_LABEL = "parse.bad_label"  # missing/empty/non-string label
C_UNKNOWN_LABEL = "parse.unknown_label"  # label not among the requested labels
C_BAD_SCORE = "parse.bad_score"  # score not a finite number (ignored)
C_SCORE_CLIPPED = "parse.score_clipped"  # score outside [0, 1]
C_SWAPPED = "parse.swapped_corners"  # x1 > x2 or y1 > y2, fixed
C_CLIPPED = "parse.clipped_box"  # box partly outside the image, clipped
C_DEGENERATE = "parse.degenerate_box"  # zero area after clipping (or entirely outside), dropped
C_CONTROL_CHARS = "parse.control_chars"  # control characters removed from text/labels

COUNTERS: tuple[str, ...] = (
    C_TEXT_TOO_LONG,
    C_NO_JSON,
    C_JSON_REPAIRED,
    C_NON_LIST,
    C_TOO_MANY,
    C_ITEM_NOT_OBJECT,
    C_NO_BBOX,
    C_BAD_BBOX,
    C_COERCED,
    C_NONFINITE,
    C_HUGE,
    C_BAD_LABEL,
    C_UNKNOWN_LABEL,
    C_BAD_SCORE,
    C_SCORE_CLIPPED,
    C_SWAPPED,
    C_CLIPPED,
    C_DEGENERATE,
    C_CONTROL_CHARS,
)

MAX_CHARS = 64 * 1024
MAX_ITEMS = 100
MAX_LABEL_CHARS = 128
MAX_ABS_COORD = 1e6  # no camera or 0..1000 grid comes near; beyond this it is garbage
_MAX_STARTS = 256  # JSON start positions tried before giving up
_BBOX_KEYS = ("bbox_2d", "bbox", "box", "bbox2d")
_SCORE_KEYS = ("score", "confidence", "conf")
_FENCE = re.compile(r"```[ \t]*(?:json|JSON)?[ \t]*\r?\n?(.*?)(?:```|\Z)", re.DOTALL)
_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f\u2028\u2029\u202a-\u202e\u2066-\u2069]")
_SPACES = re.compile(r"\s+")


@dataclass(frozen=True)
class Box:
    """One detection: ``(x1, y1, x2, y2)`` with x1 <= x2, y1 <= y2, in the coordinates stated by context."""

    label: str
    box: tuple[float, float, float, float]
    score: float | None = None


@dataclass
class ParseResult:
    """Boxes in the model's coordinates plus what had to be fixed or dropped to get them."""

    boxes: list[Box] = field(default_factory=list)
    counters: Counter[str] = field(default_factory=Counter)
    found_json: bool = False


def sanitize_text(text: Any, max_chars: int = 8192, counters: Counter[str] | None = None) -> str:
    """Printable, bounded text for publishing (answers, labels). Never raises."""
    if not isinstance(text, str):
        text = "" if text is None else str(text)
    cleaned = _CONTROL.sub("", text)
    if counters is not None and cleaned != text:
        counters[C_CONTROL_CHARS] += 1
    if len(cleaned) > max_chars:
        cleaned = cleaned[:max_chars]
        if counters is not None:
            counters[C_TEXT_TOO_LONG] += 1
    return cleaned


def normalise_label(label: str) -> str:
    """Case/space-insensitive form used to compare labels."""
    return _SPACES.sub(" ", label.strip().lower())


def _reject_constant(name: str) -> float:
    # json accepts NaN/Infinity/-Infinity by default; keep them visible as non-finite floats
    return float("nan")


def _loads(s: str) -> Any:
    return json.loads(s, parse_constant=_reject_constant)


def _candidates(text: str) -> list[str]:
    """Where JSON may live: fenced blocks first (Qwen fences its grounding), then the raw text."""
    out = [m.group(1) for m in _FENCE.finditer(text)]
    out.append(text)
    return out


def _decode_first(s: str) -> tuple[Any, bool] | None:
    """The first complete JSON list/object in ``s`` (prose before/after allowed)."""
    decoder = json.JSONDecoder(parse_constant=_reject_constant)
    for tries, m in enumerate(re.finditer(r"[\[{]", s)):
        if tries >= _MAX_STARTS:  # bounded work on adversarial input like "[[[[..."
            return None
        try:
            value, _end = decoder.raw_decode(s, m.start())
        except (ValueError, RecursionError):
            continue
        if isinstance(value, (list, dict)):
            return value, m.start() > 0 or bool(s[_end:].strip())
    return None


def _salvage_objects(s: str) -> list[Any]:
    """Complete top-level ``{...}`` objects in broken/truncated JSON, in order."""
    decoder = json.JSONDecoder(parse_constant=_reject_constant)
    found: list[Any] = []
    pos = 0
    failures = 0
    while failures < _MAX_STARTS:  # bounded work on adversarial input like "{{{{..."
        start = s.find("{", pos)
        if start < 0:
            break
        try:
            value, end = decoder.raw_decode(s, start)
        except (ValueError, RecursionError):
            failures += 1
            pos = start + 1
            continue
        found.append(value)
        pos = end
    return found


def _extract(text: str, counters: Counter[str]) -> tuple[list[Any], bool]:
    for cand in _candidates(text):
        stripped = cand.strip()
        if not stripped:
            continue
        try:
            return _as_list(_loads(stripped), counters), True
        except (ValueError, RecursionError):
            pass
        # Not clean JSON: prose around it, or cut off by max_new_tokens. Complete objects
        # scanned left to right recover both (a truncated list keeps its finished items).
        salvaged = _salvage_objects(stripped)
        if salvaged:
            counters[C_JSON_REPAIRED] += 1
            items: list[Any] = []
            for obj in salvaged:
                if isinstance(obj, dict) and not any(k in obj for k in _BBOX_KEYS):
                    inner = next((v for v in obj.values() if isinstance(v, list)), None)
                    if inner is not None:  # {"objects": [...]} wrapper
                        items.extend(inner)
                        continue
                items.append(obj)
            return items, True
        first = _decode_first(stripped)
        if first is not None:
            return _as_list(first[0], counters), True
    counters[C_NO_JSON] += 1
    return [], False


def _as_list(value: Any, counters: Counter[str]) -> list[Any]:
    if isinstance(value, list):
        return value
    counters[C_NON_LIST] += 1
    if isinstance(value, dict):
        if any(k in value for k in _BBOX_KEYS):
            return [value]
        # e.g. {"objects": [...]}: take the first list of objects inside
        for v in value.values():
            if isinstance(v, list):
                return v
    return []


def _number(v: Any, counters: Counter[str]) -> float | None:
    """A finite float from a JSON value, or None (counted). Bools are not numbers."""
    if isinstance(v, bool):
        return None
    if isinstance(v, str):
        try:
            f = float(v.strip())
        except ValueError:
            return None
        counters[C_COERCED] += 1
    elif isinstance(v, int):
        if abs(v) > MAX_ABS_COORD:
            counters[C_HUGE] += 1
            return None
        f = float(v)
    elif isinstance(v, float):
        f = v
    else:
        return None
    if not math.isfinite(f):
        counters[C_NONFINITE] += 1
        return None
    if abs(f) > MAX_ABS_COORD:
        counters[C_HUGE] += 1
        return None
    return f


def _bbox(item: dict[str, Any], counters: Counter[str]) -> tuple[float, float, float, float] | None:
    raw = next((item[k] for k in _BBOX_KEYS if k in item), None)
    if raw is None:
        counters[C_NO_BBOX] += 1
        return None
    if not isinstance(raw, list) or len(raw) != 4:
        counters[C_BAD_BBOX] += 1
        return None
    nums: list[float] = []
    for v in raw:
        before = counters[C_NONFINITE] + counters[C_HUGE]
        f = _number(v, counters)
        if f is None:
            if counters[C_NONFINITE] + counters[C_HUGE] == before:
                counters[C_BAD_BBOX] += 1
            return None
        nums.append(f)
    x1, y1, x2, y2 = nums
    if x1 > x2 or y1 > y2:
        counters[C_SWAPPED] += 1
        x1, x2 = min(x1, x2), max(x1, x2)
        y1, y2 = min(y1, y2), max(y1, y2)
    return (x1, y1, x2, y2)


def _score(item: dict[str, Any], counters: Counter[str]) -> float | None:
    key = next((k for k in _SCORE_KEYS if k in item), None)
    if key is None:
        return None
    v = item[key]
    f: float | None = None
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        f = float(v)
    elif isinstance(v, str):
        try:
            f = float(v.strip())
        except ValueError:
            f = None
    if f is None or not math.isfinite(f):
        counters[C_BAD_SCORE] += 1
        return None
    if f < 0.0 or f > 1.0:
        counters[C_SCORE_CLIPPED] += 1
        f = min(1.0, max(0.0, f))
    return f


def _match_label(label: str, wanted: dict[str, str]) -> str | None:
    """Canonical requested label for a predicted one: exact, else a requested label's words inside it."""
    norm = normalise_label(label)
    if norm in wanted:
        return wanted[norm]
    words = f" {norm} "
    for key, canonical in wanted.items():
        if f" {key} " in words:  # "ball" requested, "red ball" answered
            return canonical
    return None


def parse_grounding(
    text: Any,
    *,
    labels: Sequence[str] | None = None,
    max_items: int = MAX_ITEMS,
    max_chars: int = MAX_CHARS,
) -> ParseResult:
    """Parse Qwen grounding output into boxes in the model's coordinates. Never raises.

    ``labels``: when non-empty, only boxes whose label matches one of them are kept
    (reported with the requested spelling); the rest are counted as unknown.
    """
    result = ParseResult()
    counters = result.counters
    if not isinstance(text, str):
        counters[C_NO_JSON] += 1
        return result
    if len(text) > max_chars:
        counters[C_TEXT_TOO_LONG] += 1
        text = text[:max_chars]
    try:
        items, result.found_json = _extract(text, counters)
    except Exception:  # noqa: BLE001 - last line of defence: a parser bug must not kill the node
        counters[C_NO_JSON] += 1
        return result
    wanted = {normalise_label(lab): lab.strip() for lab in (labels or ()) if isinstance(lab, str) and lab.strip()}
    if len(items) > max_items:
        counters[C_TOO_MANY] += len(items) - max_items
        items = items[:max_items]
    for item in items:
        if not isinstance(item, dict):
            counters[C_ITEM_NOT_OBJECT] += 1
            continue
        raw_label = item.get("label", item.get("name"))
        if isinstance(raw_label, (int, float)) and not isinstance(raw_label, bool):
            raw_label = str(raw_label)
        if not isinstance(raw_label, str) or not raw_label.strip():
            counters[C_BAD_LABEL] += 1
            continue
        label = sanitize_text(raw_label, MAX_LABEL_CHARS, counters).strip()
        if not label:
            counters[C_BAD_LABEL] += 1
            continue
        if wanted:
            canonical = _match_label(label, wanted)
            if canonical is None:
                counters[C_UNKNOWN_LABEL] += 1
                continue
            label = canonical
        box = _bbox(item, counters)
        if box is None:
            continue
        result.boxes.append(Box(label=label, box=box, score=_score(item, counters)))
    return result


def finalize_boxes(
    boxes: Iterable[Box],
    *,
    coords: CoordSystem,
    resized_hw: tuple[int, int],
    original_hw: tuple[int, int],
    counters: Counter[str],
) -> list[Box]:
    """Model coordinates -> original-image pixels, clipped to the image; empty boxes dropped."""
    oh, ow = original_hw
    out: list[Box] = []
    for b in boxes:
        x1, y1, x2, y2 = box_to_original(b.box, coords=coords, resized_hw=resized_hw, original_hw=original_hw)
        if x1 > x2:
            x1, x2 = x2, x1
        if y1 > y2:
            y1, y2 = y2, y1
        cx1, cy1 = min(max(x1, 0.0), float(ow)), min(max(y1, 0.0), float(oh))
        cx2, cy2 = min(max(x2, 0.0), float(ow)), min(max(y2, 0.0), float(oh))
        if (cx1, cy1, cx2, cy2) != (x1, y1, x2, y2):
            counters[C_CLIPPED] += 1
        if cx2 - cx1 <= 0.0 or cy2 - cy1 <= 0.0:
            counters[C_DEGENERATE] += 1
            continue
        out.append(Box(label=b.label, box=(cx1, cy1, cx2, cy2), score=b.score))
    return out


class Answer(Protocol):
    """What a backend's generation says about one answer (perception/vlm/backend.py: Generation)."""

    @property
    def text(self) -> str: ...
    @property
    def coords(self) -> CoordSystem: ...
    @property
    def resized_hw(self) -> tuple[int, int]: ...
    @property
    def original_hw(self) -> tuple[int, int]: ...


def answer_boxes(
    gen: Answer, labels: Sequence[str] | None = None, counters: Counter[str] | None = None
) -> tuple[ParseResult, list[Box]]:
    """A VLM's answer -> its parse and its boxes in the original image's pixels. Never raises.
    The parse's counters and the rescaling's go to `counters` when given (else to the parse's)."""
    parsed = parse_grounding(gen.text, labels=labels)
    out = parsed.counters if counters is None else counters
    if counters is not None:
        counters.update(parsed.counters)
    boxes = finalize_boxes(
        parsed.boxes, coords=gen.coords, resized_hw=gen.resized_hw, original_hw=gen.original_hw, counters=out
    )
    return parsed, boxes
