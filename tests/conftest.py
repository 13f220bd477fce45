"""Shared test set-up.

- The tests import this checkout's `src/` and `testing_support/` (also in the processes they start),
  so a worktree tests its own code whatever `.venv` it borrows.
- Every test session gets a DDS domain that nothing on this host is using: a lock file per domain
  keeps concurrent sessions apart, and a discovery probe skips domains where any participant (a
  running demo, a ROS 2 node) already speaks. Traffic stays on loopback.
- State the nodes keep across restarts (the safety gate's e-stop latch, under XDG_STATE_HOME) goes
  to a temporary folder: one for the session, and one of its own for every test, so a test that ends
  with a gate latched never latches the next test's gate, and nothing lands in the user's home.
- Property tests (hypothesis) have no per-example deadline: timing is for benchmarks/, not tests.
"""

from __future__ import annotations

import atexit
import os
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = str(Path(__file__).resolve().parents[1])  # for testing_support/, the dev-only helpers
SRC = str(Path(ROOT) / "src")
sys.path[:0] = [SRC, ROOT]
os.environ["PYTHONPATH"] = os.pathsep.join([SRC, ROOT, *filter(None, [os.environ.get("PYTHONPATH")])])
os.environ["GO2VLM_IFACE"] = "lo"
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ["XDG_STATE_HOME"] = tempfile.mkdtemp(prefix="go2vlm-test-state-")
atexit.register(shutil.rmtree, os.environ["XDG_STATE_HOME"], True)

from busutil import Procs, claim_free_domain  # noqa: E402

# Before go2vlm creates a participant: an explicit GO2VLM_TEST_DOMAIN wins, else a free one.
os.environ["ROS_DOMAIN_ID"] = str(claim_free_domain())

import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

# No property test has a time limit: a busy machine is not a failure (speed targets live in benchmarks/).
settings.register_profile("go2vlm", deadline=None)
settings.load_profile("go2vlm")


@pytest.fixture(autouse=True)
def _own_state_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test's nodes (in-process and the processes it starts) keep their state in its own folder."""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))


@pytest.fixture
def procs():
    """Start go2vlm commands as real processes; all are stopped (SIGINT, then kill) after the test."""
    p = Procs()
    try:
        yield p
    finally:
        p.stop_all()
