"""The Unitree Go2, as facts: every number about the robot that more than one module needs, once.

Pure, so the safety gate, the driver, the simulator and the behaviours
all read the same figures.
"""

from __future__ import annotations

import math

import numpy as np

from go2vlm.geometry.camera import fovy_to_hfov
from go2vlm.geometry.scan import ScanSpec, mount_transform

__all__ = [
    "BASE_FRAME",
    "BATTERY_CELLS",
    "BATTERY_WH",
    "CAMERA_FRAME",
    "FOOTPRINT_LENGTH",
    "FOOTPRINT_WIDTH",
    "HEAD_CAMERA_FOVY_DEG",
    "HEAD_CAMERA_HEIGHT",
    "HEAD_CAMERA_POS",
    "LIDAR_FRAME",
    "LIDAR_MOUNT_PITCH",
    "LIDAR_MOUNT_POS",
    "LIDAR_TOPIC",
    "ODOM_FRAME",
    "STAND_HEIGHT",
    "VX_MAX_BACKWARD",
    "VX_MAX_FORWARD",
    "VYAW_MAX",
    "VY_MAX",
    "clamp_velocity",
    "head_camera_hfov_deg",
    "lidar_scan_spec",
    "lidar_transforms",
]

# Sport-mode Move() ranges (Unitree's documented limits): the hard ceiling of every speed limit.
VX_MAX_FORWARD = 3.8  # m/s
VX_MAX_BACKWARD = 2.5  # m/s, as a positive number
VY_MAX = 1.0  # m/s
VYAW_MAX = 4.0  # rad/s

# Body: base height standing (m) and the footprint, legs included (m).
STAND_HEIGHT = 0.32
FOOTPRINT_LENGTH = 0.70
FOOTPRINT_WIDTH = 0.31

# Head camera: position in the base frame (m), looking along base +x, and its vertical field of
# view (degrees); the real camera streams 1280x720.
HEAD_CAMERA_POS = (0.32715, 0.0, 0.04297)
HEAD_CAMERA_FOVY_DEG = 58.0
HEAD_CAMERA_HEIGHT = STAND_HEIGHT + HEAD_CAMERA_POS[2]  # above the floor, standing

# Battery: a Go2's standard pack, 8 Li-ion cells in series (28.8 V nominal) and 8000 mAh.
BATTERY_CELLS = 8
BATTERY_WH = 28.8 * 8.0

# L1 lidar (under the chin): the robot publishes its cloud on its DDS bus as sensor_msgs/PointCloud2
# on rt/utlidar/cloud, which is the ROS 2 topic /utlidar/cloud; in the lidar's frame. The mount pose
# in base_link (m, rad about y: the sensor looks forward and down, tilted ~165 deg) is the one public
# Go2 launch files use (docs/safety.md#range-sensing).
LIDAR_TOPIC = "/utlidar/cloud"  # DDS rt/utlidar/cloud
LIDAR_FRAME = "utlidar_lidar"
LIDAR_MOUNT_POS = (0.28945, 0.0, -0.046825)
LIDAR_MOUNT_PITCH = 2.8782

# Frame names on /tf, /odom and the camera topics.
ODOM_FRAME = "odom"
BASE_FRAME = "base_link"
CAMERA_FRAME = "camera_optical_frame"


def lidar_transforms() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Frame -> (R, t) into base_link, for every frame a lidar cloud may come in."""
    return {LIDAR_FRAME: mount_transform(LIDAR_MOUNT_POS, LIDAR_MOUNT_PITCH), BASE_FRAME: (np.eye(3), np.zeros(3))}


def lidar_scan_spec() -> ScanSpec:
    """The /scan of a Go2: its own legs (the footprint, 2 cm padded) left out of the cloud."""
    return ScanSpec(self_hx=FOOTPRINT_LENGTH / 2 + 0.02, self_hy=FOOTPRINT_WIDTH / 2 + 0.02)


def clamp_velocity(vx: float, vy: float, vyaw: float) -> tuple[float, float, float]:
    """A velocity command clamped to the sport-mode ranges."""
    return (
        min(max(vx, -VX_MAX_BACKWARD), VX_MAX_FORWARD),
        min(max(vy, -VY_MAX), VY_MAX),
        min(max(vyaw, -VYAW_MAX), VYAW_MAX),
    )


def head_camera_hfov_deg(width: int, height: int) -> float:
    """The head camera's horizontal field of view at this image size (square pixels)."""
    return math.degrees(fovy_to_hfov(HEAD_CAMERA_FOVY_DEG, width, height))
