"""`SimConfig`: the one configuration of the simulated Go2, shared by `Go2Sim` and the sim node.

Its fields are declared as node parameters (`go2vlm.bus.params.param`), so the sim node's
parameters are these same fields under the same names and defaults, plus the node's own
(publishing rates, real-time factor; robots/go2_sim/sim_node.py).
"""

from __future__ import annotations

from dataclasses import dataclass

from go2vlm.bus.params import param
from go2vlm.robot_profile.go2 import GO2
from go2vlm.sim.controller import GaitParams

__all__ = ["SimConfig"]


@dataclass
class SimConfig:
    world: str = param(
        "follow_ball",
        help="world name (vision_test, follow_ball, obstacles, distractors, household, apartment, empty, wall) "
        "or an .xml path",
    )
    mode: str = param(
        "dynamic", help="physics: dynamic (torque-controlled trot) or kinematic", choices=("dynamic", "kinematic")
    )
    spawn: tuple[float, float, float] | None = param(None, help="robot spawn [x, y, yaw] (null = the world's default)")
    start_standing: bool = param(True, help="start standing (false: lying on the belly)")
    camera_width: int = param(640, help="head camera width (the real Go2 camera is 1280x720)", min=16, max=3840)
    camera_height: int = param(480, help="head camera height", min=16, max=2160)
    camera_fovy_deg: float = param(
        GO2.head_camera.fovy_deg, help="head camera vertical field of view, degrees", min=10.0, max=150.0
    )
    world_camera_width: int = param(640, help="world camera width", min=16, max=3840)
    world_camera_height: int = param(480, help="world camera height", min=16, max=2160)
    ball_speed: float = param(0.3, help="speed of the red ball on its path, m/s", min=0.0, max=3.0)
    ball_path: str = param(
        "",
        help="override the world's ball path: ellipse or figure8 ('' = world default)",
        choices=("", "ellipse", "figure8"),
    )
    seed: int = param(0, help="seed of the initial joint noise (used when init_noise > 0)")
    init_noise: float = param(0.0, help="uniform noise on the initial joint angles, rad", min=0.0, max=1.0)
    timestep: float = param(0.002, help="physics step, s", min=0.0001, max=0.01)
    control_decimation: int = param(2, help="controller every N physics steps (2 -> 250 Hz)", min=1, max=20)
    fall_tilt: float = param(1.0, help="tilt (rad) beyond which standing or walking counts as fallen", min=0.1)
    fall_height: float = param(0.14, help="base height (m) below which standing or walking counts as fallen", min=0.0)
    gait: GaitParams = param(GaitParams, help="trot controller gains and timing (sim/controller.py)")

    def __post_init__(self) -> None:
        if self.spawn is not None and len(self.spawn) == 0:
            self.spawn = None  # [] from a params file means "the world's default"

    def validate(self) -> None:
        if self.spawn is not None and len(self.spawn) != 3:
            raise ValueError(f"parameter 'spawn' must be [x, y, yaw] or null, got {list(self.spawn)}")
