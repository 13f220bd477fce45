"""The sim node's render thread: it owns the GL context, a mirror MjData and the cameras' renderers,
and draws each snapshot of the physics state it is handed, so that rendering never stalls the
physics. What it draws goes to the sink it was given (`FrameSink`: the sim node's publishers); it
knows nothing of topics.

The newest snapshot wins: a frame that is still waiting when the next one comes is dropped and
counted. `wait_idle()` lets a fast run (no real-time pacing) wait for every frame instead.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any, Protocol

import mujoco
import numpy as np

from go2vlm.sim.render import (
    NewestOnly,
    camera_scene_option,
    labelled_bodies,
    pose_mirror,
    render_segmentation,
    segmentation_boxes,
)

__all__ = ["FrameSink", "RenderThread", "Snapshot"]


@dataclass
class Snapshot:
    """What the render thread needs to draw one instant: the pose of everything, and its stamp."""

    sim_time: float
    stamp: float
    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    head: bool
    world: bool


class FrameSink(Protocol):
    """Where drawn frames go (called on the render thread)."""

    def frame(self, key: str, rgb: np.ndarray, stamp: float) -> None: ...  # key: "head" or "world"

    def boxes(self, boxes: dict[str, tuple[int, int, int, int]], stamp: float) -> None: ...


@dataclass(frozen=True)
class CameraSetup:
    """Which cameras to draw, at what size; `detections`: also the head frame's ground-truth boxes."""

    head: tuple[int, int] | None  # (width, height), None = off
    world: tuple[int, int] | None
    detections: bool = False


class RenderThread:
    def __init__(self, model: mujoco.MjModel, setup: CameraSetup, sink: FrameSink, log: Any, name: str) -> None:
        self.model = model
        self.setup = setup
        self.sink = sink
        self.log = log
        self._snapshots: NewestOnly[Snapshot] = NewestOnly()
        self.frames = 0
        self.dropped = 0
        self.busy_s = 0.0
        self.error: str | None = None
        self.ready = threading.Event()  # GL contexts made and warmed up (or failed): the clock may start
        self._idle = threading.Condition()
        self._submitted = 0
        self._finished = 0
        self._head_cam = model.camera("head_camera").id
        names = {model.camera(i).name for i in range(model.ncam)}
        self._world_cam = model.camera("world_camera").id if "world_camera" in names else -1
        self._thread = threading.Thread(target=self._run, name=f"{name}:render", daemon=True)

    @property
    def has_world_camera(self) -> bool:
        return self._world_cam >= 0

    def start(self) -> None:
        self._thread.start()

    def submit(self, snap: Snapshot) -> None:
        with self._idle:
            self._submitted += 1
        if self._snapshots.put(snap):
            self.dropped += 1  # the newest frame wins; a late frame is worth nothing
            self._done(1)

    def _done(self, n: int) -> None:
        with self._idle:
            self._finished += n
            self._idle.notify_all()

    def wait_idle(self, stop: threading.Event) -> None:
        """Block until every submitted snapshot is rendered (or rendering failed, or `stop`)."""
        with self._idle:
            while self._finished < self._submitted and self.error is None and not stop.is_set():
                self._idle.wait(0.1)  # wall time: re-check stop and error

    def stop(self) -> None:
        self._snapshots.close()
        if self._thread.is_alive():
            self._thread.join(5.0)

    def _renderer(self, size: tuple[int, int] | None, cam: int, renderers: list[mujoco.Renderer]) -> Any:
        if size is None or cam < 0:
            return None
        r = mujoco.Renderer(self.model, height=size[1], width=size[0])
        renderers.append(r)
        return r

    def _run(self) -> None:
        renderers: list[mujoco.Renderer] = []
        try:
            data = mujoco.MjData(self.model)
            head_opt = camera_scene_option(hide_robot=True)
            world_opt = camera_scene_option(hide_robot=False)
            bodies = labelled_bodies(self.model)
            head_r = self._renderer(self.setup.head, self._head_cam, renderers)
            world_r = self._renderer(self.setup.world, self._world_cam, renderers)
            # The first frame compiles llvmpipe's shaders (slow): do it before the clock starts.
            data.qpos[:] = self.model.qpos0
            mujoco.mj_kinematics(self.model, data)
            mujoco.mj_camlight(self.model, data)
            if head_r is not None:
                head_r.update_scene(data, camera=self._head_cam, scene_option=head_opt)
                head_r.render()
            if world_r is not None:
                world_r.update_scene(data, camera=self._world_cam, scene_option=world_opt)
                world_r.render()
        except Exception as exc:  # no GL here: physics keeps running, cameras stay silent
            self.error = f"rendering unavailable: {type(exc).__name__}: {exc}"
            self.log.error(f"{self.error}; set MUJOCO_GL=egl or osmesa (see docs/demo.md)")
            self._done(0)
            self.ready.set()
            for r in renderers:
                r.close()
            return
        self.ready.set()
        try:
            while (snap := self._snapshots.take()) is not None:
                t0 = time.perf_counter()  # wall time: the render thread's CPU load, for benchmarks
                pose_mirror(self.model, data, snap.qpos, snap.mocap_pos, snap.mocap_quat)
                if snap.head and head_r is not None:
                    head_r.update_scene(data, camera=self._head_cam, scene_option=head_opt)
                    self.sink.frame("head", head_r.render(), snap.stamp)
                    if self.setup.detections:  # same pose, same camera: the boxes of exactly that frame
                        ids = render_segmentation(head_r, data, self._head_cam, head_opt)
                        self.sink.boxes(segmentation_boxes(ids, self.model.geom_bodyid, bodies), snap.stamp)
                if snap.world and world_r is not None:
                    world_r.update_scene(data, camera=self._world_cam, scene_option=world_opt)
                    self.sink.frame("world", world_r.render(), snap.stamp)
                self.frames += 1
                self.busy_s += time.perf_counter() - t0
                self._done(1)
        except Exception as exc:
            self.error = f"render thread failed: {type(exc).__name__}: {exc}"
            self.log.error(self.error)
            self._done(0)
        finally:
            for r in renderers:
                r.close()
