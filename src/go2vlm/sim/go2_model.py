"""Our own MJCF model of the Unitree Go2, built from primitives.

Dimensions, masses, joint ranges and torque limits follow Unitree's published
Go2 figures; geometry is deliberately simple (boxes, capsules, spheres).

Geom groups: 2 = robot visuals (hidden from the head camera), 3 = robot
collision shapes (never drawn).  Robot shapes have contype=2/conaffinity=1 so
they touch the world (contype=1) but never each other.
"""

from __future__ import annotations

import numpy as np

from go2vlm.robot_profile.go2 import GO2

LEG_NAMES: tuple[str, ...] = ("FR", "FL", "RR", "RL")  # Unitree motor order
JOINT_KINDS: tuple[str, ...] = ("hip", "thigh", "calf")
JOINT_NAMES: tuple[str, ...] = tuple(f"{leg}_{k}_joint" for leg in LEG_NAMES for k in JOINT_KINDS)
FOOT_GEOMS: tuple[str, ...] = tuple(f"{leg}_foot" for leg in LEG_NAMES)

TRUNK_SIZE = (0.3762, 0.0935, 0.114)
HIP_X, HIP_Y = 0.1934, 0.0465
THIGH_OFFSET = 0.0955
THIGH_LEN = 0.213
CALF_LEN = 0.213
FOOT_RADIUS = 0.022
# +1 for left legs, -1 for right legs / +1 front, -1 rear.
LEG_SIDE = np.array([-1.0, 1.0, -1.0, 1.0])
LEG_FRONT = np.array([1.0, 1.0, -1.0, -1.0])
HIP_OFFSETS = np.stack([LEG_FRONT * HIP_X, LEG_SIDE * HIP_Y, np.zeros(4)], axis=1)

HIP_RANGE = (-1.0472, 1.0472)
THIGH_RANGE_FRONT = (-1.5708, 3.4907)
THIGH_RANGE_REAR = (-0.5236, 4.5379)
CALF_RANGE = (-2.7227, -0.83776)
TORQUE_LIMITS = np.tile([23.7, 23.7, 45.43], 4)

IMU_POS = (-0.02557, 0.0, 0.04232)

# Published link masses (kg): trunk 6.921, hip 0.678, thigh 1.152, calf 0.154, foot 0.04.
TRUNK_MASS = 6.921
HIP_MASS, THIGH_MASS, CALF_MASS, FOOT_MASS = 0.678, 1.152, 0.154, 0.04
TOTAL_MASS = TRUNK_MASS + 4 * (HIP_MASS + THIGH_MASS + CALF_MASS + FOOT_MASS)

STAND_Q = np.tile([0.0, 0.78, -1.56], 4)  # foot under the hip, base ~0.32 m
LIE_Q = np.tile([0.0, 1.25, -2.70], 4)  # folded legs, belly near the ground
LIE_HEIGHT = 0.11
STAND_HEIGHT = GO2.stand_height
HEAD_CAMERA_POS = GO2.head_camera.pos

GREY = "0.62 0.64 0.66 1"
DARK = "0.12 0.12 0.13 1"
BLACK = "0.05 0.05 0.05 1"


def _f(v: tuple[float, ...] | list[float] | np.ndarray) -> str:
    return " ".join(f"{x:.6g}" for x in v)


def _leg_xml(i: int) -> str:
    leg = LEG_NAMES[i]
    s = LEG_SIDE[i]
    front = LEG_FRONT[i] > 0
    thigh_range = THIGH_RANGE_FRONT if front else THIGH_RANGE_REAR
    hip_pos = HIP_OFFSETS[i]
    # Hip motor housing sits slightly outboard, thigh hangs at the 0.0955 offset.
    return f"""
    <body name="{leg}_hip" pos="{_f(hip_pos)}">
      <inertial pos="{-0.0054 * LEG_FRONT[i]:.4f} {0.0018 * s:.4f} 0" mass="{HIP_MASS}"
                diaginertia="0.00048 0.00088 0.00059"/>
      <joint name="{leg}_hip_joint" class="go2_hip" range="{_f(HIP_RANGE)}"/>
      <geom class="go2_visual" type="cylinder" size="0.046 0.024" pos="0 {0.008 * s:.4f} 0"
            zaxis="0 1 0" rgba="{GREY}"/>
      <geom class="go2_visual" type="cylinder" size="0.04 0.02" pos="{-0.05 * LEG_FRONT[i]:.4f} 0 0"
            zaxis="1 0 0" rgba="{GREY}"/>
      <body name="{leg}_thigh" pos="0 {THIGH_OFFSET * s:.4f} 0">
        <inertial pos="-0.0037 {-0.022 * s:.4f} -0.033" mass="{THIGH_MASS}"
                  diaginertia="0.0058 0.0058 0.0010"/>
        <joint name="{leg}_thigh_joint" class="go2_thigh" range="{_f(thigh_range)}"/>
        <geom class="go2_visual" type="cylinder" size="0.045 0.02" zaxis="0 1 0" rgba="{DARK}"/>
        <geom class="go2_visual" type="box" size="0.017 0.0125 0.1065" pos="0 0 -0.1065" rgba="{DARK}"/>
        <geom class="go2_collision" type="capsule" size="0.02" fromto="0 0 -0.03 0 0 -0.19"/>
        <body name="{leg}_calf" pos="0 0 {-THIGH_LEN}">
          <inertial pos="0.0055 0 -0.115" mass="{CALF_MASS + FOOT_MASS}"
                    diaginertia="0.0016 0.0016 0.00004"/>
          <joint name="{leg}_calf_joint" class="go2_calf" range="{_f(CALF_RANGE)}"/>
          <geom class="go2_visual" type="capsule" size="0.013" fromto="0 0 0 0 0 -0.195" rgba="{BLACK}"/>
          <geom class="go2_visual" type="sphere" size="{FOOT_RADIUS}" pos="0 0 {-CALF_LEN}" rgba="{BLACK}"/>
          <geom class="go2_collision" type="capsule" size="0.014" fromto="0 0 -0.02 0 0 -0.17"/>
          <geom name="{leg}_foot" class="go2_foot" type="sphere" size="{FOOT_RADIUS}" pos="0 0 {-CALF_LEN}"/>
          <site name="{leg}_foot_site" pos="0 0 {-CALF_LEN}" size="0.01"/>
        </body>
      </body>
    </body>"""


