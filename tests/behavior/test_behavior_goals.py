"""The goal parser, table-driven, English and Chinese."""

from __future__ import annotations

import pytest

from go2vlm.behavior.goals import GoalParseError, parse_goal, parse_target

CASES = [
    # English
    ("follow the red ball", "follow", "red", "ball"),
    ("Follow the RED ball!", "follow", "red", "ball"),
    ("please follow the red sphere", "follow", "red", "ball"),
    ("track the yellow ball", "follow", "yellow", "ball"),
    ("go to the blue cylinder", "go_to", "blue", "cylinder"),
    ("walk over to the blue pillar", "go_to", "blue", "cylinder"),
    ("approach the green cube", "go_to", "green", "box"),
    ("could you move towards the red ball", "go_to", "red", "ball"),
    ("look for the green box", "look_for", "green", "box"),
    ("find the yellow ball", "look_for", "yellow", "ball"),
    ("search for the blue cylinder", "look_for", "blue", "cylinder"),
    ("where is the green box?", "look_for", "green", "box"),
    ("find the red one", "look_for", "red", None),
    ("go to the ball", "go_to", None, "ball"),
    ("stop", "stop", None, None),
    ("Stop!", "stop", None, None),
    ("stop following the ball", "stop", None, None),
    ("halt", "stop", None, None),
    ("don't move", "stop", None, None),
    ("do not go to the red ball", "stop", None, None),
    ("sit", "sit", None, None),
    ("sit down", "sit", None, None),
    ("stand up", "stand", None, None),
    ("stand", "stand", None, None),
    ("turn left 20 degrees", "turn", None, None),
    ("turn -12.5", "turn", None, None),
    # Chinese
    ("跟着红球", "follow", "red", "ball"),
    ("跟随红色的球", "follow", "red", "ball"),
    ("请你跟着那个红色的球吧", "follow", "red", "ball"),
    ("走到蓝色圆柱", "go_to", "blue", "cylinder"),
    ("走到蓝色的圆柱体。", "go_to", "blue", "cylinder"),
    ("去绿色的箱子", "go_to", "green", "box"),
    ("靠近黄色方块", "go_to", "yellow", "box"),
    ("找一下绿色盒子", "look_for", "green", "box"),
    ("寻找红色的球", "look_for", "red", "ball"),
    ("去找蓝色圆柱", "look_for", "blue", "cylinder"),
    ("停", "stop", None, None),
    ("停下", "stop", None, None),
    ("停下来!", "stop", None, None),
    ("别动", "stop", None, None),
    ("坐下", "sit", None, None),
    ("站起来", "stand", None, None),
]


@pytest.mark.parametrize(("text", "kind", "color", "shape"), CASES)
def test_parses(text: str, kind: str, color: str | None, shape: str | None) -> None:
    goal = parse_goal(text)
    assert goal.kind == kind
    assert goal.text == text
    if kind in ("stop", "sit", "stand", "turn"):
        assert goal.target is None
        assert not goal.moves
    else:
        assert goal.target is not None and goal.moves
        assert (goal.target.color, goal.target.shape) == (color, shape)


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("", "empty"),
        ("   ", "empty"),
        ("dance", "cannot understand"),
        ("follow", "no object"),
        ("go to", "no object"),
        ("跳舞", "不理解"),
        ("找", "no object"),
        ("follow the red ball " * 20, "characters"),
        ("follow the\x00 red ball", "control"),
        ("turn 31 degrees", "at most 30"),
        ("turn around", "how far"),
        ("turn right -10", "not both"),
        ("向左转45度", "at most 30"),
    ],
)
def test_rejects_with_a_reason(text: str, needle: str) -> None:
    with pytest.raises(GoalParseError) as exc:
        parse_goal(text)
    assert needle in str(exc.value)


def test_free_text_objects_are_kept_for_a_vlm() -> None:
    goal = parse_goal("follow the person")
    assert goal.target is not None
    assert goal.target.label == "person" and not goal.target.classical
    assert parse_goal("跟着那个人").target.label == "人"


def test_targets_alone() -> None:
    assert parse_target("red ball") == parse_target("红色的球")
    assert parse_target("blue cylinder").label == "blue cylinder"


@pytest.mark.parametrize(
    ("text", "angle"),
    [
        ("turn left 20 degrees", 20.0),
        ("turn right 15", -15.0),
        ("turn -12.5", -12.5),
        ("Turn by 10 degrees to the right", -10.0),
        ("please turn 30°", 30.0),
        ("向左转20度", 20.0),
        ("右转1.5度", -1.5),
    ],
)
def test_a_turn_keeps_its_sign_and_decimals(text: str, angle: float) -> None:
    goal = parse_goal(text)
    assert goal.kind == "turn" and goal.angle_deg == angle and goal.target is None
