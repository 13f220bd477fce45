"""Fixtures for the shipped tiny grounder: its directory, and `transformers serve` in front of it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def grounder_ckpt() -> Path:
    """tests/data/tiny_grounder (skipped, not failed, where the vlm extra is not installed)."""
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    from go2vlm.testing.tiny_grounder import grounder_checkpoint

    return grounder_checkpoint()


@pytest.fixture(scope="session")
def grounder_server(grounder_ckpt: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """`transformers serve <grounder dir>` on 127.0.0.1:<free port>; yields the /v1 base URL."""
    pytest.importorskip("fastapi")
    pytest.importorskip("uvicorn")
    pytest.importorskip("openai")
    from go2vlm.testing.serve import ServeFailed, serve_checkpoint

    log = tmp_path_factory.mktemp("grounder_serve") / "serve.log"
    try:
        with serve_checkpoint(grounder_ckpt, log) as url:
            yield url
    except ServeFailed as exc:
        pytest.fail(str(exc))
