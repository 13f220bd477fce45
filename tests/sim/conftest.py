"""Make ``go2vlm`` importable from the src layout even without an editable install."""

from __future__ import annotations

import sys
from pathlib import Path

_SRC = Path(__file__).resolve().parents[2] / "src"
if str(_SRC) not in sys.path:
    sys.path.insert(0, str(_SRC))

import go2vlm.sim  # noqa: E402,F401  - selects the GL backend before anything imports mujoco
