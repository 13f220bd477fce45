"""Secrets (the MCP server's bearer token, a Go2's AES key) come from the environment or a file, never
from the command line (`ps` shows it) nor a parameter (any peer on the bus reads parameters), and no
message here ever holds one.

    key = read_secret("GO2VLM_AES_KEY", cfg.aes_key_file, "the robot's AES key")   # '' when neither
"""

from __future__ import annotations

import os
from pathlib import Path

from go2vlm.errors import ConfigError
from go2vlm.statefiles import read_bounded

__all__ = ["MIN_TOKEN_CHARS", "read_secret"]

MAX_SECRET_FILE_BYTES = 4096
MIN_TOKEN_CHARS = 16  # a bearer token (the MCP server's, the Foxglove view's): e.g. `openssl rand -hex 16`


def read_secret(env: str, file: str | None, what: str) -> str:
    """The first line of `file` when one is named, else $env, else ''; ConfigError (naming the file,
    never the secret) when the file cannot be read."""
    if not file:
        return os.environ.get(env, "").strip()
    try:
        text = read_bounded(Path(file).expanduser(), MAX_SECRET_FILE_BYTES).decode()
    except (OSError, ConfigError, UnicodeDecodeError) as exc:
        why = getattr(exc, "strerror", None) or str(exc).split(":")[-1].strip()
        raise ConfigError(f"{what}: cannot read {file}: {why}") from None
    lines = text.strip().splitlines()
    return lines[0].strip() if lines else ""
