"""`transformers serve` of a checkpoint as a pytest fixture body (testing_support.serve underneath)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest


def served(ckpt: Path, tmp_path_factory: pytest.TempPathFactory, name: str) -> Iterator[str]:
    """Serve `ckpt` on 127.0.0.1:<free port> and yield its /v1 base URL; skip without the serve extras."""
    pytest.importorskip("fastapi")
    pytest.importorskip("uvicorn")
    pytest.importorskip("openai")
    from testing_support.serve import ServeFailed, serve_checkpoint

    log = tmp_path_factory.mktemp(name) / "serve.log"
    try:
        with serve_checkpoint(ckpt, log) as url:
            yield url
    except ServeFailed as exc:
        pytest.fail(str(exc))
