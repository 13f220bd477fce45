"""The driver turns the robot's rt/utlidar/cloud into /scan (the sim's code, geometry/scan.py); a cloud
in an unknown frame is dropped and counted, never read as free space."""

from __future__ import annotations

import numpy as np
import pytest
from busutil import Recorder, wait_for

from go2vlm.bus import QOS_SENSOR, Node, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.pointcloud import xyz_cloud
from go2vlm.msgs.sensor_msgs import LaserScan, PointCloud2
from go2vlm.msgs.std_msgs import Header
from go2vlm.robot_profile.go2 import GO2


class _Robot(Node):
    name = "lidar_robot"


def test_driver_publishes_scan_from_the_robot_cloud() -> None:
    driver = make_node("go2", params={"camera_rate_hz": 1.0, "rpc_timeout_s": 0.2})
    robot, scans = _Robot(), Recorder()
    cloud = robot.create_publisher(PointCloud2, GO2.lidar.topic, QOS_SENSOR)
    robot.create_subscription(LaserScan, "/scan", scans, QOS_SENSOR)
    r, t = GO2.lidar_transforms()[GO2.lidar.frame]
    wall = np.array([[1.5, y, 0.0] for y in np.linspace(-0.4, 0.4, 9)])
    with running(driver, robot):
        bad = xyz_cloud(Header(frame_id="somewhere"), wall)
        good = xyz_cloud(Header(frame_id=GO2.lidar.frame), (wall - t) @ r)
        assert wait_for(lambda: (cloud.publish(bad), cloud.publish(good), len(scans))[2] > 0, 30)
        scan = scans.msgs()[-1]
        assert scan.header.frame_id == GO2.frames.base
        assert min(scan.ranges) == pytest.approx(1.5, abs=1e-3)
        assert driver.counters.get("bad_cloud", 0) >= 1
