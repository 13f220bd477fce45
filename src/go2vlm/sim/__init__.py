"""go2vlm.sim: a pure-Python MuJoCo simulation of the Unitree Go2.

No DDS/ROS here: the sim node (robots/go2_sim/) wraps this API.  Importing the package selects a
headless GL backend (``MUJOCO_GL=egl``, else ``osmesa``) *before* MuJoCo is
imported, so import ``go2vlm.sim`` before ``mujoco`` if you can (a late import
is repaired when the first renderer is created).

Quick start::

    from go2vlm.sim import Go2Sim, SimConfig

    sim = Go2Sim(SimConfig(world="follow_ball", mode="dynamic",
                           camera_width=640, camera_height=480, ball_speed=0.3))
    sim.set_command(0.5, 0.0, 0.2)        # vx, vy (m/s, heading frame), vyaw (rad/s)
    sim.advance(1.0)                      # simulate one second (500 physics steps)
    rgb = sim.render_head()               # (480, 640, 3) uint8, robot never visible
    st = sim.state()                      # RobotState dataclass
    k = sim.head_intrinsics()             # a PinholeCamera: fx, fy, cx, cy, .k

API
---
``SimConfig`` (sim/config.py; the sim node's parameters are the same fields), main fields::

    world="follow_ball"        # "vision_test" | "follow_ball" | "obstacles" | "distractors" | "empty" | .xml path
    mode="dynamic"             # "dynamic" (torque-controlled trot) | "kinematic" (animated)
    spawn=None                 # (x, y, yaw) or None for the world's default
    start_standing=True        # False: start lying on the belly
    camera_width=640, camera_height=480, camera_fovy_deg=58.0   # head camera (vertical fov)
    world_camera_width=640, world_camera_height=480
    ball_speed=0.3, ball_path="" ("ellipse" | "figure8"), seed=0, init_noise=0.0
    timestep=0.002, control_decimation=2 (250 Hz controller), fall_tilt=1.0, fall_height=0.14
    gait=GaitParams()          # trot period, gains, ... (go2vlm.sim.controller)

``Go2Sim(config: SimConfig | None = None)``:

- ``step(n: int = 1) -> None``; ``advance(dt_s: float) -> None``; ``reset() -> None``
- ``set_command(vx, vy, vyaw) -> np.ndarray`` clamped to the Go2 sport-mode ranges
  (the Go2 profile, robot_profile/go2.py); ``stop()``
- ``stand_up(duration=1.2)``, ``lie_down(duration=1.5)``, ``damp()``,
  ``recovery_stand() -> bool`` (rolls over from side/back, then stands; False if
  already standing); ``set_ball_speed(speed)``
- ``push(dv_world, dw_body=(0, 0, 0))``: velocity kick on the base (tests)
- ``mode -> str``: one of ``MODES`` = lying, standing_up, standing, walking,
  lying_down, damped, fallen, recovering; ``fell -> bool``; ``time``; ``dt``
- ``state() -> RobotState`` (time, mode, fell, position, quaternion (w,x,y,z),
  lin_vel_world, lin_vel_body, ang_vel_body, ang_vel_world, imu_gyro, imu_acc,
  imu_rpy, joint_names, joint_pos, joint_vel, joint_torque, foot_names,
  foot_contact, foot_force, command).  Joint order is Unitree's: FR, FL, RR, RL
  x (hip, thigh, calf).
- ``object_poses() -> dict[str, Pose]``: "go2" plus every named world body
  ("red_ball", "red_sphere", "green_box", "blue_cylinder", ...).
- ``render_head(width=None, height=None) -> np.ndarray`` (H, W, 3) uint8 RGB;
  ``render_world_camera(width=None, height=None)`` likewise (static camera).
- ``render_head_segmentation(width=None, height=None)`` (H, W) geom ids;
  ``robot_geom_ids()``
- ``head_intrinsics(width=None, height=None) -> PinholeCamera``,
  ``world_camera_intrinsics()``; ``head_camera_pose() -> Pose`` (ROS optical
  frame: z forward, x right, y down); ``project_to_head(points_world, width=None,
  height=None) -> (uv, in_front)``; ``close()`` (also a context manager).

Head camera: base frame (0.32715, 0, 0.04297), optical axis along base +x.
Robot geoms are in group 2, which the head camera does not draw.
``available_worlds()`` lists the bundled world files.
"""

from go2vlm.sim.gl import preload_triton, setup_gl

setup_gl()
preload_triton()  # before any GL context: Mesa's libLLVM first would crash a later `import torch._dynamo`

from go2vlm.sim.config import SimConfig  # noqa: E402
from go2vlm.sim.controller import GaitParams  # noqa: E402
from go2vlm.sim.go2sim import MODES, Go2Sim  # noqa: E402
from go2vlm.sim.state import Pose, RobotState  # noqa: E402
from go2vlm.sim.worlds import available_worlds  # noqa: E402

__all__ = [
    "MODES",
    "GaitParams",
    "Go2Sim",
    "Pose",
    "RobotState",
    "SimConfig",
    "available_worlds",
    "setup_gl",
]
