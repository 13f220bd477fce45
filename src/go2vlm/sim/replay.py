"""Re-render a run from recorded states: a chase camera that shows the Go2 walking.

A run's recording holds the robot's base pose and its 12 joint angles (from /sim/ground_truth and
/joint_states) and the poses of moving bodies (the ball). `ChaseCamera` poses a model of the same
world with them and renders a third-person view from behind the robot, after the run, so that the
video costs nothing while the loop runs in real time.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from go2vlm.sim import go2_model as gm
from go2vlm.sim.gl import RenderingUnavailable, patch_late_import
from go2vlm.sim.render import camera_scene_option
from go2vlm.sim.worlds import build_world_xml

__all__ = ["ChaseCamera"]


class ChaseCamera:
    """A camera that follows the robot from behind, above and a little to the side (so that the legs
    show in three-quarter view), its heading smoothed (a camera that turned with every step of the
    trot would shake)."""

    def __init__(
        self,
        world: str,
        spawn: tuple[float, float, float] | None = None,
        width: int = 640,
        height: int = 480,
        distance_m: float = 2.8,
        elevation_deg: float = -22.0,
        azimuth_offset_deg: float = -30.0,  # what is ahead shows left of the inset
        heading_tau_s: float = 0.6,
    ) -> None:
        xml, _ = build_world_xml(world, spawn, (width, height))
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._qadr = np.array([m.jnt_qposadr[m.joint(n).id] for n in gm.JOINT_NAMES])
        self._mocap = {m.body(b).name: int(m.body(b).mocapid[0]) for b in range(m.nbody) if m.body(b).mocapid[0] >= 0}
        patch_late_import()
        try:
            self._renderer = mujoco.Renderer(m, height=height, width=width)
        except Exception as exc:  # noqa: BLE001 - any GL failure means "no rendering here"
            raise RenderingUnavailable(exc) from exc
        self._opt = camera_scene_option(hide_robot=False)
        self._cam = mujoco.MjvCamera()
        self._cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        self._cam.distance = distance_m
        self._cam.elevation = elevation_deg
        self._tau = heading_tau_s
        self._offset = azimuth_offset_deg
        self._heading: float | None = None
        self._t: float | None = None

    @property
    def size(self) -> tuple[int, int]:
        return self._renderer.width, self._renderer.height

    def render(
        self,
        t: float,
        base_pos: Sequence[float],
        base_quat: Sequence[float],
        joint_pos: Sequence[float] | None,
        bodies: Mapping[str, Sequence[float]] | None = None,
    ) -> np.ndarray:
        """RGB (H, W, 3) uint8 at sim time `t` (seconds; frames in time order): the Go2's base at
        `base_pos`/`base_quat` (w, x, y, z), its joints at `joint_pos` (Unitree order; None keeps the
        last), mocap bodies at `bodies[name]`."""
        d = self.data
        d.qpos[0:3] = base_pos
        d.qpos[3:7] = base_quat
        if joint_pos is not None:
            d.qpos[self._qadr] = joint_pos
        for name, pos in (bodies or {}).items():
            i = self._mocap.get(name)
            if i is not None:
                d.mocap_pos[i] = pos
        mujoco.mj_kinematics(self.model, d)
        w, x, y, z = base_quat
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        if self._heading is None or self._t is None:
            self._heading = yaw
        else:  # first-order low-pass on the heading, along the shorter way round
            a = 1.0 - math.exp(-max(0.0, t - self._t) / self._tau)
            self._heading += a * math.atan2(math.sin(yaw - self._heading), math.cos(yaw - self._heading))
        self._t = t
        self._cam.lookat[:] = (base_pos[0], base_pos[1], 0.25)
        self._cam.azimuth = math.degrees(self._heading) + self._offset
        self._renderer.update_scene(d, camera=self._cam, scene_option=self._opt)
        return self._renderer.render()

    def close(self) -> None:
        self._renderer.close()

    def __enter__(self) -> ChaseCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
