"""Shared test set-up: every test session gets its own DDS domain on loopback, so parallel runs on
one machine never hear each other."""

from __future__ import annotations

import os
import random

# Before go2vlm creates a participant: a private domain on loopback for this session (<= 101: higher
# domains put discovery ports into the ephemeral range on Linux).
os.environ.setdefault("ROS_DOMAIN_ID", str(random.Random(os.getpid()).randint(20, 101)))
os.environ.setdefault("GO2VLM_IFACE", "lo")
os.environ.setdefault("MUJOCO_GL", os.environ.get("MUJOCO_GL", "egl"))

import pytest  # noqa: E402
from busutil import Procs  # noqa: E402


@pytest.fixture
def procs():
    """Start go2vlm commands as real processes; all are stopped (SIGINT, then kill) after the test."""
    p = Procs()
    try:
        yield p
    finally:
        p.stop_all()
