"""``transformers serve`` of a local checkpoint on loopback: a real OpenAI-compatible server for tests
and benchmarks of the openai backend."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["ServeFailed", "free_port", "serve_checkpoint"]


class ServeFailed(RuntimeError):
    """The server exited or never became healthy; the message ends with its log's tail."""


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


@contextmanager
def serve_checkpoint(ckpt: str | os.PathLike[str], log_path: Path, *, timeout_s: float = 120.0) -> Iterator[str]:
    """Start ``transformers serve <ckpt>`` on 127.0.0.1 and a free port, CPU, offline; yield its ``/v1`` URL
    once ``/health`` answers 200; stop it on exit. Requests must name the model ``str(ckpt)``."""
    port = free_port()
    env = dict(os.environ)
    # Offline: the server must never try the hub for a local directory.
    env.update(HF_HUB_OFFLINE="1", TRANSFORMERS_OFFLINE="1", TOKENIZERS_PARALLELISM="false")
    cmd = [*_serve_command(), str(ckpt), "--host", "127.0.0.1", "--port", str(port), "--device", "cpu"]
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + timeout_s
        while True:
            if proc.poll() is not None:
                raise ServeFailed(f"transformers serve exited {proc.returncode}:\n{log_path.read_text()[-3000:]}")
            try:
                with urllib.request.urlopen(base + "/health", timeout=2) as r:
                    if r.status == 200:
                        break
            except OSError:
                pass
            if time.monotonic() > deadline:
                tail = log_path.read_text()[-3000:]
                raise ServeFailed(f"transformers serve not healthy in {timeout_s:.0f} s:\n{tail}")
            time.sleep(0.3)  # poll interval of the health check
        yield base + "/v1"
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
