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
  /go2/command                std_msgs/String       posture, the go2 driver's words (robots/go2/protocol.py
                                                    POSTURES): stand, balance, rise (stand up), recover,
                                                    sit, standdown (lie down), damp, stop, hello (stands
                                                    still for it, as the Unitree bridge does); only without
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
                                                    estop_why, commander (who may drive /cmd_vel, and
                                                    why not), last_command {seq, name, result}

The node is wiring (robots/base.py does the e-stop, /cmd_vel, postures and status): its physics
thread is robots/go2_sim/physics.py, its render thread render_thread.py, its outputs publishers.py.

Faults (live parameters, `go2vlm param set /sim NAME VALUE`, for the health monitor's tests and
drills; robots/go2_sim/lowstate.py): fault_motor_temp_c (> 0: the FR calf motor reports it),
fault_battery_pct (>= 0: the battery reports it), fault_tilt_deg (added to the reported roll),
fault_lowstate_silent (true: /lowstate stops, a lost state stream), fault_webrtc_silent (true: the
WebRTC data channel says nothing while the video goes on: a stalled channel). A real tilt: /sim/push.

Frames: odom coincides with the world frame (perfect odometry from the simulator), unless
`odom_drift` > 0: then /odom, /tf (odom -> base_link) and rt/sportmodestate (position, IMU yaw,
velocity) report the pose a Go2's leg odometry would, drifting with the distance walked
(sim/odometry_drift.py, sized from published Go2 figures, drawn from `seed`); world -> odom stays the
identity it was at the start, /imu's gyro and accelerometer stay true, and /sim/ground_truth keeps
the true pose (gt/go2).
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

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from go2vlm.bus import ParamError, param
from go2vlm.bus.topics import GO2_COMMAND, SIM_PUSH, SIM_STATUS
from go2vlm.msgs.geometry_msgs import Twist
from go2vlm.robot_profile.go2 import SIM
from go2vlm.robots.base import RobotEnd, RobotEndConfig
from go2vlm.robots.go2 import protocol
from go2vlm.robots.go2_sim.physics import PhysicsThread
from go2vlm.robots.go2_sim.publishers import SimPublishers
from go2vlm.robots.go2_sim.render_thread import CameraSetup, RenderThread
from go2vlm.secret import read_secret
from go2vlm.sim import Go2Sim, SimConfig
from go2vlm.sim.odometry_drift import OdometryDrift


@dataclass
class SimNodeConfig(SimConfig, RobotEndConfig):
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
        help="how con_notify seals the key: 1 plain, 2 the app's key, 3 the robot's AES key (env GO2VLM_AES_KEY "
        "or webrtc_aes_key_file)",
        min=1,
        max=3,
    )
    webrtc_aes_key_file: str = param(
        "", help="a file holding the robot's AES-128 key (32 hex chars; else env GO2VLM_AES_KEY), webrtc_seal 3"
    )
    webrtc_firmware: str = param(protocol.SIM_FIRMWARE, help="the firmware version the sim reports over WebRTC")
    webrtc_takeover: bool = param(False, help="a new WebRTC client replaces the connected one (as the phone app can)")
    viewer: bool = param(False, help="open MuJoCo's interactive passive viewer (needs a display)")
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
    odom_drift: float = param(
        0.0,
        help="leg-odometry drift of /odom, /tf and rt/sportmodestate: 0 = the truth, 1 = a Go2's size "
        "(1.5 % of the distance, 0.03 deg/m and 2 % of each turn in heading; sim/odometry_drift.py), "
        "drawn from `seed`",
        min=0.0,
        max=10.0,
    )
    fault_webrtc_silent: bool = param(
        False, help="fault: the WebRTC data channel sends nothing (the video goes on)", live=True
    )

    def validate(self) -> None:
        SimConfig.validate(self)
        RobotEndConfig.validate(self)


