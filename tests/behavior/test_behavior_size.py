"""House 4's rule for the behaviour stage: the mission in parts, no file in behavior/ over 400 lines
(a file that grows past it is one that has taken on a second job: give it a module of its own); and
one navigator, the only caller of a planner."""

from __future__ import annotations

from pathlib import Path

import go2vlm.behavior

MAX_LINES = 400


def test_no_behaviour_file_is_over_400_lines() -> None:
    root = Path(go2vlm.behavior.__file__).parent
    sizes = {str(f.relative_to(root)): len(f.read_text().splitlines()) for f in root.rglob("*.py")}
    long = {name: n for name, n in sizes.items() if n > MAX_LINES}
    assert not long, f"over {MAX_LINES} lines: {long}"


def test_only_the_navigator_calls_a_planner() -> None:
    """behavior/ has one navigator: outside navigate/ (and the planners themselves), a module may
    import the planners' types and parameters, never a function that plans or steers."""
    import ast

    root = Path(go2vlm.behavior.__file__).parent
    calls = set()
    for f in root.rglob("*.py"):
        part = f.relative_to(root).parts[0]
        if part in ("navigate", "planner"):
            continue
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("go2vlm.behavior.planner"):
                calls |= {f"{f.relative_to(root)}: {a.name}" for a in node.names if a.name[0].islower()}
    assert not calls, f"planner functions used outside the navigator: {sorted(calls)}"
