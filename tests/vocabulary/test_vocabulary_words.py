"""One vocabulary: every module's word lists are go2vlm.vocabulary's objects, every table keyed by a
word covers all the words, and no other module spells a list of colour, shape or posture words.

Adding a colour, a shape or a posture in one place only fails here."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from go2vlm.vocabulary import words as w

ROOT = Path(__file__).resolve().parents[2]
SCANNED = [ROOT / "src" / "go2vlm", ROOT / "benchmarks", ROOT / "scripts"]
# Tables keyed by the words, each checked below to cover them all: (file, variable name).
KEYED_TABLES = {
    ("perception/ranging.py", "DEFAULT_SIZES"),
    ("world/objects_msg.py", "_MARKER_SHAPES"),
    ("robots/go2/protocol.py", "COMMANDS"),
    ("robots/go2/protocol.py", "ESTOP_ALLOWED"),
    ("robots/go2_sim/sim_node.py", "POSTURES"),
}
# Words that are also goal kinds or VLM decisions ("stop", "sit", "stand"): a list of those is not a
# posture list, so the scan counts only the postures that mean nothing else.
_ONLY_POSTURES = set(w.POSTURES) - {"stop", "sit", "stand"}


def test_modules_use_the_vocabularys_objects() -> None:
    from go2vlm.apps.mcp import rules
    from go2vlm.behavior import goals
    from go2vlm.perception import color, grounding
    from go2vlm.robots.go2 import protocol

    assert goals.COLORS is w.COLORS and goals.SHAPES is w.SHAPES
    assert goals._EN_COLORS is w.EN_COLOR_WORDS and goals._ZH_COLORS is w.ZH_COLOR_WORDS
    assert goals._EN_SHAPES is w.EN_SHAPE_WORDS and goals._ZH_SHAPES is w.ZH_SHAPE_WORDS
    assert color.PRESETS is w.COLOR_HSV and grounding.PRESETS is w.COLOR_HSV and grounding.SHAPES is w.SHAPES
    assert rules.COLORS is w.COLORS and rules.SHAPES is w.SHAPES
    assert protocol.POSTURES is w.POSTURES


def test_tables_keyed_by_words_cover_them_all() -> None:
    from go2vlm.behavior import decisions, goals
    from go2vlm.perception.ranging import DEFAULT_SIZES
    from go2vlm.robots.go2 import protocol
    from go2vlm.robots.go2_sim import sim_node
    from go2vlm.world import objects_msg

    assert set(DEFAULT_SIZES) == set(w.SHAPES)
    assert set(objects_msg._MARKER_SHAPES) == set(w.SHAPES)
    assert set(w.ROUND_SHAPES) <= set(w.SHAPES)
    assert tuple(w.COLOR_RGB) == w.COLORS
    assert tuple(protocol.COMMANDS) == w.POSTURES and tuple(sim_node.POSTURES) == w.POSTURES
    assert set(w.POSTURES) >= protocol.ESTOP_ALLOWED
    assert set(goals.POSTURE_GOALS) <= set(w.POSTURES) and set(goals.POSTURE_GOALS) <= set(goals.GOAL_KINDS)
    assert "sit" in decisions.ACTIONS and "sit" in w.POSTURES  # a VLM's sit is sent as the posture
    for synonyms, words in (
        (w.EN_COLOR_WORDS, w.COLORS),
        (w.ZH_COLOR_WORDS, w.COLORS),
        (w.EN_SHAPE_WORDS, w.SHAPES),
        (dict(w.ZH_SHAPE_WORDS), w.SHAPES),
    ):
        assert set(synonyms.values()) == set(words), synonyms  # every word has a synonym, none is stray
    assert all(w.EN_COLOR_WORDS[c] == c for c in w.COLORS) and all(w.EN_SHAPE_WORDS[s] == s for s in w.SHAPES)
    assert w.BODY_SHAPE_WORDS.items() <= w.EN_SHAPE_WORDS.items()


@pytest.mark.parametrize("color", w.COLORS)
@pytest.mark.parametrize("shape", w.SHAPES)
def test_every_pair_of_words_is_understood_everywhere(color: str, shape: str) -> None:
    """A goal, a label and a remembered object read every colour and shape the same way."""
    from go2vlm.behavior.goals import parse_goal
    from go2vlm.world.labels import normalize_label

    goal = parse_goal(f"go to the {color} {shape}")
    assert goal.target is not None and (goal.target.color, goal.target.shape) == (color, shape)
    label = w.parse_label(f"{color}_{shape}")
    assert (label.color, label.shape) == (color, shape)
    assert normalize_label(f"{color.upper()}  {shape}") == f"{color} {shape}"


def _word_lists(tree: ast.AST) -> list[tuple[int, str | None, list[str]]]:
    """(line, assigned name or None, the string elements) of every literal tuple/list/set and dict's keys."""
    names: dict[int, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                if isinstance(t, ast.Name) and node.value is not None:
                    for sub in ast.walk(node.value):
                        names.setdefault(id(sub), t.id)
    out = []
    for node in ast.walk(tree):
        elts: list[ast.expr | None] = []
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            elts = list(node.elts)
        elif isinstance(node, ast.Dict):
            elts = list(node.keys)
        strings = [e.value for e in elts if isinstance(e, ast.Constant) and isinstance(e.value, str)]
        if len(strings) >= 2:
            out.append((getattr(node, "lineno", 0), names.get(id(node)), strings))
    return out


def test_no_other_module_spells_a_word_list() -> None:
    vocab = ROOT / "src" / "go2vlm" / "vocabulary"
    found = []
    for top in SCANNED:
        for path in sorted(top.rglob("*.py")):
            if vocab in path.parents:
                continue
            rel = path.relative_to(ROOT / "src" / "go2vlm") if top.name == "go2vlm" else path.relative_to(ROOT)
            for line, name, strings in _word_lists(ast.parse(path.read_text(encoding="utf-8"))):
                if (str(rel), name) in KEYED_TABLES:
                    continue
                for kind, words in (("colour", w.COLORS), ("shape", w.SHAPES), ("posture", _ONLY_POSTURES)):
                    if len({s for s in strings if s in words}) >= 2:
                        found.append(f"{rel}:{line} spells {kind} words {strings}")
    assert not found, "take the words from go2vlm.vocabulary:\n" + "\n".join(found)


def test_a_label_with_more_than_a_colour_and_a_shape_keeps_its_words() -> None:
    """ "blue_mug" is a mug, not every blue thing: the memory kept it as "blue", which no body is."""
    from go2vlm.world.labels import label_fits, normalize_label

    assert normalize_label("blue_mug") == "blue mug" and normalize_label("the red_lego_brick") == "red lego brick"
    assert normalize_label("box_1") == "box 1" and normalize_label("red_sphere") == "red ball"
    assert label_fits("blue mug", normalize_label("blue_mug")) == 2 and label_fits("box", "box 1") >= 1