# /go2/command words (the go2 driver's vocabulary) -> what the simulated robot does. The sim has no
# sitting posture: it sits by lying down, and rises by standing up; for hello (a real Go2's wave) it
# stands still, as its Unitree bridge does.
POSTURES: dict[str, Callable[[Go2Sim], Any]] = {
    "stand": lambda sim: sim.stand_up(),
    "balance": lambda sim: sim.stand_up(),
    "sit": lambda sim: sim.lie_down(),
    "rise": lambda sim: sim.stand_up(),
    "standdown": lambda sim: sim.lie_down(),
    "damp": lambda sim: sim.damp(),
    "recover": lambda sim: sim.recovery_stand(),
    "hello": lambda sim: sim.stop(),
    "stop": lambda sim: sim.stop(),
}
if tuple(POSTURES) != protocol.POSTURES:
    raise ImportError(f"the sim's postures {tuple(POSTURES)} differ from the vocabulary's {protocol.POSTURES}")


class SimNode(RobotEnd):
    name = "sim"
    Config = SimNodeConfig
    provides_clock = True  # with use_sim_time its clock is its own physics time, not /clock
    profile = SIM
    postures = protocol.POSTURES
    estop_postures = protocol.ESTOP_ALLOWED
    posture_topic = GO2_COMMAND
    status_topic = SIM_STATUS

    def __init__(self, config: SimNodeConfig | None = None, **kwargs: Any) -> None:
        cfg = config if config is not None else SimNodeConfig()
        super().__init__(
            cfg,
            held="Damp, no /cmd_vel, no standing up",
            released_note="the robot stays down until 'recover' or 'stand'; /cmd_vel must pass through zero",
            take_postures=not (cfg.unitree or cfg.webrtc),  # with the Unitree bridge the driver sends sport RPCs
            **kwargs,
        )
        try:
            self.sim = Go2Sim(cfg)
        except (ValueError, FileNotFoundError) as exc:  # unknown world, bad world file
            raise ParamError(f"node {self.node_name!r}: {exc}") from None
        self._cmd_timed_out = True
        self._started = False
        self.odometry = OdometryDrift(cfg.odom_drift, cfg.seed)  # what /odom reports of the true pose
        self.bridge: Any = None
        self.webrtc: Any = None  # the Go2's WebRTC service (robots/go2_sim/webrtc_server.py), with `webrtc`
        SIM_PUSH.subscription(self, self._on_push)
        if self.clock.sim:
            self.set_sim_time(self.sim.time)  # stamps from the start are sim time (0.0)
        model = self.sim.model
        has_world_camera = "world_camera" in {model.camera(i).name for i in range(model.ncam)}
        if cfg.world_camera and not has_world_camera:
            self.log.info(f"world {cfg.world!r} has no world_camera; /world_camera/* stays silent")
        world_camera = cfg.world_camera and has_world_camera
        self.outputs = SimPublishers(self, self.sim, self.profile, cfg, world_camera)
        setup = CameraSetup(
            head=(cfg.camera_width, cfg.camera_height) if cfg.camera else None,
            world=(cfg.world_camera_width, cfg.world_camera_height) if world_camera else None,
            detections=cfg.detections,
        )
        self.renderer = RenderThread(model, setup, self.outputs, self.log, self.node_name)
        self.physics = PhysicsThread(self)
        if cfg.unitree or cfg.webrtc:
            try:
                from go2vlm.robots.go2_sim.unitree_bridge import UnitreeSimBridge
            except ImportError as exc:
                raise RuntimeError(
                    f"unitree: true needs go2vlm.robots.go2_sim.unitree_bridge, which cannot be imported: {exc}"
                ) from exc
            self.bridge = UnitreeSimBridge(
                self, self.sim, estop=lambda: self.estop.engaged, odometry=self.odometry.reported
            )
        if cfg.webrtc:
            from go2vlm.robots.go2_sim.webrtc_server import SimWebRtcServer

            self.webrtc = SimWebRtcServer(
                self,
                self.profile,
                host=cfg.webrtc_host,
                port=cfg.webrtc_port,
                legacy_port=cfg.webrtc_legacy_port,
                seal=cfg.webrtc_seal,
                aes_key=read_secret(protocol.AES_KEY_ENV, cfg.webrtc_aes_key_file, "webrtc_aes_key_file"),
                firmware=cfg.webrtc_firmware,
                takeover=cfg.webrtc_takeover,
            )
        self.outputs.static(has_world_camera)

    # -- the robot end's own parts (robots/base.py) --------------------------------------------
    def damp(self) -> None:
        self.physics.call(self._damp)

    def _damp(self, sim: Go2Sim) -> None:
        if self.bridge is not None:
            self.bridge.damp_now()  # through the bridge, so that its sport mode agrees
        else:
            sim.damp()

    def posture(self, word: str) -> None:
        action = POSTURES[word]
        self.log.info(f"posture: {word}")

        def run(sim: Go2Sim) -> None:
            action(sim)
            self.posture_done(word, "ok")

        self.physics.call(run)

    def on_posture_done(self) -> None:
        """The physics thread's /sim/status (2 Hz) carries it."""

    def apply_command(self, sim: Go2Sim) -> None:
        """On the physics thread, before each chunk: the command the robot walks with."""
        if self.estop.engaged:  # nothing moves the robot while the e-stop holds
            sim.set_command(0.0, 0.0, 0.0)
            return
        cmd, timed_out = self.latest_command()
        just_timed_out = timed_out and not self._cmd_timed_out
        if just_timed_out and any(cmd):
            self.log.warning(f"no /cmd_vel for {self.config.cmd_timeout_s:g} s: stopping")
        self._cmd_timed_out = timed_out
        if not timed_out:
            sim.set_command(*cmd)
        elif self.bridge is None or just_timed_out:
            # Stop once on the timeout; after that, with the Unitree bridge, its sport API has the robot.
            sim.set_command(0.0, 0.0, 0.0)

    def status(self) -> dict[str, Any]:
        """Called on the physics thread (its state is the newest)."""
        cfg: SimNodeConfig = self.config
        s = self.physics.state if self.physics.state is not None else self.sim.state()
        status: dict[str, Any] = {
            "sim_time": round(s.time, 4),
            "wall_time": round(time.time(), 3),  # wall time whatever the clock: pairs sim time with the wall
            "use_sim_time": self.clock.sim,
            "rtf": round(self.physics.rtf, 3),
            "rtf_target": None if cfg.fast else cfg.rtf,
            "fast": cfg.fast,
            "mode": s.mode,
            "physics": cfg.mode,
            "fell": bool(s.fell),
            "world": cfg.world,
            "command": [round(float(v), 4) for v in s.command],
            "cmd_timed_out": self._cmd_timed_out,
            "frames": self.renderer.frames,
            "frames_dropped": self.renderer.dropped,
            "overruns": self.counters.get("physics_overruns", 0),
            "render_error": self.renderer.error,
            "motor_temp_max_c": round(float(self.outputs.thermal.temps.max()), 1),
            "battery_pct": round(self.outputs.battery.soc_pct, 2),
            "lidar": cfg.lidar,
            "odom_drift": cfg.odom_drift,
            "counters": dict(self.counters),
        }
        if self.webrtc is not None:
            status["webrtc"] = self.webrtc.status()
        return status

    # -- inputs ------------------------------------------------------------------------------
    def _on_push(self, msg: Twist) -> None:
        dv = (msg.linear.x, msg.linear.y, msg.linear.z)
        dw = (msg.angular.x, msg.angular.y, msg.angular.z)
        if not all(math.isfinite(v) for v in dv + dw) or math.hypot(*dv) > 10.0 or math.hypot(*dw) > 30.0:
            self.count("bad_push")
            self.log.throttled("error", 2.0, f"rejected /sim/push {dv} {dw}: non-finite or too large")
            return
        self.log.info(f"push: dv {dv} m/s (world), dw {dw} rad/s (base)")
        self.physics.call(lambda sim: sim.push(dv, dw))

    # -- lifecycle ---------------------------------------------------------------------------
    def start(self) -> SimNode:
        super().start()
        if not self._started:
            self._started = True
            self.renderer.start()
            self.physics.start()
        return self

    def close(self) -> None:
        self.physics.stop()
        self.renderer.stop()
        if self.bridge is not None:
            self.bridge.close()
        if self.webrtc is not None:
            self.webrtc.close()
        self.sim.close()

    @property
    def sim_time(self) -> float:
        return self.sim.time

    @property
    def rtf(self) -> float:
        """The real-time factor achieved over the last ~2 s of wall time."""
        return self.physics.rtf

    @property
    def frames(self) -> int:
        return self.renderer.frames
