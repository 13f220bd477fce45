"""Shared test set-up.

- The tests import this checkout's `src/` (also in the processes they start), so a worktree tests
  its own code whatever `.venv` it borrows.
- Every test session gets a DDS domain that nothing on this host is using: a lock file per domain
  keeps concurrent sessions apart, and a discovery probe skips domains where any participant (a
  running demo, a ROS 2 node) already speaks. Traffic stays on loopback.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

SRC = str(Path(__file__).resolve().parents[1] / "src")
sys.path.insert(0, SRC)
os.environ["PYTHONPATH"] = os.pathsep.join([SRC, *filter(None, [os.environ.get("PYTHONPATH")])])
os.environ["GO2VLM_IFACE"] = "lo"
os.environ.setdefault("MUJOCO_GL", "egl")

from busutil import Procs, claim_free_domain  # noqa: E402

# Before go2vlm creates a participant: an explicit GO2VLM_TEST_DOMAIN wins, else a free one.
os.environ["ROS_DOMAIN_ID"] = str(claim_free_domain())

import pytest  # noqa: E402


@pytest.fixture
def procs():
    """Start go2vlm commands as real processes; all are stopped (SIGINT, then kill) after the test."""
    p = Procs()
    try:
        yield p
    finally:
        p.stop_all()
