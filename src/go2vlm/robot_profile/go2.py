"""The Unitree Go2, as facts: every number about the robot that more than one module needs, once.

Two robot ends drive a Go2, so there are two profiles of the same robot: `GO2`, a real Go2 through
the go2 driver (robots/go2/), and `SIM`, the MuJoCo Go2 (robots/go2_sim/). They differ only in
where their robot end reports the robot's health: the driver relays the Go2's 500 Hz rt/lowstate as
/go2/lowstate at its state rate, the sim publishes /lowstate as a Go2 does.

The names below the profiles are the same facts for modules that read one or two of them. The
Go2's own topics are robot facts too: the topic table (bus/topics.py) takes their names from here,
with their types and QoS (this floor imports nothing above geometry/).
"""

from __future__ import annotations

from dataclasses import replace

from go2vlm.robot_profile.profile import Battery, HeadCamera, LidarMount, RobotProfile, SpeedCeilings

__all__ = [
    "BASE_FRAME",
    "DRIVER_LOWSTATE_TOPIC",
    "FOOTPRINT_LENGTH",
    "FOOTPRINT_WIDTH",
    "GO2",
    "HEAD_CAMERA_FOVY_DEG",
    "HEAD_CAMERA_HEIGHT",
    "HEAD_CAMERA_POS",
    "LIDAR_TOPIC",
    "LOWSTATE_TOPIC",
    "SIM",
    "head_camera_hfov_deg",
]

# The Go2's topics in ROS form (its DDS topic rt/<name>), and the go2 driver's relay.
LOWSTATE_TOPIC = "/lowstate"  # rt/lowstate: the Go2 (and the sim, as one) reports its state here
LIDAR_TOPIC = "/utlidar/cloud"  # rt/utlidar/cloud: the L1 lidar's cloud, in the lidar's frame
DRIVER_LOWSTATE_TOPIC = "/go2/lowstate"  # the go2 driver relays rt/lowstate here, at its state rate

GO2 = RobotProfile(
    name="go2",
    description="a Unitree Go2 through the go2 driver (Unitree's DDS protocol or WebRTC)",
    # Sport-mode Move() ranges (Unitree's documented limits): the hard ceiling of every speed limit.
    ceilings=SpeedCeilings(vx_forward=3.8, vx_backward=2.5, vy=1.0, vyaw=4.0),
    stand_height=0.32,
    # The footprint, legs included.
    footprint_length=0.70,
    footprint_width=0.31,
    # Looking along base +x; the real camera streams 1280x720.
    head_camera=HeadCamera(pos=(0.32715, 0.0, 0.04297), fovy_deg=58.0, width=1280, height=720),
    # L1 lidar (under the chin): the robot publishes its cloud on its DDS bus as sensor_msgs/PointCloud2
    # on rt/utlidar/cloud, which is the ROS 2 topic /utlidar/cloud, in the lidar's frame. The mount pose
    # (the sensor looks forward and down, tilted ~165 deg about y) is the one public Go2 launch files
    # use (docs/safety.md#range-sensing).
    lidar=LidarMount(topic=LIDAR_TOPIC, frame="utlidar_lidar", pos=(0.28945, 0.0, -0.046825), pitch=2.8782),
    # A Go2's standard pack: 8 Li-ion cells in series (28.8 V nominal), 8000 mAh.
    battery=Battery(cells=8, wh=28.8 * 8.0),
    health_topic=DRIVER_LOWSTATE_TOPIC,
)

SIM = replace(GO2, name="sim", description="the MuJoCo Go2 (go2vlm's simulator)", health_topic=LOWSTATE_TOPIC)

FOOTPRINT_LENGTH = GO2.footprint_length
FOOTPRINT_WIDTH = GO2.footprint_width
HEAD_CAMERA_POS = GO2.head_camera.pos
HEAD_CAMERA_FOVY_DEG = GO2.head_camera.fovy_deg
HEAD_CAMERA_HEIGHT = GO2.head_camera_height
BASE_FRAME = GO2.frames.base
head_camera_hfov_deg = GO2.head_camera.hfov_deg
