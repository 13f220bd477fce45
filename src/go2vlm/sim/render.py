"""Render-thread helpers shared by the sim node's cameras and the Unitree bridge's JPEG camera.

A render thread owns its GL context and a mirror MjData; the physics thread hands it snapshots of
the pose through a `NewestOnly` mailbox (a late frame is worth nothing, so the newest wins), and the
render thread poses its mirror with `pose_mirror` before rendering.
"""

from __future__ import annotations

import threading
from typing import Generic, TypeVar

import mujoco
import numpy as np

__all__ = ["NewestOnly", "camera_scene_option", "pose_mirror"]

T = TypeVar("T")


class NewestOnly(Generic[T]):
    """A one-item mailbox between two threads: `put` replaces an untaken item, `take` waits."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._item: T | None = None
        self._closed = False

    def put(self, item: T) -> bool:
        """Store `item` as the newest; True if it replaced one that was never taken."""
        with self._cond:
            replaced = self._item is not None
            self._item = item
            self._cond.notify()
            return replaced

    def take(self) -> T | None:
        """Wait for the next item; None once closed (an item still waiting is then left)."""
        with self._cond:
            while self._item is None and not self._closed:
                self._cond.wait()
            if self._closed:
                return None
            item, self._item = self._item, None
            return item

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify()


def camera_scene_option(hide_robot: bool) -> mujoco.MjvOption:
    """Scene options of a camera: collision geoms (group 3) hidden, and the robot's own body
    (group 2) too for the head camera (the robot does not see its own body)."""
    opt = mujoco.MjvOption()
    if hide_robot:
        opt.geomgroup[2] = 0
    opt.geomgroup[3] = 0
    return opt


def pose_mirror(
    model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray, mocap_pos: np.ndarray, mocap_quat: np.ndarray
) -> None:
    """Pose a mirror MjData as a physics snapshot: positions, cameras and lights (no dynamics)."""
    data.qpos[:] = qpos
    data.mocap_pos[:] = mocap_pos
    data.mocap_quat[:] = mocap_quat
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)
