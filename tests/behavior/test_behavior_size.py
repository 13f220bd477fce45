"""House 4's rule for the behaviour stage: the mission in parts, no file in behavior/ over 400 lines
(a file that grows past it is one that has taken on a second job: give it a module of its own)."""

from __future__ import annotations

from pathlib import Path

import go2vlm.behavior

MAX_LINES = 400


def test_no_behaviour_file_is_over_400_lines() -> None:
    root = Path(go2vlm.behavior.__file__).parent
    sizes = {str(f.relative_to(root)): len(f.read_text().splitlines()) for f in root.rglob("*.py")}
    long = {name: n for name, n in sizes.items() if n > MAX_LINES}
    assert not long, f"over {MAX_LINES} lines: {long}"
