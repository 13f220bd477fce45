"""sim: a simulated Unitree Go2 (MuJoCo) that speaks ROS 2.

Steps a `Go2Sim` on its own physics thread, in real time by default (`rtf`), or as fast as the
machine allows (`fast: true`). Cameras are rendered on a separate render thread that owns its GL
context and works from a snapshot of the physics state, so rendering never stalls the physics.

Subscribes:
  /emergency_stop             std_msgs/Bool         true latches the e-stop here too (safety/estop.py):
                                                    Damp, as the go2 driver does on a real Go2, and no
                                                    /cmd_vel, no standing up until released; false does
                                                    NOT release
  /emergency_stop/release     std_msgs/String       data == `release_token` ("RELEASE"), exactly, releases;
                                                    the robot stays down until "recover" or "stand", and
                                                    /cmd_vel moves it only after passing through zero
  /cmd_vel                    geometry_msgs/Twist   body-frame velocity (linear.x, linear.y, angular.z),
                                                    only from the one safety gate (safety/commander.py):
                                                    another writer stops the robot; after such a stop or
                                                    a release, motion starts from a zero command;
                                                    zeroed after `cmd_timeout_s` without a valid command
                                                    (the safety gate streams at >= 20 Hz); seconds of the
                                                    node's clock: sim time with use_sim_time, else wall
  /safety/heartbeat           std_msgs/String       (latched) which /cmd_vel writer is a safety gate
  /go2/command                 std_msgs/String       posture, as the go2 driver takes it: stand, balance,
                                                    recover, sit/standdown (lie down), damp; only without
                                                    `unitree` (then the driver sends sport RPCs instead);
                                                    while the e-stop is latched only damp, standdown, stop
  /sim/push                   geometry_msgs/Twist   disturbance test: an instant kick of the base, linear =
                                                    velocity change in the world frame (m/s, |v| <= 10),
                                                    angular = in the base frame (rad/s, |w| <= 30)
Publishes:
  /camera/image_raw           sensor_msgs/Image     head camera, rgb8, frame camera_optical_frame
  /camera/camera_info         sensor_msgs/CameraInfo  latched, also sent with every frame (same stamp)
  /world_camera/image_raw     sensor_msgs/Image     static world camera, rgb8 (the VLM article's Gazebo
                                                    camera: 640x480, 10 Hz)
  /world_camera/camera_info   sensor_msgs/CameraInfo  latched
  /odom                       nav_msgs/Odometry     odom -> base_link; twist in base_link
  /imu                        sensor_msgs/Imu       frame base_link (the IMU frame is the base frame)
  /joint_states               sensor_msgs/JointState  the 12 joints in Unitree order (FR, FL, RR, RL)
  /tf                         tf2_msgs/TFMessage    odom -> base_link
  /tf_static                  tf2_msgs/TFMessage    latched: world -> odom (identity), base_link -> camera_link,
                                                    base_link -> camera_optical_frame, base_link -> utlidar_lidar,
                                                    world -> world_camera_optical_frame
  /clock                      rosgraph_msgs/Clock   simulation time, after every physics chunk (clock_rate_hz,
                                                    100 Hz of sim time): the clock of nodes with use_sim_time
  /sim/ground_truth           tf2_msgs/TFMessage    world -> gt/go2 (the base) and world -> gt/<body> for
                                                    every named world body (gt/red_ball, ...)
  /utlidar/cloud              sensor_msgs/PointCloud2  sensor QoS, `lidar_rate_hz` (10 Hz sim time) while
                                                    `lidar` (live): the L1 lidar by MuJoCo ray casting
                                                    (sim/lidar.py), frame utlidar_lidar, float32 x y z:
                                                    on DDS that is rt/utlidar/cloud, the real Go2's topic
  /scan                       sensor_msgs/LaserScan  sensor QoS, with each cloud: 360 deg in 2 deg bins,
                                                    frame base_link, the nearest return in the obstacle
                                                    band (geometry/scan.py); no cloud, no scan
  /sim/detections             vision_msgs/Detection2DArray  only with `detections`: ground-truth boxes
                                                    of the head camera frame with the same stamp, from
                                                    a segmentation render (class_id = the body name,
                                                    score 1.0, the box of the visible part; specks
                                                    under 16 pixels or 2 pixels a side left out): the
                                                    perfect detector
  /lowstate                   unitree_go/LowState   = rt/lowstate, as a Go2 publishes it, at lowstate_rate_hz:
                                                    motor_state[0..11] (q, dq, tau_est, temperature from
                                                    the thermal model), bms_state.soc and power_v from the
                                                    battery model (sim/thermal.py), imu_state (rpy ...);
                                                    with the fault_* parameters applied (tests, drills)
  /sim/status                 std_msgs/String       latched JSON, 2 Hz (wall): sim_time, wall_time, rtf
                                                    (achieved, last ~2 s), rtf_target, fast, mode
                                                    (standing, walking, fallen ...), physics, fell, world,
                                                    command, cmd_timed_out, frames, frames_dropped,
                                                    overruns, render_error, use_sim_time, estop,
                                                    commander (who may drive /cmd_vel, and why not)

Faults (live parameters, `go2vlm param set /sim NAME VALUE`, for the health monitor's tests and
drills; robots/go2_sim/lowstate.py): fault_motor_temp_c (> 0: the FR calf motor reports it),
fault_battery_pct (>= 0: the battery reports it), fault_tilt_deg (added to the reported roll),
fault_lowstate_silent (true: /lowstate stops, a lost state stream). A real tilt: /sim/push.

Frames: odom coincides with the world frame (perfect odometry from the simulator).
Rates: state topics, cameras and ground truth are due in sim time; `rtf` paces sim time against the
wall clock (a lag under 2 s is caught up, a longer stall re-anchors and counts an overrun). Camera
frames are rendered from a snapshot taken at their sim time; if rendering falls behind, the newest
snapshot wins and the dropped ones are counted (with `rtf`); with `fast` the physics waits for the
previous frame to be drawn instead, so that a fast run sees every frame a real-time run sees.
Clock: the sim is the source of sim time. Physics runs in chunks of 1/max(clock_rate_hz,
state_rate_hz) s (10 ms by default) and /clock goes out after each: 100 Hz is enough for every timer
of our nodes (the fastest is the follower's 10 ms watchdog; the gate ticks at 50 Hz) and costs one
small message per chunk; a finer /clock would only wake every sim-time node more often. With
use_sim_time the sim does not subscribe to /clock: its node clock is its own physics time.
Stamps: with use_sim_time every header (images, camera_info, odom, imu, joint_states, tf, tf_static,
ground truth, rt/sportmodestate) carries the sim time of the state it describes, and cmd_timeout_s
and the Unitree Move timeout are sim seconds; without it headers carry wall-clock time, like the real
robot. The pacing (rtf, fast), /sim/status (2 Hz of wall time, with both sim_time and wall_time) and
the render thread are wall time in both modes: they are about how fast the host runs the sim.

E-stop: the sim damps, as the go2 driver makes a real Go2 do (Unitree's own emergency action), so
that what is rehearsed on the sim is what the robot will do; a stop-and-stand would teach the wrong
recovery. With `unitree: true` its Unitree bridge also refuses every sport request but Damp,
StandDown and StopMove while the e-stop is latched.

With `unitree: true` the node also serves the Unitree DDS protocol (rt/api/sport/request Move,
StandUp ..., rt/api/videohub/request camera JPEGs, rt/sportmodestate) through
`go2vlm.robots.go2_sim.unitree_bridge.UnitreeSimBridge`, so `go2vlm run go2 --param interface=lo` drives it like
a real Go2. While /cmd_vel is silent the sport API has the robot; a live /cmd_vel overrides it.

With `webrtc: true` (implies `unitree`) it also answers the Go2's WebRTC route, the Unitree app's, on
`webrtc_host`:`webrtc_port` (127.0.0.1:9991): signalling, the data channel relaying the Unitree topics
above as JSON, and the head camera (/camera/image_raw: keep `camera` on) as an H.264 video track
(robots/go2_sim/webrtc_server.py). `go2vlm run go2 --param transport=webrtc --param ip=127.0.0.1` and
unitree_webrtc_connect drive it like a real Go2.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from go2vlm.bus import QOS_DEFAULT, QOS_IMAGE, QOS_LATCHED, QOS_SENSOR, QOS_UNITREE_WRITER, Node, ParamError, param
from go2vlm.geometry.camera import PinholeCamera, fovy_to_hfov
from go2vlm.msgs.base_state import base_state_messages, transform_stamped
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.geometry_msgs import Twist
from go2vlm.msgs.image import camera_info, numpy_to_image
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.pointcloud import scan_from_cloud, xyz_cloud
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.sensor_msgs import Image, Imu, JointState, LaserScan, PointCloud2
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.msgs.tf2_msgs import TFMessage
from go2vlm.msgs.unitree import LowState
from go2vlm.msgs.vision_msgs import Detection2DArray, detection_array
from go2vlm.robots.go2 import protocol, spec
from go2vlm.robots.go2_sim.lowstate import Faults, low_state
from go2vlm.safety.commander import CmdVelInput
from go2vlm.safety.estop import RELEASE_TOKEN, EstopInput, EstopLatch, check_token
from go2vlm.sim import Go2Sim, SimConfig
from go2vlm.sim.lidar import Lidar
from go2vlm.sim.render import (
    NewestOnly,
    camera_scene_option,
    labelled_bodies,
    pose_mirror,
    render_segmentation,
    segmentation_boxes,
)
from go2vlm.sim.thermal import Battery, MotorThermal

# A real-time run that falls behind by less than this catches up (briefly faster than real time),
# so that a short stall (another process, a GC pause) does not lower the real-time factor for good.
CATCH_UP_S = 2.0

# camera_link (x forward, y left, z up) and the optical frame (x right, y down, z forward), as
# columns expressed in MuJoCo's camera frame (x right, y up, looking along -z).
_MJ_TO_LINK = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
_MJ_TO_OPTICAL = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


@dataclass
class SimNodeConfig(SimConfig):
    """The sim's own config (world, physics, cameras: sim/config.py) plus how the node runs it."""

    rtf: float = param(1.0, help="target real-time factor (sim seconds per wall second)", min=0.01, max=100.0)
    fast: bool = param(False, help="run as fast as possible (ignores rtf)")
    camera: bool = param(True, help="render and publish the head camera")
    camera_rate_hz: float = param(10.0, help="head camera rate in sim time", min=0.1, max=60.0)
    world_camera: bool = param(True, help="render and publish the static world camera")
    world_camera_rate_hz: float = param(10.0, help="world camera rate in sim time", min=0.1, max=60.0)
    state_rate_hz: float = param(50.0, help="rate of /odom, /imu, /joint_states, /tf (sim time)", min=1.0, max=500.0)
    clock_rate_hz: float = param(
        100.0,
        help="rate of /clock (sim time): one per physics chunk of 1/max(this, state_rate_hz) s",
        min=1.0,
        max=1000.0,
    )
    ground_truth_rate_hz: float = param(20.0, help="rate of /sim/ground_truth (sim time)", min=0.1, max=500.0)
    cmd_timeout_s: float = param(
        0.5, help="zero the velocity after this long without /cmd_vel (sim s with use_sim_time)", min=0.05, max=10.0
    )
    lidar: bool = param(True, help="publish the ray-cast L1 lidar on /utlidar/cloud and /scan", live=True)
    lidar_rate_hz: float = param(10.0, help="lidar cloud and /scan rate (sim time)", min=1.0, max=50.0)
    detections: bool = param(False, help="publish ground-truth boxes of each head frame on /sim/detections")
    unitree: bool = param(False, help="also serve the Unitree DDS protocol (UnitreeSimBridge)")
    webrtc: bool = param(False, help="also serve the Go2's WebRTC (signalling, data channel, video); implies unitree")
    webrtc_host: str = param("127.0.0.1", help="address of the WebRTC signalling server")
    webrtc_port: int = param(protocol.SIGNAL_PORT, help="WebRTC signalling port (a Go2's is 9991)", min=1, max=65535)
    webrtc_legacy_port: int = param(
        0, help="also the legacy plain-text /offer signalling here (a Go2's is 8081); 0 = off", min=0, max=65535
    )
    webrtc_seal: int = param(
        protocol.SEAL_STATIC,
        help="how con_notify seals the key: 1 plain, 2 the app's key, 3 webrtc_aes_key",
        min=1,
        max=3,
    )
    webrtc_aes_key: str = param("", help="the robot's AES-128 key (32 hex chars) for webrtc_seal 3")
    webrtc_firmware: str = param(protocol.SIM_FIRMWARE, help="the firmware version the sim reports over WebRTC")
    webrtc_takeover: bool = param(False, help="a new WebRTC client replaces the connected one (as the phone app can)")
    viewer: bool = param(False, help="open MuJoCo's interactive passive viewer (needs a display)")
    release_token: str = param(
        RELEASE_TOKEN, help="the /emergency_stop/release text that releases the e-stop (exact match)"
    )
    lowstate_rate_hz: float = param(
        20.0, help="rate of /lowstate (sim time; a Go2's rt/lf/lowstate is ~20 Hz)", min=1.0, max=500.0
    )
    battery_pct: float = param(100.0, help="the battery's state of charge at start (percent)", min=0.0, max=100.0)
    fault_motor_temp_c: float = param(
        0.0,
        help="fault: the FR calf motor reports this temperature on /lowstate (0 = none)",
        min=0.0,
        max=255.0,
        live=True,
    )
    fault_battery_pct: float = param(
        -1.0, help="fault: the battery reports this charge on /lowstate (< 0 = none)", min=-1.0, max=100.0, live=True
    )
    fault_tilt_deg: float = param(
        0.0, help="fault: added to the roll /lowstate reports (degrees)", min=-180.0, max=180.0, live=True
    )
    fault_lowstate_silent: bool = param(False, help="fault: stop publishing /lowstate", live=True)

    def validate(self) -> None:
        super().validate()
        check_token(self.release_token)


