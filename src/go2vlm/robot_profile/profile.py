"""`RobotProfile`: what the rest of go2vlm must know about one robot, and nothing it decides itself.

A profile is facts, frozen: the speed ceilings of the robot's own velocity API, its size, its head
camera, its lidar mount, its battery, the frame names it publishes under, and the topic its robot
end reports its health on. The safety gate takes its hard ceilings and the guard its footprint from
the profile of the robot it commands; the sim builds its model from the Go2's; the robot ends
publish under its frames; launch files name it (`robot: go2`). Adding a robot is a new profile,
not an edit of safety/ or sim/.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from go2vlm.geometry.camera import fovy_to_hfov
from go2vlm.geometry.scan import ScanSpec, mount_transform

__all__ = ["Battery", "Frames", "HeadCamera", "LidarMount", "RobotProfile", "SpeedCeilings"]


@dataclass(frozen=True)
class SpeedCeilings:
    """The robot's own velocity range: the hard ceiling of every speed limit (m/s, rad/s, all >= 0)."""

    vx_forward: float
    vx_backward: float  # as a positive number
    vy: float
    vyaw: float

    def clamp(self, vx: float, vy: float, vyaw: float) -> tuple[float, float, float]:
        """A velocity command clamped to the ceilings."""
        return (
            min(max(vx, -self.vx_backward), self.vx_forward),
            min(max(vy, -self.vy), self.vy),
            min(max(vyaw, -self.vyaw), self.vyaw),
        )


@dataclass(frozen=True)
class HeadCamera:
    """The camera in the robot's head: where it sits in the base frame (m, looking along base +x),
    its pitch (degrees, + = looking down), its vertical field of view (degrees) and the image size the
    real camera streams. The one camera mount: ranging and placement read it, no node declares it."""

    pos: tuple[float, float, float]
    fovy_deg: float
    width: int
    height: int
    pitch_deg: float = 0.0

    def hfov_deg(self, width: int, height: int) -> float:
        """The horizontal field of view at this image size (square pixels)."""
        return math.degrees(fovy_to_hfov(self.fovy_deg, width, height))


@dataclass(frozen=True)
class LidarMount:
    """The range sensor: its cloud's ROS topic and frame, and its pose in the base frame (m; pitch
    about y, rad)."""

    topic: str
    frame: str
    pos: tuple[float, float, float]
    pitch: float


@dataclass(frozen=True)
class Battery:
    cells: int  # in series
    wh: float  # energy of a full pack


@dataclass(frozen=True)
class Frames:
    """Frame names on /tf, /odom and the sensor topics."""

    odom: str = "odom"
    base: str = "base_link"
    camera: str = "camera_optical_frame"
    camera_link: str = "camera_link"


@dataclass(frozen=True)
class RobotProfile:
    name: str  # the robot end's node kind: `go2vlm run NAME`, `robot: NAME` in launch files
    description: str
    ceilings: SpeedCeilings
    stand_height: float  # base above the floor, standing (m)
    footprint_length: float  # legs included (m)
    footprint_width: float
    head_camera: HeadCamera
    lidar: LidarMount
    battery: Battery
    health_topic: str  # unitree_go/LowState the robot end publishes: the gate's health input
    frames: Frames = Frames()

    @property
    def head_camera_height(self) -> float:
        """The head camera above the floor, standing (m)."""
        return self.stand_height + self.head_camera.pos[2]

    def lidar_transforms(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Frame -> (R, t) into the base frame, for every frame a lidar cloud may come in."""
        return {
            self.lidar.frame: mount_transform(self.lidar.pos, self.lidar.pitch),
            self.frames.base: (np.eye(3), np.zeros(3)),
        }

    def scan_spec(self) -> ScanSpec:
        """The robot's /scan: its own legs (the footprint, 2 cm padded) left out of the cloud."""
        return ScanSpec(
            self_hx=self.footprint_length / 2 + 0.02, self_hy=self.footprint_width / 2 + 0.02,
            stand_height=self.stand_height,
        )  # fmt: skip
