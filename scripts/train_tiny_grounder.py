#!/usr/bin/env python
"""Build the tiny grounding checkpoints shipped in tests/data (see docs/vlm.md).

    nice -n 10 .venv/bin/python scripts/train_tiny_grounder.py --seed 0 --frames 6000 --steps 3000 \\
        --out tests/data/tiny_grounder
    nice -n 10 .venv/bin/python scripts/train_tiny_grounder.py --dataset household ... \\
        --out tests/data/tiny_grounder_household      # the exact command is in its go2vlm_grounder.json

Runs this checkout's code (its src/ and testing_support/ first on the path) whatever go2vlm is installed.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT)]  # go2vlm and the dev-only testing_support
os.environ.setdefault("MUJOCO_GL", "egl")

from testing_support.train_grounder import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
