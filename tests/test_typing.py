"""Types: mypy on src/ and testing_support/ passes (the configuration is pyproject.toml's [tool.mypy]),
and the explicit `Any`s do not grow past the figure docs/typing.md records and explains."""

from __future__ import annotations

import re
import runpy
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow  # a minute of CPU on a fresh clone (seconds with mypy's cache)
def test_mypy_src_is_clean() -> None:
    proc = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, f"mypy src (see docs/typing.md):\n{proc.stdout}{proc.stderr}"


def test_explicit_any_does_not_grow() -> None:
    doc = (ROOT / "docs" / "typing.md").read_text(encoding="utf-8")
    m = re.search(r"explicit `Any`s: \*\*(\d+)\*\*", doc)
    assert m is not None, "docs/typing.md no longer records the explicit Any count"
    recorded = int(m.group(1))
    kinds, files = runpy.run_path(str(ROOT / "scripts" / "count_any.py"))["count"]()
    now = sum(kinds.values())
    top = ", ".join(f"{name} {n}" for name, n in files.most_common(5))
    assert now <= recorded, (
        f"src/go2vlm and testing_support name Any {now} times, docs/typing.md records {recorded}: type the new "
        f"ones, or record the new figure there with the reason (python scripts/count_any.py; most in {top})"
    )
