"""A process that renders on Mesa llvmpipe and then loads a VLM must not crash.

Mesa's libLLVM loaded first makes triton's module init segfault on `import torch._dynamo` (which
torchvision and Qwen's processor import); `go2vlm.sim` loads triton first where it is installed.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import pytest

SCRIPT = """
from go2vlm.sim import Go2Sim, SimConfig
sim = Go2Sim(SimConfig(world="vision_test", camera_width=64, camera_height=48))
sim.render_head()
import torchvision  # noqa: F401
print("ok")
"""


@pytest.mark.slow  # a fresh interpreter that renders, then imports torch and torchvision
@pytest.mark.skipif(importlib.util.find_spec("torchvision") is None, reason="needs the vlm extra")
def test_rendering_then_importing_torchvision_does_not_crash() -> None:
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().endswith("ok")