def _mat_quat(r: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(r, dtype=float).reshape(9))
    return q


@dataclass
class _Snapshot:
    """What the render thread needs to draw one instant: the pose of everything, and its stamp."""

    sim_time: float
    stamp: float
    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    head: bool
    world: bool


class _Renderer:
    """Render thread: owns the GL context, a mirror MjData and the cameras' renderers."""

    def __init__(self, node: SimNode, model: mujoco.MjModel) -> None:
        self.node = node
        self.model = model
        self._snapshots: NewestOnly[_Snapshot] = NewestOnly()
        self.frames = 0
        self.dropped = 0
        self.busy_s = 0.0
        self.error: str | None = None
        self.ready = threading.Event()  # GL contexts made and warmed up (or failed): the clock may start
        self._idle = threading.Condition()
        self._submitted = 0
        self._finished = 0
        self._head_cam = model.camera("head_camera").id
        names = {model.camera(i).name for i in range(model.ncam)}
        self._world_cam = model.camera("world_camera").id if "world_camera" in names else -1
        self._thread = threading.Thread(target=self._run, name=f"{node.node_name}:render", daemon=True)

    @property
    def has_world_camera(self) -> bool:
        return self._world_cam >= 0

    def start(self) -> None:
        self._thread.start()

    def submit(self, snap: _Snapshot) -> None:
        with self._idle:
            self._submitted += 1
        if self._snapshots.put(snap):
            self.dropped += 1  # the newest frame wins; a late frame is worth nothing
            self._done(1)

    def _done(self, n: int) -> None:
        with self._idle:
            self._finished += n
            self._idle.notify_all()

    def wait_idle(self, stop: threading.Event) -> None:
        """Block until every submitted snapshot is rendered (or rendering failed, or `stop`)."""
        with self._idle:
            while self._finished < self._submitted and self.error is None and not stop.is_set():
                self._idle.wait(0.1)  # wall time: re-check stop and error

    def stop(self) -> None:
        self._snapshots.close()
        if self._thread.is_alive():
            self._thread.join(5.0)

    def _run(self) -> None:
        cfg = self.node.config
        renderers: list[mujoco.Renderer] = []
        try:
            data = mujoco.MjData(self.model)
            head_opt = camera_scene_option(hide_robot=True)
            bodies = labelled_bodies(self.model)
            world_opt = camera_scene_option(hide_robot=False)
            head_r = world_r = None
            if cfg.camera:
                head_r = mujoco.Renderer(self.model, height=cfg.camera_height, width=cfg.camera_width)
                renderers.append(head_r)
            if cfg.world_camera and self._world_cam >= 0:
                world_r = mujoco.Renderer(self.model, height=cfg.world_camera_height, width=cfg.world_camera_width)
                renderers.append(world_r)
            # The first frame compiles llvmpipe's shaders (slow): do it before the clock starts.
            data.qpos[:] = self.model.qpos0
            mujoco.mj_kinematics(self.model, data)
            mujoco.mj_camlight(self.model, data)
            if head_r is not None:
                head_r.update_scene(data, camera=self._head_cam, scene_option=head_opt)
                head_r.render()
            if world_r is not None:
                world_r.update_scene(data, camera=self._world_cam, scene_option=world_opt)
                world_r.render()
        except Exception as exc:  # no GL here: physics keeps running, cameras stay silent
            self.error = f"rendering unavailable: {type(exc).__name__}: {exc}"
            self.node.log.error(f"{self.error}; set MUJOCO_GL=egl or osmesa (see docs/demo.md)")
            self._done(0)
            self.ready.set()
            for r in renderers:
                r.close()
            return
        self.ready.set()
        try:
            while (snap := self._snapshots.take()) is not None:
                t0 = time.perf_counter()  # wall time: the render thread's CPU load, for benchmarks
                pose_mirror(self.model, data, snap.qpos, snap.mocap_pos, snap.mocap_quat)
                if snap.head and head_r is not None:
                    head_r.update_scene(data, camera=self._head_cam, scene_option=head_opt)
                    self.node._publish_frame("head", head_r.render(), snap.stamp)
                    if cfg.detections:  # same pose, same camera: the boxes of exactly that frame
                        ids = render_segmentation(head_r, data, self._head_cam, head_opt)
                        boxes = segmentation_boxes(ids, self.model.geom_bodyid, bodies)
                        self.node._publish_detections(boxes, snap.stamp)
                if snap.world and world_r is not None:
                    world_r.update_scene(data, camera=self._world_cam, scene_option=world_opt)
                    self.node._publish_frame("world", world_r.render(), snap.stamp)
                self.frames += 1
                self.busy_s += time.perf_counter() - t0
                self._done(1)
        except Exception as exc:
            self.error = f"render thread failed: {type(exc).__name__}: {exc}"
            self.node.log.error(self.error)
            self._done(0)
        finally:
            for r in renderers:
                r.close()


