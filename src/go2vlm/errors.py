"""The one exit-code rule, as exception types.

`go2vlm` (cli/main.py) maps exceptions to exit codes in one place: a `UsageError` (including every
`ConfigError`) exits 2 with one line, any other exception at runtime exits 1 with one line, and a
signal N exits 128 + N (bus/runtime.py). Raise these anywhere: they carry no CLI knowledge.
"""

from __future__ import annotations

__all__ = ["ConfigError", "UsageError"]


class UsageError(ValueError):
    """The command was asked for something that cannot work as given (exit 2)."""


class ConfigError(UsageError):
    """A parameter, file or model that is missing, malformed or out of range (exit 2)."""