def robot_defaults_xml() -> str:
    return """
  <default class="go2">
    <joint damping="0.05" armature="0.01" frictionloss="0.1" limited="true"/>
    <default class="go2_hip"><joint axis="1 0 0"/></default>
    <default class="go2_thigh"><joint axis="0 1 0"/></default>
    <default class="go2_calf"><joint axis="0 1 0"/></default>
    <default class="go2_visual">
      <geom contype="0" conaffinity="0" group="2" density="0" mass="0"/>
    </default>
    <default class="go2_collision">
      <geom contype="2" conaffinity="1" group="3" density="0" mass="0" rgba="1 0 0 0.3"/>
    </default>
    <default class="go2_foot">
      <geom contype="2" conaffinity="1" group="3" density="0" mass="0" condim="3"
            friction="0.9 0.02 0.01" priority="1"/>
    </default>
  </default>"""


def robot_body_xml(pos: tuple[float, float, float] = (0.0, 0.0, STAND_HEIGHT), yaw: float = 0.0) -> str:
    """The ``<body name="base">`` element, spawned at ``pos`` with heading ``yaw``."""
    quat = (np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2))
    hx, hy, hz = (s / 2 for s in TRUNK_SIZE)
    legs = "".join(_leg_xml(i) for i in range(4))
    return f"""
  <body name="base" pos="{_f(pos)}" quat="{_f(quat)}" childclass="go2">
    <freejoint name="base_free"/>
    <inertial pos="0.021 0 -0.005" mass="{TRUNK_MASS}" diaginertia="0.0245 0.098 0.107"/>
    <geom class="go2_visual" type="box" size="{hx} {hy} {hz}" rgba="{GREY}"/>
    <geom class="go2_visual" type="box" size="0.16 0.05 0.012" pos="-0.01 0 {hz}" rgba="0.5 0.52 0.54 1"/>
    <geom class="go2_visual" type="box" size="0.055 0.046 0.045" pos="0.245 0 0.012" rgba="{GREY}"/>
    <geom class="go2_visual" type="box" size="0.012 0.04 0.03" pos="0.298 0 0.012" rgba="{BLACK}"/>
    <geom class="go2_visual" type="sphere" size="0.009" pos="0.306 0.022 0.022" rgba="0.3 0.7 1 1"/>
    <geom class="go2_visual" type="sphere" size="0.009" pos="0.306 -0.022 0.022" rgba="0.3 0.7 1 1"/>
    <geom class="go2_visual" type="cylinder" size="0.03 0.02" pos="0.27 0 -0.055" rgba="{DARK}"/>
    <geom class="go2_collision" type="box" size="{hx} {hy} {hz}"/>
    <geom class="go2_collision" type="box" size="0.055 0.046 0.045" pos="0.245 0 0.012"/>
    <site name="imu" pos="{_f(IMU_POS)}" size="0.01"/>
    <camera name="head_camera" pos="{_f(HEAD_CAMERA_POS)}" xyaxes="0 -1 0 0 0 1" fovy="{GO2.head_camera.fovy_deg:g}"/>
    {legs}
  </body>"""


def robot_actuators_xml() -> str:
    motors = []
    for name, lim in zip(JOINT_NAMES, TORQUE_LIMITS, strict=True):
        motors.append(
            f'    <motor name="{name.replace("_joint", "")}" joint="{name}" '
            f'ctrlrange="{-lim} {lim}" ctrllimited="true"/>'
        )
    return "\n".join(motors)


def robot_sensors_xml() -> str:
    return """
    <gyro name="imu_gyro" site="imu"/>
    <accelerometer name="imu_acc" site="imu"/>
    <framequat name="imu_quat" objtype="site" objname="imu"/>"""
