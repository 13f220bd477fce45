"""ROS-style console logging: `[INFO] [1732240000.123456789] [node]: message` on stderr."""

from __future__ import annotations

import os
import sys
import threading
import time

LEVELS = {"debug": 10, "info": 20, "warn": 30, "warning": 30, "error": 40, "fatal": 50}
_NAMES = {10: "DEBUG", 20: "INFO", 30: "WARN", 40: "ERROR", 50: "FATAL"}
_write_lock = threading.Lock()


def _level_from_env() -> int:
    raw = os.environ.get("GO2VLM_LOG_LEVEL", "info").lower()
    return LEVELS.get(raw, 20)


class Logger:
    level: int = _level_from_env()

    def __init__(self, name: str) -> None:
        self.name = name
        self._last: dict[str, float] = {}

    @classmethod
    def set_level(cls, level: str) -> None:
        if level.lower() not in LEVELS:
            raise ValueError(f"log level {level!r} is not one of {sorted(LEVELS)}")
        cls.level = LEVELS[level.lower()]

    def log(self, level: int, msg: str) -> None:
        if level < Logger.level:
            return
        t = time.time()  # wall time: a log line says when it was written, whatever the node's clock
        line = f"[{_NAMES[level]}] [{t:.9f}] [{self.name}]: {msg}\n"
        with _write_lock:
            sys.stderr.write(line)
            sys.stderr.flush()

    def debug(self, msg: str) -> None:
        self.log(10, msg)

    def info(self, msg: str) -> None:
        self.log(20, msg)

    def warning(self, msg: str) -> None:
        self.log(30, msg)

    warn = warning

    def error(self, msg: str) -> None:
        self.log(40, msg)

    def throttled(self, level: str, period_s: float, msg: str, key: str | None = None) -> None:
        """Log at most once per `period_s` for `key` (default: the level), like rclpy's throttle."""
        k = key or level
        now = time.monotonic()  # wall time: throttling protects the console, in wall seconds
        if now - self._last.get(k, -1e18) >= period_s:
            self._last[k] = now
            self.log(LEVELS[level], msg)
