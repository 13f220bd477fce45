"""Pick a headless OpenGL backend for MuJoCo before ``mujoco`` is imported.

MuJoCo reads ``MUJOCO_GL`` once, at import time, so :func:`setup_gl` must run
before the first ``import mujoco`` anywhere in the process.  ``go2vlm.sim``
calls it from its package ``__init__``.

Order of preference: an explicit ``MUJOCO_GL`` from the user, then ``egl``
(GPU or Mesa llvmpipe, no X server), then ``osmesa`` (pure software).
"""

from __future__ import annotations

import ctypes.util
import importlib.util
import os
import sys

APT_HINT = (
    "No headless OpenGL found for MuJoCo. On Debian/Ubuntu install EGL: "
    "`apt-get install -y libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri` "
    "or OSMesa: `apt-get install -y libosmesa6`, then set MUJOCO_GL=egl "
    "(or osmesa)."
)

_VALID = ("egl", "osmesa", "glfw")


def _has_lib(*names: str) -> bool:
    return any(ctypes.util.find_library(n) for n in names)


def detect_backend() -> str | None:
    """Return the first usable headless backend name, or ``None``."""
    if _has_lib("EGL") and _has_lib("GL", "OpenGL"):
        return "egl"
    if _has_lib("OSMesa"):
        return "osmesa"
    return None


def setup_gl(prefer: str | None = None) -> str | None:
    """Set ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``) if not set already.

    Returns the backend in effect, or ``None`` when nothing usable exists
    (physics still works; only rendering will fail, see :data:`APT_HINT`).
    """
    current = os.environ.get("MUJOCO_GL")
    if current:
        backend: str | None = current.lower()
    else:
        if "mujoco" in sys.modules:
            # Too late to influence MuJoCo; report what it will use.
            return os.environ.get("MUJOCO_GL")
        backend = prefer if prefer in _VALID else detect_backend()
        if backend is None:
            return None
        os.environ["MUJOCO_GL"] = backend
    if backend in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", backend)
    return backend


class RenderingUnavailable(RuntimeError):
    """Raised when an offscreen GL context cannot be created."""

    def __init__(self, cause: BaseException) -> None:
        super().__init__(f"{APT_HINT} (MUJOCO_GL={os.environ.get('MUJOCO_GL')!r}; cause: {cause})")


def patch_late_import() -> str | None:
    """Repair the case where ``mujoco`` was imported before :func:`setup_gl`.

    Without ``MUJOCO_GL`` MuJoCo binds GLFW, which needs an X display.  On a
    headless machine swap in the EGL (or OSMesa) context class; MuJoCo's
    ``Renderer`` looks the class up at construction time.
    """
    env = os.environ.get("MUJOCO_GL", "").lower()
    if env in ("egl", "osmesa") or os.environ.get("DISPLAY"):
        return env or None
    import importlib

    from mujoco.rendering.classic import gl_context

    for name in ("egl", "osmesa"):
        if name == "egl" and not (_has_lib("EGL") and _has_lib("GL", "OpenGL")):
            continue
        if name == "osmesa" and not _has_lib("OSMesa"):
            continue
        os.environ.setdefault("PYOPENGL_PLATFORM", name)
        try:
            module = importlib.import_module(f"mujoco.{name}")
        except Exception:  # noqa: BLE001, S112 - try the next backend
            continue
        gl_context.GLContext = module.GLContext
        os.environ["MUJOCO_GL"] = name
        return name
    return None


def preload_triton() -> bool:
    """Load triton's bundled LLVM before Mesa's llvmpipe loads the system libLLVM.

    In the other order (a MuJoCo frame rendered on llvmpipe, then `import torch._dynamo`, which
    `import torchvision` and Qwen's processor do) the process segfaults in triton's module init, so
    a process that renders and then runs a VLM would crash. Costs about 0.1 s, and only where
    triton is installed (the `vlm` extra).
    """
    if "triton" in sys.modules or importlib.util.find_spec("triton") is None:
        return False
    try:
        import triton  # noqa: F401
    except Exception:  # a broken triton is torch's problem, not the simulator's
        return False
    return True
