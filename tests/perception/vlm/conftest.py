"""Fixtures for the VLM tests: a tiny trained Qwen2.5-VL checkpoint and a real OpenAI-compatible
server (`transformers serve`) in front of it, each built/started once per session.

The checkpoint is cached under $GO2VLM_CACHE or ~/.cache/go2vlm, keyed on its parameters and
library versions, so a rerun skips the ~15 s build.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def tiny_ckpt() -> Path:
    """A tiny Qwen2.5-VL checkpoint trained to answer tiny.DEFAULT_ANSWER (a grounding JSON)."""
    # Skip (not fail) where the vlm extra is not installed; other perception tests still run.
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    from go2vlm.testing.tiny_qwen import DEFAULT_ANSWER, cached_tiny_checkpoint

    return cached_tiny_checkpoint(answer=DEFAULT_ANSWER, steps=300, seed=0)


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _serve_command() -> list[str]:
    exe = Path(sys.executable).with_name("transformers")
    if exe.exists():
        return [str(exe), "serve"]
    found = shutil.which("transformers")
    if found:
        return [found, "serve"]
    return [sys.executable, "-c", "from transformers.cli.transformers import main; main()", "serve"]


@pytest.fixture(scope="session")
def tiny_server(tiny_ckpt: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """`transformers serve <tiny dir>` on 127.0.0.1:<free port>; yields the /v1 base URL."""
    pytest.importorskip("fastapi")
    pytest.importorskip("uvicorn")
    pytest.importorskip("openai")
    port = free_port()
    log_path = tmp_path_factory.mktemp("serve") / "serve.log"
    env = dict(os.environ)
    # Offline: the server must never try the hub for a local directory.
    env.update(HF_HUB_OFFLINE="1", TRANSFORMERS_OFFLINE="1", TOKENIZERS_PARALLELISM="false")
    cmd = [*_serve_command(), str(tiny_ckpt), "--host", "127.0.0.1", "--port", str(port), "--device", "cpu"]
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 120
        while True:
            if proc.poll() is not None:
                pytest.fail(f"transformers serve exited {proc.returncode}:\n{log_path.read_text()[-3000:]}")
            try:
                with urllib.request.urlopen(base + "/health", timeout=2) as r:
                    if r.status == 200:
                        break
            except OSError:
                pass
            if time.monotonic() > deadline:
                pytest.fail(f"transformers serve not healthy in 120 s:\n{log_path.read_text()[-3000:]}")
            time.sleep(0.3)
        yield base + "/v1"
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
