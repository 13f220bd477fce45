"""The sim node's outputs: every topic it publishes about the robot and the world, built from the
physics state at the instant it describes (the state, the clock, the ground truth, the lidar, the
lowstate with its motor and battery models, the static transforms) and the frames the render thread
draws (`frame` and `boxes`: it is the render thread's `FrameSink`). Topics, types and QoS are in
sim_node.py's contract.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from go2vlm.bus import Node
from go2vlm.bus.topics import (
    CAMERA_IMAGE,
    CAMERA_INFO,
    CLOCK,
    IMU,
    JOINT_STATES,
    LIDAR_CLOUD,
    LOWSTATE,
    ODOM,
    SCAN,
    SIM_DETECTIONS,
    SIM_GROUND_TRUTH,
    TF,
    TF_STATIC,
    WORLD_CAMERA_IMAGE,
    WORLD_CAMERA_INFO,
    Topic,
)
from go2vlm.geometry.camera import PinholeCamera, fovy_to_hfov
from go2vlm.msgs.base_state import base_state_messages, transform_stamped
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.image import camera_info, numpy_to_image
from go2vlm.msgs.pointcloud import scan_from_cloud, xyz_cloud
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.sensor_msgs import CameraInfo, Image, JointState
from go2vlm.msgs.std_msgs import Header
from go2vlm.msgs.tf2_msgs import TFMessage
from go2vlm.msgs.vision_msgs import detection_array
from go2vlm.robot_profile import RobotProfile
from go2vlm.robots.go2_sim.lowstate import Faults, low_state
from go2vlm.sim import Go2Sim
from go2vlm.sim.lidar import Lidar
from go2vlm.sim.state import RobotState
from go2vlm.sim.thermal import Battery, MotorThermal

__all__ = ["SimPublishers"]

# camera_link (x forward, y left, z up) and the optical frame (x right, y down, z forward), as
# columns expressed in MuJoCo's camera frame (x right, y up, looking along -z).
_MJ_TO_LINK = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
_MJ_TO_OPTICAL = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
WORLD_CAMERA_FRAME = "world_camera_optical_frame"


def _mat_quat(r: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(r, dtype=float).reshape(9))
    return q


class SimPublishers:
    """The sim node's publishers and the models behind /lowstate. `cfg` is the node's SimNodeConfig
    at start-up; live parameters are read from the node each time."""

    def __init__(self, node: Node, sim: Go2Sim, robot: RobotProfile, cfg: Any, world_camera: bool) -> None:
        self.node = node
        self.sim = sim
        self.robot = robot
        self.cfg = cfg
        self.odom = ODOM.publisher(node)
        self.imu = IMU.publisher(node)
        self.joints = JOINT_STATES.publisher(node)
        self.tf = TF.publisher(node)
        self.tf_static = TF_STATIC.publisher(node)
        self.clock = CLOCK.publisher(node)
        self.gt = SIM_GROUND_TRUTH.publisher(node)
        self.lowstate = LOWSTATE.publisher(node, name=robot.health_topic)
        self.thermal = MotorThermal()
        self.battery = Battery(cfg.battery_pct)
        self._health_t = sim.time
        self.dets = SIM_DETECTIONS.publisher(node) if cfg.detections else None
        self.lidar = Lidar(sim.model, sim.model.body("base").id)
        self._scan_spec, self._lidar_tfs = robot.scan_spec(), robot.lidar_transforms()
        self.cloud = LIDAR_CLOUD.publisher(node, name=robot.lidar.topic)
        self.scan = SCAN.publisher(node)
        self.cams: dict[str, tuple[Any, Any, CameraInfo]] = {}  # key -> (image pub, info pub, CameraInfo)
        if cfg.camera:
            w, h = cfg.camera_width, cfg.camera_height
            self._camera("head", (CAMERA_IMAGE, CAMERA_INFO), robot.frames.camera, w, h, cfg.camera_fovy_deg)
        if world_camera:
            w, h = cfg.world_camera_width, cfg.world_camera_height
            fovy = float(sim.model.cam_fovy[sim.model.camera("world_camera").id])
            self._camera("world", (WORLD_CAMERA_IMAGE, WORLD_CAMERA_INFO), WORLD_CAMERA_FRAME, w, h, fovy)

    def _camera(
        self, key: str, topics: tuple[Topic[Image], Topic[CameraInfo]], frame: str, w: int, h: int, fovy_deg: float
    ) -> None:
        info = camera_info(PinholeCamera.from_hfov(w, h, fovy_to_hfov(fovy_deg, w, h)))
        info.header.frame_id = frame
        self.cams[key] = (
            topics[0].publisher(self.node),
            topics[1].publisher(self.node),
            info,
        )

    # -- from the physics thread ---------------------------------------------------------------
    def state(self, s: RobotState, t: float) -> None:
        """/odom, /imu, /joint_states, /tf at `t`, and /lowstate when it is due."""
        stamp = self.node.stamp(t)
        frames = self.robot.frames
        odom, imu, tf = base_state_messages(
            stamp,
            frames.odom,
            frames.base,
            s.position,
            s.quaternion,
            s.lin_vel_body,
            s.ang_vel_body,
            s.imu_gyro,
            s.imu_acc,
        )
        self.odom.publish(odom)
        self.imu.publish(imu)
        self.joints.publish(
            JointState(
                header=Header(stamp=stamp, frame_id=""),
                name=list(s.joint_names),
                position=[float(v) for v in s.joint_pos],
                velocity=[float(v) for v in s.joint_vel],
                effort=[float(v) for v in s.joint_torque],
            )
        )
        self.tf.publish(tf)
        self._lowstate(s)

    def _lowstate(self, s: RobotState) -> None:
        """Advance the motor and battery models to this state's time, then publish /lowstate."""
        if s.time - self._health_t < 1.0 / self.cfg.lowstate_rate_hz - 1e-9:
            return
        dt, self._health_t = s.time - self._health_t, s.time
        temps = self.thermal.step(dt, s.joint_torque)
        soc = self.battery.step(dt, s.joint_torque, s.joint_vel)
        cfg = self.node.config  # the fault_* parameters are live: read each time
        if cfg.fault_lowstate_silent:
            return
        faults = Faults(cfg.fault_motor_temp_c, cfg.fault_battery_pct, cfg.fault_tilt_deg)
        self.lowstate.publish(low_state(s, temps, soc, self.battery.voltage, faults))

    def sim_clock(self, t: float) -> None:
        self.clock.publish(Clock(clock=Time.from_sec(t)))

    def ground_truth(self, t: float) -> None:
        header = Header(stamp=self.node.stamp(t), frame_id="world")
        tfs = [
            transform_stamped(header, f"gt/{name}", p.position, p.quaternion)
            for name, p in self.sim.object_poses().items()
        ]
        self.gt.publish(TFMessage(transforms=tfs))

    def lidar_scan(self, t: float, period: float) -> None:
        points = self.lidar.scan(self.sim.data)
        cloud = xyz_cloud(Header(stamp=self.node.stamp(t), frame_id=self.robot.lidar.frame), points)
        self.cloud.publish(cloud)
        stance = self.lidar.stance(self.sim.data)
        scan = scan_from_cloud(cloud, self._scan_spec, self._lidar_tfs, self.robot.frames.base, period, stance)
        if scan is not None:
            self.scan.publish(scan)

    # -- from the render thread (FrameSink) ----------------------------------------------------
    def frame(self, key: str, rgb: np.ndarray, stamp: float) -> None:
        img_pub, info_pub, info = self.cams[key]
        header = Header(stamp=self.node.stamp(stamp), frame_id=info.header.frame_id)
        img_pub.publish(numpy_to_image(rgb, "rgb8", header))
        info.header = header
        info_pub.publish(info)

    def boxes(self, boxes: dict[str, tuple[int, int, int, int]], stamp: float) -> None:
        if self.dets is None:
            return
        header = Header(stamp=self.node.stamp(stamp), frame_id=self.robot.frames.camera)
        self.dets.publish(detection_array(header, ((name, box, 1.0) for name, box in sorted(boxes.items()))))

    # -- once, at start-up ---------------------------------------------------------------------
    def static(self, has_world_camera: bool) -> None:
        """/tf_static (the camera and lidar mounts, the odom frame and the world camera's, if the
        world has one) and the cameras' latched camera_info."""
        m, d = self.sim.model, self.sim.data
        frames = self.robot.frames
        header = Header(stamp=self.node.stamp(), frame_id=frames.base)
        world = Header(stamp=header.stamp, frame_id="world")
        base = m.body("base").id
        rb = d.xmat[base].reshape(3, 3)
        cam = m.camera("head_camera").id
        rc = d.cam_xmat[cam].reshape(3, 3)
        pos = rb.T @ (d.cam_xpos[cam] - d.xpos[base])
        rel = rb.T @ rc
        tfs = [
            transform_stamped(world, frames.odom, np.zeros(3), np.array([1.0, 0, 0, 0])),
            transform_stamped(header, frames.camera_link, pos, _mat_quat(rel @ _MJ_TO_LINK)),
            transform_stamped(header, frames.camera, pos, _mat_quat(rel @ _MJ_TO_OPTICAL)),
            transform_stamped(
                header, self.robot.lidar.frame, np.array(self.robot.lidar.pos), _mat_quat(self.lidar.mount_r)
            ),
        ]
        if has_world_camera:
            wc = m.camera("world_camera").id
            optical = _mat_quat(d.cam_xmat[wc].reshape(3, 3) @ _MJ_TO_OPTICAL)
            tfs.append(transform_stamped(world, WORLD_CAMERA_FRAME, d.cam_xpos[wc], optical))
        self.tf_static.publish(TFMessage(transforms=tfs))
        for _, info_pub, info in self.cams.values():
            info.header.stamp = self.node.stamp()
            info_pub.publish(info)
