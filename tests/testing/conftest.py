"""Fixtures for the shipped tiny grounder: its directory, and `transformers serve` in front of it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from serveutil import served


@pytest.fixture(scope="session")
def grounder_ckpt() -> Path:
    """tests/data/tiny_grounder (skipped, not failed, where the vlm extra is not installed)."""
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    from testing_support.tiny_grounder import grounder_checkpoint

    return grounder_checkpoint()


@pytest.fixture(scope="session")
def grounder_server(grounder_ckpt: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """`transformers serve <grounder dir>` on 127.0.0.1:<free port>; yields the /v1 base URL."""
    yield from served(grounder_ckpt, tmp_path_factory, "grounder_serve")