# /go2/command words -> what the simulated robot does (the real Go2's Sit has no sim posture; it lies down).
_POSTURES: dict[str, Callable[[Go2Sim], Any]] = {
    "stand": lambda sim: sim.stand_up(),
    "balance": lambda sim: sim.stand_up(),
    "recover": lambda sim: sim.recovery_stand(),
    "sit": lambda sim: sim.lie_down(),
    "standdown": lambda sim: sim.lie_down(),
    "damp": lambda sim: sim.damp(),
    "stop": lambda sim: sim.stop(),
}


class SimNode(Node):
    name = "sim"
    Config = SimNodeConfig
    provides_clock = True  # with use_sim_time its clock is its own physics time, not /clock

    def __init__(self, config: SimNodeConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        cfg: SimNodeConfig = self.config
        try:
            self.sim = Go2Sim(cfg)
        except (ValueError, FileNotFoundError) as exc:  # unknown world, bad world file
            raise ParamError(f"node {self.node_name!r}: {exc}") from None
        self._cmd_lock = threading.Lock()
        self._cmd = (0.0, 0.0, 0.0)
        self._cmd_t = -math.inf  # node-clock time of the last valid /cmd_vel
        self._cmd_timed_out = True
        self._physics_calls: list[Callable[[Go2Sim], None]] = []
        self._physics_thread: threading.Thread | None = None
        self._physics_stop = threading.Event()
        self.rtf = 0.0  # achieved, over the last ~2 s of wall time
        self.physics_busy_s = 0.0
        self.fell_reported = False
        self.bridge: Any = None
        self.webrtc: Any = None  # the Go2's WebRTC service (robots/go2_sim/webrtc_server.py), with `webrtc`

        # The e-stop first: each executor pass takes it before /cmd_vel.
        self.estop = EstopLatch(cfg.release_token)
        EstopInput(
            self,
            self.estop,
            held="Damp, no /cmd_vel, no standing up",
            on_engage=self._on_estop,
            on_release=self._on_release,
            released_note="the robot stays down until 'recover' or 'stand'; /cmd_vel must pass through zero",
        )
        self.cmd_vel = CmdVelInput(self, self._on_cmd_vel, self._on_cmd_stop)
        self.create_subscription(Twist, "/sim/push", self._on_push, QOS_DEFAULT)
        if self.clock.sim:
            self.set_sim_time(self.sim.time)  # stamps from the start are sim time (0.0)
        if not (cfg.unitree or cfg.webrtc):
            self.create_subscription(String, "/go2/command", self._on_posture, QOS_DEFAULT)
        self.pub_odom = self.create_publisher(Odometry, "/odom", QOS_DEFAULT)
        self.pub_imu = self.create_publisher(Imu, "/imu", QOS_DEFAULT)
        self.pub_joints = self.create_publisher(JointState, "/joint_states", QOS_DEFAULT)
        self.pub_tf = self.create_publisher(TFMessage, "/tf", QOS_DEFAULT)
        self.pub_tf_static = self.create_publisher(TFMessage, "/tf_static", QOS_LATCHED)
        self.pub_clock = self.create_publisher(Clock, "/clock", QOS_DEFAULT)
        self.pub_gt = self.create_publisher(TFMessage, "/sim/ground_truth", QOS_DEFAULT)
        self.pub_status = self.create_publisher(String, "/sim/status", QOS_LATCHED)
        self.pub_lowstate = self.create_publisher(LowState, "/lowstate", QOS_UNITREE_WRITER)
        self.thermal = MotorThermal()
        self.battery = Battery(cfg.battery_pct)
        self._health_t = self.sim.time
        if cfg.detections:
            self.pub_dets = self.create_publisher(Detection2DArray, "/sim/detections", QOS_DEFAULT)
        self.lidar = Lidar(self.sim.model, self.sim.model.body("base").id)
        self._scan_spec, self._lidar_tfs = spec.lidar_scan_spec(), spec.lidar_transforms()
        self.pub_cloud = self.create_publisher(PointCloud2, spec.LIDAR_TOPIC, QOS_SENSOR)
        self.pub_scan = self.create_publisher(LaserScan, "/scan", QOS_SENSOR)

        self._renderer = _Renderer(self, self.sim.model)
        self._cams: dict[str, tuple[Any, Any, Any]] = {}  # key -> (image pub, info pub, CameraInfo)
        if cfg.camera:
            w, h = cfg.camera_width, cfg.camera_height
            info = camera_info(PinholeCamera.from_hfov(w, h, fovy_to_hfov(cfg.camera_fovy_deg, w, h)))
            info.header.frame_id = spec.CAMERA_FRAME
            self._cams["head"] = (
                self.create_publisher(Image, "/camera/image_raw", QOS_IMAGE),
                self.create_publisher(type(info), "/camera/camera_info", QOS_LATCHED),
                info,
            )
        if cfg.world_camera and self._renderer.has_world_camera:
            w, h = cfg.world_camera_width, cfg.world_camera_height
            fovy = float(self.sim.model.cam_fovy[self.sim.model.camera("world_camera").id])
            info = camera_info(PinholeCamera.from_hfov(w, h, fovy_to_hfov(fovy, w, h)))
            info.header.frame_id = "world_camera_optical_frame"
            self._cams["world"] = (
                self.create_publisher(Image, "/world_camera/image_raw", QOS_IMAGE),
                self.create_publisher(type(info), "/world_camera/camera_info", QOS_LATCHED),
                info,
            )
        elif cfg.world_camera:
            self.log.info(f"world {cfg.world!r} has no world_camera; /world_camera/* stays silent")

        if cfg.unitree or cfg.webrtc:
            try:
                from go2vlm.robots.go2_sim.unitree_bridge import UnitreeSimBridge
            except ImportError as exc:
                raise RuntimeError(
                    f"unitree: true needs go2vlm.robots.go2_sim.unitree_bridge, which cannot be imported: {exc}"
                ) from exc
            self.bridge = UnitreeSimBridge(self, self.sim, estop=lambda: self.estop.engaged)
        if cfg.webrtc:
            from go2vlm.robots.go2_sim.webrtc_server import SimWebRtcServer

            self.webrtc = SimWebRtcServer(
                self,
                host=cfg.webrtc_host,
                port=cfg.webrtc_port,
                legacy_port=cfg.webrtc_legacy_port,
                seal=cfg.webrtc_seal,
                aes_key=cfg.webrtc_aes_key,
                firmware=cfg.webrtc_firmware,
                takeover=cfg.webrtc_takeover,
            )

        self._publish_static_tf()
        for _, info_pub, info in self._cams.values():
            info.header.stamp = self.stamp()
            info_pub.publish(info)

    # -- inputs ------------------------------------------------------------------------------
    def _on_cmd_vel(self, msg: Twist) -> None:
        vals = (msg.linear.x, msg.linear.y, msg.angular.z)
        if not all(math.isfinite(v) for v in vals):
            self.count("bad_cmd_vel")
            self.log.throttled("error", 2.0, f"rejected /cmd_vel with a non-finite value {vals}; robot not moved by it")
            return
        with self._cmd_lock:
            self._cmd = (float(vals[0]), float(vals[1]), float(vals[2]))
            self._cmd_t = self.clock.monotonic()

    def _on_cmd_stop(self, reason: str) -> None:
        """Driving is not allowed any more (another /cmd_vel writer): stop now."""
        with self._cmd_lock:
            self._cmd, self._cmd_t = (0.0, 0.0, 0.0), self.clock.monotonic()

    def _on_estop(self) -> None:
        self._on_cmd_stop("e-stop")
        self.call_in_physics(self._damp)

    def _damp(self, sim: Go2Sim) -> None:
        if self.bridge is not None:
            self.bridge.damp_now()  # through the bridge, so that its sport mode agrees
        else:
            sim.damp()

    def _on_release(self) -> None:
        self.cmd_vel.require_zero()

    def _on_push(self, msg: Twist) -> None:
        dv = (msg.linear.x, msg.linear.y, msg.linear.z)
        dw = (msg.angular.x, msg.angular.y, msg.angular.z)
        if not all(math.isfinite(v) for v in dv + dw) or math.hypot(*dv) > 10.0 or math.hypot(*dw) > 30.0:
            self.count("bad_push")
            self.log.throttled("error", 2.0, f"rejected /sim/push {dv} {dw}: non-finite or too large")
            return
        self.log.info(f"push: dv {dv} m/s (world), dw {dw} rad/s (base)")
        self.call_in_physics(lambda sim: sim.push(dv, dw))

    def _on_posture(self, msg: String) -> None:
        word = msg.data.strip().lower()
        action = _POSTURES.get(word)
        if action is None:
            self.count("bad_posture")
            self.log.throttled(
                "error", 2.0, f"unknown /go2/command {msg.data[:40]!r}; known: {', '.join(sorted(_POSTURES))}"
            )
            return
        if self.estop.engaged and word not in protocol.ESTOP_ALLOWED:
            self.count("refused_command")
            self.log.throttled("error", 2.0, f"refused {word!r}: emergency stop latched (release it first)")
            return
        self.log.info(f"posture: {word}")
        self.call_in_physics(action)

    def call_in_physics(self, fn: Callable[[Go2Sim], None]) -> None:
        """Run `fn(sim)` on the physics thread before the next step (Go2Sim is not thread-safe)."""
        with self._cmd_lock:
            self._physics_calls.append(fn)

    # -- lifecycle ---------------------------------------------------------------------------
    def start(self) -> SimNode:
        super().start()
        if self._physics_thread is None:
            self._renderer.start()
            self._physics_thread = threading.Thread(target=self._physics, name=f"{self.node_name}:physics", daemon=True)
            self._physics_thread.start()
        return self

    def close(self) -> None:
        self._physics_stop.set()
        if self._physics_thread is not None and self._physics_thread is not threading.current_thread():
            self._physics_thread.join(5.0)
        self._renderer.stop()
        if self.bridge is not None and hasattr(self.bridge, "close"):
            self.bridge.close()
        if self.webrtc is not None:
            self.webrtc.close()
        self.sim.close()

    @property
    def sim_time(self) -> float:
        return self.sim.time

    @property
    def frames(self) -> int:
        return self._renderer.frames

    # -- physics thread ----------------------------------------------------------------------
    def _physics(self) -> None:
        try:
            self._physics_loop()
        except Exception as exc:
            self.count("physics_errors")
            self.log.error(f"physics thread stopped: {type(exc).__name__}: {exc}")

    def _physics_loop(self) -> None:
        cfg: SimNodeConfig = self.config
        sim = self.sim
        dt = sim.dt
        chunk = max(1, int(round(1.0 / (max(cfg.clock_rate_hz, cfg.state_rate_hz) * dt))))
        state_period = 1.0 / cfg.state_rate_hz
        cam_period = 1.0 / cfg.camera_rate_hz
        wcam_period = 1.0 / cfg.world_camera_rate_hz
        gt_period = 1.0 / cfg.ground_truth_rate_hz
        lidar_period = 1.0 / cfg.lidar_rate_hz
        # Due times on a grid of their periods from the start (0.02, 0.04 ... for 50 Hz), so that
        # stamps are whole multiples of the period in sim time.
        next_state, next_cam = sim.time + state_period, sim.time + cam_period
        next_wcam, next_gt = sim.time + wcam_period, sim.time + gt_period
        next_lidar = sim.time + lidar_period
        viewer = self._open_viewer() if cfg.viewer else None
        next_viewer = 0.0
        # Wall time from here on where it says so: start-up, pacing against the wall (rtf), the
        # achieved rtf, /sim/status and the viewer are about how fast the host runs the sim.
        deadline = time.monotonic() + 30.0
        while self._cams and not self._renderer.ready.wait(0.1) and not self._physics_stop.is_set():
            if time.monotonic() > deadline:
                self.log.warning("the cameras are not ready after 30 s; starting the clock anyway")
                break

        wall0, sim0 = time.monotonic(), sim.time  # pacing reference
        hist: list[tuple[float, float]] = [(wall0, sim0)]
        next_status = wall0
        next_log = wall0 + 5.0
        state = sim.state()
        while not self._physics_stop.is_set():
            t_busy = time.perf_counter()
            self._apply_command()
            sim.step(chunk)
            t = sim.time
            if self.clock.sim:
                self.set_sim_time(t)
            stamp_t = self.now()  # sim time with use_sim_time, else the wall clock
            state_due = t + 1e-9 >= next_state
            if state_due:
                next_state += state_period * max(1, math.floor((t - next_state) / state_period) + 1)
                state = sim.state()
                self._publish_state(state, stamp_t)
            self.pub_clock.publish(Clock(clock=Time.from_sec(t)))
            head_due = cfg.camera and t + 1e-9 >= next_cam
            world_due = "world" in self._cams and t + 1e-9 >= next_wcam
            if head_due:
                next_cam += cam_period * max(1, math.floor((t - next_cam) / cam_period) + 1)
            if world_due:
                next_wcam += wcam_period * max(1, math.floor((t - next_wcam) / wcam_period) + 1)
            if head_due or world_due:
                if cfg.fast:  # as fast as the host renders too: every frame due in sim time is drawn
                    self._renderer.wait_idle(self._physics_stop)
                d = sim.data
                self._renderer.submit(
                    _Snapshot(t, stamp_t, d.qpos.copy(), d.mocap_pos.copy(), d.mocap_quat.copy(), head_due, world_due)
                )
            if t + 1e-9 >= next_gt:
                next_gt += gt_period * max(1, math.floor((t - next_gt) / gt_period) + 1)
                self._publish_ground_truth(stamp_t)
            if t + 1e-9 >= next_lidar:
                next_lidar += lidar_period * max(1, math.floor((t - next_lidar) / lidar_period) + 1)
                if self.config.lidar:  # live: read each time
                    self._publish_lidar(stamp_t, lidar_period)
            if state_due and state.fell and not self.fell_reported:
                self.fell_reported = True
                self.log.error(f"the robot fell at sim time {t:.2f} s")
            if self.bridge is not None and hasattr(self.bridge, "on_step"):
                self.bridge.on_step(state if state_due else None)
            if viewer is not None and time.monotonic() >= next_viewer:
                next_viewer = time.monotonic() + 1 / 60
                if viewer.is_running():
                    viewer.sync()
            self.physics_busy_s += time.perf_counter() - t_busy

            mono = time.monotonic()
            hist.append((mono, t))
            while len(hist) > 2 and mono - hist[0][0] > 2.0:
                hist.pop(0)
            if mono > hist[0][0]:
                self.rtf = (t - hist[0][1]) / (mono - hist[0][0])
            if mono >= next_status:
                next_status = mono + 0.5
                self._publish_status(state if state_due else sim.state())
            if mono >= next_log:
                next_log = mono + 10.0
                target = "fast" if cfg.fast else f"target {cfg.rtf:g}"
                self.log.info(f"sim time {t:.1f} s, real-time factor {self.rtf:.2f} ({target}), mode {state.mode}")
            if not cfg.fast:
                due = wall0 + (t - sim0) / cfg.rtf
                lag = due - mono
                if lag > 0:
                    self._physics_stop.wait(lag)
                elif lag < -CATCH_UP_S:
                    # Far behind (a stall, a machine too slow): re-anchor instead of a long fast burst.
                    self.count("physics_overruns")
                    wall0, sim0 = mono, t
        if viewer is not None:
            viewer.close()

    def _apply_command(self) -> None:
        with self._cmd_lock:
            calls, self._physics_calls = self._physics_calls, []
            cmd, stamp = self._cmd, self._cmd_t
        for fn in calls:
            try:
                fn(self.sim)
            except Exception as exc:
                self.count("physics_call_errors")
                self.log.throttled("error", 2.0, f"physics call failed: {type(exc).__name__}: {exc}")
        if self.estop.engaged:  # nothing moves the robot while the e-stop holds
            self.sim.set_command(0.0, 0.0, 0.0)
            return
        timed_out = self.clock.monotonic() - stamp > self.config.cmd_timeout_s
        just_timed_out = timed_out and not self._cmd_timed_out
        if just_timed_out and any(cmd):
            self.log.warning(f"no /cmd_vel for {self.config.cmd_timeout_s:g} s: stopping")
        self._cmd_timed_out = timed_out
        if not timed_out:
            self.sim.set_command(*cmd)
        elif self.bridge is None or just_timed_out:
            # Stop once on the timeout; after that, with the Unitree bridge, its sport API has the robot.
            self.sim.set_command(0.0, 0.0, 0.0)

    def _open_viewer(self) -> Any:
        import os

        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            self.log.error("--viewer needs a display (DISPLAY/WAYLAND_DISPLAY is not set); running headless")
            return None
        try:
            import mujoco.viewer

            return mujoco.viewer.launch_passive(self.sim.model, self.sim.data)
        except Exception as exc:
            self.log.error(f"cannot open the MuJoCo viewer ({type(exc).__name__}: {exc}); running headless")
            return None

    # -- outputs -----------------------------------------------------------------------------
    def _publish_state(self, s: Any, t: float) -> None:
        stamp = self.stamp(t)
        odom, imu, tf = base_state_messages(
            stamp,
            spec.ODOM_FRAME,
            spec.BASE_FRAME,
            s.position,
            s.quaternion,
            s.lin_vel_body,
            s.ang_vel_body,
            s.imu_gyro,
            s.imu_acc,
        )
        self.pub_odom.publish(odom)
        self.pub_imu.publish(imu)
        self.pub_joints.publish(
            JointState(
                header=Header(stamp=stamp, frame_id=""),
                name=list(s.joint_names),
                position=[float(v) for v in s.joint_pos],
                velocity=[float(v) for v in s.joint_vel],
                effort=[float(v) for v in s.joint_torque],
            )
        )
        self.pub_tf.publish(tf)
        self._publish_lowstate(s)

    def _publish_lowstate(self, s: Any) -> None:
        """Advance the motor and battery models to this state's time, then publish /lowstate."""
        if s.time - self._health_t < 1.0 / self.config.lowstate_rate_hz - 1e-9:
            return
        dt, self._health_t = s.time - self._health_t, s.time
        temps = self.thermal.step(dt, s.joint_torque)
        soc = self.battery.step(dt, s.joint_torque, s.joint_vel)
        cfg: SimNodeConfig = self.config
        if cfg.fault_lowstate_silent:
            return
        faults = Faults(cfg.fault_motor_temp_c, cfg.fault_battery_pct, cfg.fault_tilt_deg)
        self.pub_lowstate.publish(low_state(s, temps, soc, self.battery.voltage, faults))

    def _publish_ground_truth(self, t: float) -> None:
        header = Header(stamp=self.stamp(t), frame_id="world")
        tfs = [
            transform_stamped(header, f"gt/{name}", p.position, p.quaternion)
            for name, p in self.sim.object_poses().items()
        ]
        self.pub_gt.publish(TFMessage(transforms=tfs))

    def _publish_lidar(self, t: float, period: float) -> None:
        cloud = xyz_cloud(Header(stamp=self.stamp(t), frame_id=spec.LIDAR_FRAME), self.lidar.scan(self.sim.data))
        self.pub_cloud.publish(cloud)
        scan = scan_from_cloud(cloud, self._scan_spec, self._lidar_tfs, spec.BASE_FRAME, period)
        if scan is not None:
            self.pub_scan.publish(scan)

    def _publish_status(self, s: Any) -> None:
        cfg: SimNodeConfig = self.config
        status = {
            "sim_time": round(s.time, 4),
            "wall_time": round(time.time(), 3),  # wall time whatever the clock: pairs sim time with the wall
            "use_sim_time": self.clock.sim,
            "rtf": round(self.rtf, 3),
            "rtf_target": None if cfg.fast else cfg.rtf,
            "fast": cfg.fast,
            "mode": s.mode,
            "physics": cfg.mode,
            "fell": bool(s.fell),
            "world": cfg.world,
            "command": [round(float(v), 4) for v in s.command],
            "cmd_timed_out": self._cmd_timed_out,
            "frames": self._renderer.frames,
            "frames_dropped": self._renderer.dropped,
            "overruns": self.counters.get("physics_overruns", 0),
            "render_error": self._renderer.error,
            "estop": self.estop.engaged,
            "motor_temp_max_c": round(float(self.thermal.temps.max()), 1),
            "battery_pct": round(self.battery.soc_pct, 2),
            "lidar": cfg.lidar,
            "commander": self.cmd_vel.status(),
            "counters": dict(self.counters),
        }
        if self.webrtc is not None:
            status["webrtc"] = self.webrtc.status()
        self.pub_status.publish(String(data=json.dumps(status)))

    def _publish_frame(self, key: str, rgb: np.ndarray, stamp: float) -> None:
        """Called on the render thread."""
        img_pub, info_pub, info = self._cams[key]
        header = Header(stamp=self.stamp(stamp), frame_id=info.header.frame_id)
        img_pub.publish(numpy_to_image(rgb, "rgb8", header))
        info.header = header
        info_pub.publish(info)

    def _publish_detections(self, boxes: dict[str, tuple[int, int, int, int]], stamp: float) -> None:
        """Called on the render thread."""
        header = Header(stamp=self.stamp(stamp), frame_id=spec.CAMERA_FRAME)
        self.pub_dets.publish(detection_array(header, ((name, box, 1.0) for name, box in sorted(boxes.items()))))

    def _publish_static_tf(self) -> None:
        m, d = self.sim.model, self.sim.data
        header = Header(stamp=self.stamp(), frame_id=spec.BASE_FRAME)
        base = m.body("base").id
        rb = d.xmat[base].reshape(3, 3)
        cam = m.camera("head_camera").id
        rc = d.cam_xmat[cam].reshape(3, 3)
        pos = rb.T @ (d.cam_xpos[cam] - d.xpos[base])
        rel = rb.T @ rc
        tfs = [
            transform_stamped(
                Header(stamp=header.stamp, frame_id="world"), spec.ODOM_FRAME, np.zeros(3), np.array([1.0, 0, 0, 0])
            ),
            transform_stamped(header, "camera_link", pos, _mat_quat(rel @ _MJ_TO_LINK)),
            transform_stamped(header, spec.CAMERA_FRAME, pos, _mat_quat(rel @ _MJ_TO_OPTICAL)),
            transform_stamped(header, spec.LIDAR_FRAME, np.array(spec.LIDAR_MOUNT_POS), _mat_quat(self.lidar.mount_r)),
        ]
        if self._renderer.has_world_camera:
            wc = m.camera("world_camera").id
            tfs.append(
                transform_stamped(
                    Header(stamp=header.stamp, frame_id="world"),
                    "world_camera_optical_frame",
                    d.cam_xpos[wc],
                    _mat_quat(d.cam_xmat[wc].reshape(3, 3) @ _MJ_TO_OPTICAL),
                )
            )
        self.pub_tf_static.publish(TFMessage(transforms=tfs))
