"""Fixtures for the VLM tests: a tiny trained Qwen2.5-VL checkpoint and a real OpenAI-compatible
server (`transformers serve`) in front of it, each built/started once per session.

The checkpoint is cached under $GO2VLM_CACHE or ~/.cache/go2vlm, keyed on its parameters and
library versions, so a rerun skips the ~15 s build.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from serveutil import served


@pytest.fixture(scope="session")
def tiny_ckpt() -> Path:
    """A tiny Qwen2.5-VL checkpoint trained to answer tiny.DEFAULT_ANSWER (a grounding JSON)."""
    # Skip (not fail) where the vlm extra is not installed; other perception tests still run.
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    from testing_support.tiny_qwen import DEFAULT_ANSWER, cached_tiny_checkpoint

    return cached_tiny_checkpoint(answer=DEFAULT_ANSWER, steps=300, seed=0)


@pytest.fixture(scope="session")
def tiny_server(tiny_ckpt: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """`transformers serve <tiny dir>` on 127.0.0.1:<free port> (testing_support.serve); yields the /v1 base URL."""
    yield from served(tiny_ckpt, tmp_path_factory, "serve")
