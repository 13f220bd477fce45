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

__all__ = [
    "NewestOnly",
    "camera_scene_option",
    "labelled_bodies",
    "pose_mirror",
    "render_segmentation",
    "segmentation_boxes",
]

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


def labelled_bodies(model: mujoco.MjModel) -> dict[int, str]:
    """Body id -> name of every named body that is neither the world nor part of the robot: the
    objects a detector may be asked about (their names are the ground-truth labels)."""
    robot_root = model.body("base").id
    out: dict[int, str] = {}
    for b in range(1, model.nbody):
        name = model.body(b).name
        if name and model.body_rootid[b] != robot_root:
            out[b] = name
    return out


def render_segmentation(
    renderer: mujoco.Renderer, data: mujoco.MjData, camera: int | mujoco.MjvCamera, scene_option: mujoco.MjvOption
) -> np.ndarray:
    """(H, W) int32 geom ids seen by `camera` (-1: background or not a geom)."""
    renderer.enable_segmentation_rendering()
    try:
        renderer.update_scene(data, camera=camera, scene_option=scene_option)
        seg = renderer.render()
    finally:
        renderer.disable_segmentation_rendering()
    ids = seg[:, :, 0].astype(np.int32)
    ids[seg[:, :, 1] != int(mujoco.mjtObj.mjOBJ_GEOM)] = -1
    return ids


def segmentation_boxes(
    geom_ids: np.ndarray, geom_bodyid: np.ndarray, bodies: dict[int, str], min_pixels: int = 16, min_side: int = 2
) -> dict[str, tuple[int, int, int, int]]:
    """Body name -> the pixel box (x1, y1, x2, y2; x2, y2 exclusive) of what the camera sees of it:
    an occluded or border-cut object gets the box of its visible part. Bodies with fewer than
    `min_pixels` visible pixels, or a box thinner than `min_side`, are left out (a speck or a sliver
    at the image border is not a detection)."""
    valid = geom_ids >= 0
    body = np.full(geom_ids.shape, -1, dtype=np.int32)
    body[valid] = geom_bodyid[geom_ids[valid]]
    out: dict[str, tuple[int, int, int, int]] = {}
    present, counts = np.unique(body[body >= 0], return_counts=True)
    for b, n in zip(present.tolist(), counts.tolist(), strict=True):
        if b not in bodies or n < min_pixels:
            continue
        mask = body == b
        rows = np.flatnonzero(mask.any(axis=1))
        cols = np.flatnonzero(mask.any(axis=0))
        box = (int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1)
        if box[2] - box[0] >= min_side and box[3] - box[1] >= min_side:
            out[bodies[b]] = box
    return out
