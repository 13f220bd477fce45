"""A robot base's state as ROS messages: /odom, /imu and the odom -> base transform on /tf.

Shared by the sim node and the go2 driver, so that the simulated and the real robot publish the same
messages from the same numbers.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.geometry_msgs import (
    Point,
    Pose,
    PoseWithCovariance,
    Quaternion,
    Transform,
    TransformStamped,
    Twist,
    TwistWithCovariance,
    Vector3,
)
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.sensor_msgs import Imu
from go2vlm.msgs.std_msgs import Header
from go2vlm.msgs.tf2_msgs import TFMessage

__all__ = ["base_state_messages", "quaternion", "transform_stamped", "vector3"]

# A vector given as a list or as a NumPy array (the sim's state).
Floats = Sequence[float] | np.ndarray


def vector3(v: Floats) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def quaternion(wxyz: Floats) -> Quaternion:
    """From (w, x, y, z), MuJoCo's and Unitree's order."""
    return Quaternion(x=float(wxyz[1]), y=float(wxyz[2]), z=float(wxyz[3]), w=float(wxyz[0]))


def transform_stamped(header: Header, child: str, pos: Floats, wxyz: Floats) -> TransformStamped:
    return TransformStamped(header=header, child_frame_id=child, transform=Transform(vector3(pos), quaternion(wxyz)))


def base_state_messages(
    stamp: Time,
    odom_frame: str,
    base_frame: str,
    position: Floats,
    wxyz: Floats,
    lin_vel_body: Floats,
    ang_vel_body: Floats,
    gyro: Floats,
    acc: Floats,
) -> tuple[Odometry, Imu, TFMessage]:
    """Odometry (odom -> base, twist in the base frame), Imu (base frame) and the odom -> base TF,
    all with this stamp. Velocities are in the base frame; `wxyz` is the base orientation in odom."""
    header = Header(stamp=stamp, frame_id=odom_frame)
    odom = Odometry(
        header=header,
        child_frame_id=base_frame,
        pose=PoseWithCovariance(pose=Pose(position=Point(*map(float, position)), orientation=quaternion(wxyz))),
        twist=TwistWithCovariance(twist=Twist(linear=vector3(lin_vel_body), angular=vector3(ang_vel_body))),
    )
    imu = Imu(
        header=Header(stamp=stamp, frame_id=base_frame),
        orientation=quaternion(wxyz),
        angular_velocity=vector3(gyro),
        linear_acceleration=vector3(acc),
    )
    tf = TFMessage(transforms=[transform_stamped(header, base_frame, position, wxyz)])
    return odom, imu, tf
