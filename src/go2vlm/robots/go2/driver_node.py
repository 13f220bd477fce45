"""go2: drives a real Unitree Go2 (or the simulator) over Unitree's own DDS protocol (`transport: dds`,
the EDU's Ethernet port) or over WebRTC (`transport: webrtc`, the Unitree app's route over Wi-Fi, every
Go2 model). Over WebRTC the Unitree topics below travel as JSON on the data channel and the camera as
a video track (robots/go2/webrtc/transport.py); everything on the ROS side is the same.

Subscribes:
  /emergency_stop          std_msgs/Bool        true -> Damp (1001), latched: no Move, no standing up
                                                until released; false does NOT release (as the safety gate)
  /emergency_stop/release  std_msgs/String      data == `release_token` ("RELEASE"), exactly, releases;
                                                the robot stays damped until "recover" or "stand", and
                                                Move resumes only after /cmd_vel has gone through zero
  /cmd_vel                 geometry_msgs/Twist  only from the one safety gate (safety/commander.py): any
                                                other writer stops the robot (StopMove) until it is gone;
                                                motion starts from a zero command after such a stop or
                                                a release; sent as sport Move (1008) at
                                                `move_rate_hz`; a zero (or stale, `cmd_timeout_s`)
                                                command sends StopMove (1003), repeated until answered ok
  /safety/heartbeat        std_msgs/String      (latched) which /cmd_vel writer is a safety gate
  /go2/command             std_msgs/String      stand | balance | sit | rise | standdown | damp |
                                                recover | hello | stop (`go2vlm go2 <posture>` sends
                                                here while a driver runs: one commander per robot)
  rt/sportmodestate        unitree_go/SportModeState_  (as /sportmodestate) the robot's state
  rt/lowstate              unitree_go/LowState_  (as /lowstate, `lowstate_topic`) motors, battery, IMU
  rt/api/sport/request     unitree_api/Request_ other clients' sport requests: a foreign controller
                                                (any writer but ours asking for a motion or posture)
                                                triggers `foreign_sport` (see below)
  rt/utlidar/cloud         sensor_msgs/PointCloud2  (= /utlidar/cloud, sensor QoS) the L1 lidar, with `lidar`
  rt/api/sport/response, rt/api/videohub/response  unitree_api/Response_
Publishes:
  rt/api/sport/request, rt/api/videohub/request    unitree_api/Request_
  /odom                    nav_msgs/Odometry    odom -> base_link, twist in base_link (`state_rate_hz`)
  /imu                     sensor_msgs/Imu      frame base_link
  /tf                      tf2_msgs/TFMessage   odom -> base_link
  /go2/lowstate            unitree_go/LowState  the robot's rt/lowstate relayed at most at `state_rate_hz`
                                                (a Go2 sends ~500 Hz): the safety gate's health input
  /camera/image_raw/compressed  sensor_msgs/CompressedImage  front camera JPEG (videohub GetImageSample)
  /camera/image_raw        sensor_msgs/Image    the same frame decoded, bgr8, frame camera_optical_frame
  /camera/camera_info      sensor_msgs/CameraInfo  pinhole from `camera_hfov_deg`
  /scan                    sensor_msgs/LaserScan  sensor QoS, from each rt/utlidar/cloud (`lidar`): frame
                           base_link, 360 deg in 2 deg bins, the nearest return in the obstacle band
                           (geometry/scan.py, the sim's code); a cloud in an unknown frame is dropped,
                           logged and counted, an empty one gives no scan (the gate's guard goes blind)
  /go2/status              std_msgs/String      latched JSON, 1 Hz and after each /go2/command: connected,
                                                estop, moving, mode, commander, foreign_sport,
                                                last_command {seq, name, result}, ...

Stops are never dropped: Damp and StopMove are repeated (every 0.25 s) until the robot answers ok,
and the e-stop is read before /cmd_vel in every executor pass. Against the simulator an ok means
the stop was applied (robots/go2_sim/unitree_bridge.py).

A foreign sport controller (`foreign_sport`): the Go2's sport API is open by Unitree's design, and a
second program commanding it (another laptop's driver, an SDK script) makes the robot obey whoever
spoke last. "damp" (the default) latches this driver's e-stop as if /emergency_stop had come: Damp,
again after every further foreign request, and no Move until the deliberate release; it is the safe
default because two masters on one robot is the situation where nobody knows what it does next,
and Damp is the one action the other controller cannot make worse by accident. "report" only logs
and counts. Either way the log says so loudly and /go2/status names the writer (GUID, node).

WebRTC (`ip`, `serial`, `mode`, `signal_port`, `aes_key_file`, `connect_timeout_s`; the AES key is a
secret: from $GO2VLM_AES_KEY or the file aes_key_file names, never a parameter, never logged): the first connection
is made at start; a robot that does not answer, a signalling answer that cannot be read or an unknown
protocol is one line and exit 2. A link that drops later stops the robot (StopMove is not possible,
so: nothing sent, nothing queued, /go2/status `link.connected` false, the gate stops on the silent
/go2/lowstate), reconnects with backoff, and moves again only after /cmd_vel passed through zero. The
robot closing the connection (another client took it over) or answering "reject" on reconnect counts
as a foreign controller (`foreign_sport`). The firmware version is read on every connect and logged,
with a warning for one go2vlm has not been tested on (docs/real_robot.md#firmware).

Time: cmd_timeout_s, move_rate_hz, state_rate_hz, camera_rate_hz, the status period and the stamps
are in the node's clock (sim time with use_sim_time, e.g. against the simulator); the sport and
videohub RPC timeouts (rpc_timeout_s) are network timeouts, always wall time.

The Go2 speaks on DDS domain 0; `interface` picks the network interface wired to it (e.g. enp3s0,
192.168.123.x); `lo` reaches a local simulator (`go2vlm run sim --param unitree=true`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from go2vlm.bus import QOS_UNITREE_READER, Endpoint, discovery_info, param
from go2vlm.bus.topics import (
    CAMERA_IMAGE,
    CAMERA_IMAGE_COMPRESSED,
    CAMERA_INFO,
    GO2_COMMAND,
    GO2_LOWSTATE,
    GO2_STATUS,
    IMU,
    LIDAR_CLOUD,
    LOWSTATE,
    ODOM,
    SCAN,
    TF,
)
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.geometry.rotations import quat_to_mat
from go2vlm.geometry.scan import Stance
from go2vlm.msgs.base_state import base_state_messages
from go2vlm.msgs.image import camera_info, numpy_to_image
from go2vlm.msgs.pointcloud import scan_from_cloud
from go2vlm.msgs.sensor_msgs import CompressedImage, PointCloud2
from go2vlm.msgs.unitree import LowState, Request, SportModeState
from go2vlm.robot_profile.go2 import GO2
from go2vlm.robots.base import RobotEnd, RobotEndConfig
from go2vlm.robots.go2 import protocol as p
from go2vlm.robots.go2.client import RpcClient

RETRY_S = 0.25  # an unanswered Damp or StopMove is sent again after this long


@dataclass
class Go2DriverConfig(RobotEndConfig):
    transport: str = param(
        "dds",
        help="dds: Unitree DDS on the Ethernet port (EDU); webrtc: the Unitree app's route (every Go2)",
        choices=("dds", "webrtc"),
    )
    ip: str = param("", help="webrtc: the robot's IP (its Wi-Fi address; 127.0.0.1 for go2vlm sim --webrtc)")
    serial: str = param("", help="webrtc: find the robot on the LAN by its serial number instead of ip")
    mode: str = param(
        "sta", help="webrtc: sta (robot on your network) or ap (your PC on the robot's Wi-Fi)", choices=("sta", "ap")
    )
    signal_port: int = param(
        p.SIGNAL_PORT, help="webrtc: the robot's signalling port (9991; the sim's --webrtc port)", min=1, max=65535
    )
    aes_key_file: str = param(
        "",
        help="webrtc: a file holding the robot's AES-128 key (32 hex chars; else env GO2VLM_AES_KEY), "
        "needed on firmware >= 1.1.15",
    )
    connect_timeout_s: float = param(
        10.0, help="webrtc: signalling + ICE + validation at start (wall s)", min=1.0, max=120.0
    )
    interface: str = param("", help="network interface wired to the Go2 (enp3s0, eth0; lo for a local sim); '' = env")
    domain: int = param(-1, help="DDS domain; the Go2 uses 0; -1 = ROS_DOMAIN_ID (default 0)", min=-1, max=232)
    move_rate_hz: float = param(20.0, help="rate of sport Move requests while /cmd_vel is non-zero", min=1.0, max=100.0)
    rpc_timeout_s: float = param(1.0, help="timeout of sport/videohub requests (unitree_sdk2 uses 1 s)", min=0.05)
    camera_rate_hz: float = param(
        10.0, help="front camera polling rate (videohub GetImageSample); 0 = camera off", min=0.0, max=30.0
    )
    camera_hfov_deg: float = param(
        round(GO2.head_camera.hfov_deg(GO2.head_camera.width, GO2.head_camera.height), 1),
        help="front camera horizontal FOV for /camera/camera_info (the sim's camera at 1280x720; calibrate)",
        min=10.0,
        max=179.0,
    )
    publish_raw: bool = param(True, help="also publish the decoded bgr8 /camera/image_raw")
    state_rate_hz: float = param(50.0, help="max rate of /odom, /imu, /tf from rt/sportmodestate", min=1.0, max=500.0)
    state_topic: str = param(
        p.SPORT_STATE_TOPIC, help="the robot's state topic (ROS form of rt/sportmodestate; e.g. /lf/sportmodestate)"
    )
    lowstate_topic: str = param(
        LOWSTATE.name, help="the robot's low-level state (ROS form of rt/lowstate; e.g. /lf/lowstate); '' = none"
    )
    lidar: bool = param(True, help="derive /scan from the robot's rt/utlidar/cloud (for the gate's collision guard)")
    stand_on_start: bool = param(False, help="send StandUp + BalanceStand once the robot is reachable")
    odom_frame: str = param(GO2.frames.odom, help="odometry frame")
    base_frame: str = param(GO2.frames.base, help="robot base frame")
    camera_frame: str = param(GO2.frames.camera, help="frame_id of the camera images")
    foreign_sport: str = param(
        "damp",
        help="what a foreign sport controller on rt/api/sport/request triggers: damp (latch the e-stop) or report",
        choices=("damp", "report"),
    )


class Go2DriverNode(RobotEnd):
    """The robot end of a real Go2 (robots/base.py does the e-stop, /cmd_vel, postures and status).
    Its own part is Unitree's: the sport RPC (`self.sport`: Move, StopMove, Damp and the posture
    chains), the videohub camera (`self.video`), and the robot's state, lowstate and lidar cloud
    turned into ROS topics. The transport is Unitree's DDS protocol (RpcClient over rt/api/*) or WebRTC
    (`self.link`, robots/go2/webrtc/transport.py: an RpcClient-shaped `sport` and the same callbacks
    `_on_state`, `_on_lowstate`, `_on_cloud`, `_publish_camera`, fed on the driver's thread)."""

    name = "go2"
    Config = Go2DriverConfig
    profile = GO2
    postures = p.POSTURES
    estop_postures = p.ESTOP_ALLOWED
    posture_topic = GO2_COMMAND
    status_topic = GO2_STATUS

    def __init__(self, config: Go2DriverConfig | None = None, **kwargs: Any) -> None:
        cfg = config if config is not None else Go2DriverConfig()
        # The driver's own params pick the participant unless the caller (CLI flags) already did.
        if cfg.interface and kwargs.get("interface") is None:
            kwargs["interface"] = cfg.interface
        if cfg.domain >= 0 and kwargs.get("domain_id") is None:
            kwargs["domain_id"] = cfg.domain
        super().__init__(
            cfg,
            held="Damp, no Move, no standing up",
            released_note="the robot stays down until 'recover' or 'stand'",
            **kwargs,
        )
        self.link: Any = None  # the WebRTC transport (robots/go2/webrtc/transport.py), with transport=webrtc
        if cfg.transport == "webrtc":
            from go2vlm.robots.go2.webrtc.transport import WebRtcTransport

            self.link = WebRtcTransport(self, cfg)
            self.sport: Any = self.link.sport
            self.video: Any = None
        else:
            self.sport = RpcClient(self, p.SPORT_SERVICE, timeout_s=cfg.rpc_timeout_s)
            self.video = RpcClient(self, p.VIDEO_SERVICE, timeout_s=cfg.rpc_timeout_s)

        self.moving = False  # a non-zero Move was sent since the last StopMove
        self._damp_acked = False
        self._damp_in_flight = False
        self._damp_last_try = -math.inf
        self._stop_acked = True  # the last StopMove was answered ok (or none was needed)
        self._stop_in_flight = False
        self._stop_last_try = -math.inf
        self._busy_command: str | None = None
        self.foreign: dict[str, Any] = {"requests": 0, "writers": {}}
        self._camera_pending = False
        self._last_state_pub = -math.inf
        self.state: SportModeState | None = None
        self._state_time = -math.inf
        self._stood_on_start = not cfg.stand_on_start
        self.moves_sent = 0
        self.stops_sent = 0
        self.damps_sent = 0
        self.frames = 0

        self.pub_odom = ODOM.publisher(self)
        self.pub_imu = IMU.publisher(self)
        self.pub_tf = TF.publisher(self)
        if cfg.camera_rate_hz > 0:
            self.pub_jpeg = (  # the robot's own JPEGs: videohub over DDS; WebRTC has H.264 video instead
                CAMERA_IMAGE_COMPRESSED.publisher(self) if self.video is not None else None
            )
            self.pub_image = CAMERA_IMAGE.publisher(self) if cfg.publish_raw else None
            self.pub_info = CAMERA_INFO.publisher(self)
            if self.video is not None:  # over WebRTC the camera is a video track
                self.create_timer(1.0 / cfg.camera_rate_hz, self._poll_camera)

        dds = self.link is None  # over WebRTC the transport feeds the same methods
        if dds:
            self.create_subscription(
                Request, p.request_topic(p.SPORT_SERVICE), self._on_sport_request, QOS_UNITREE_READER, with_sender=True
            )
        self._names = discovery_info.directory(self.participant)
        if dds:
            self.create_subscription(SportModeState, cfg.state_topic, self._on_state, QOS_UNITREE_READER)
        self._last_lowstate_pub = -math.inf
        if cfg.lowstate_topic:
            self.pub_lowstate = GO2_LOWSTATE.publisher(self, name=self.profile.health_topic)
            if dds:
                LOWSTATE.subscription(self, self._on_lowstate, name=cfg.lowstate_topic)
        if cfg.lidar:
            self._scan_spec, self._lidar_tfs = self.profile.scan_spec(), self.profile.lidar_transforms()
            self.pub_scan = SCAN.publisher(self)
            if dds:
                LIDAR_CLOUD.subscription(self, self._on_cloud, name=self.profile.lidar.topic)
        self.create_timer(1.0 / cfg.move_rate_hz, self._move_tick)
        self.create_timer(1.0, self.publish_status)
        if self.link is not None:
            self.link.start()  # the first connection, or a LinkError: one line, exit 2

    def close(self) -> None:
        if self.link is not None:
            self.link.stop()

    # -- the robot end's own parts (robots/base.py) --------------------------------------------
    def on_stop(self, reason: str) -> None:
        if self.moving:
            self._stop_move()

    def damp(self) -> None:
        self._damp_acked = False
        self._damp()

    def posture(self, word: str) -> None:
        self.run_command(word)

    def _on_sport_request(self, req: Request, sender: Endpoint | None) -> None:
        own = str(self.sport.writer_guid)
        if sender is not None and sender.guid == own:
            return
        api = int(req.header.identity.api_id)
        if api not in p.SPORT_API_NAMES:
            return  # a query (API version), not a command
        who = "an unknown writer" if sender is None else sender.guid
        node = self._names.node_of(sender.guid) if sender is not None else None
        self._foreign_sport(p.SPORT_API_NAMES[api], who, None if sender is None else sender.participant, node)

    def _foreign_sport(self, name: str, who: str, participant: Any, node: str | None) -> None:
        """Another controller commands the robot (`foreign_sport`): damp and latch, or report."""
        self.foreign["requests"] += 1
        writers = self.foreign["writers"]
        if who not in writers and len(writers) >= 16:
            writers.pop(next(iter(writers)))  # the status names the latest few, the log every one
        writers[who] = {
            "participant": participant,
            "node": node,
            "last_api": name,
        }
        n = self.count("foreign_sport_requests")
        act = "damping and latching the e-stop" if self.config.foreign_sport == "damp" else "reporting only"
        self.log.throttled(
            "error",
            2.0,
            f"FOREIGN SPORT CONTROLLER: {name} from writer {who} (node {node or 'unknown'}), {n} so far; {act}",
            key=f"foreign:{who}",
        )
        if self.config.foreign_sport != "damp":
            return
        if not self.estop.engaged:
            self.log.warning(
                f"EMERGENCY STOP (foreign_sport=damp): Damp, no Move until {self.estop.token!r} is "
                "published on /emergency_stop/release"
            )
            self.estop.engage(f"foreign sport controller {who} ({name})")
            self.count("estops")
        self._damp_acked = False  # damp again: the other controller may have stood it up
        if not self._damp_in_flight and self.clock.monotonic() - self._damp_last_try > RETRY_S:
            self._damp()

    def run_command(self, name: str) -> None:
        """Send a posture command's API ids in order, each after the previous one answered ok."""
        if name != "stop" and self.moving:
            self._stop_move()
        self._busy_command = name
        self._chain(name, list(p.COMMANDS[name]))

    def _chain(self, name: str, api_ids: list[int]) -> None:
        if not api_ids:
            self._busy_command = None
            self.log.info(f"{name}: done")
            self.posture_done(name, "ok")
            return
        api = api_ids[0]

        def done(result: p.RpcResult) -> None:
            if not result.ok:
                self._busy_command = None
                self.count("rpc_errors")
                what = f"{p.SPORT_API_NAMES.get(api, api)} failed: {result.describe()}"
                self.log.error(f"{name}: {what}")
                self.posture_done(name, what)
                return
            if self.estop.engaged and name not in p.ESTOP_ALLOWED:
                self._busy_command = None
                self.posture_done(name, "refused: emergency stop latched")
                return  # an e-stop came in between: do not finish standing up
            self._chain(name, api_ids[1:])

        self.sport.call_async(api).add_done_callback(done)

    def _on_cloud(self, msg: PointCloud2) -> None:
        try:
            scan = scan_from_cloud(msg, self._scan_spec, self._lidar_tfs, self.config.base_frame, 0.0, self._stance())
        except ValueError as exc:
            self.count("bad_cloud")
            self.log.throttled("error", 2.0, f"dropped a lidar cloud: {exc}")
            return
        if scan is not None:
            self.pub_scan.publish(scan)

    def _stance(self) -> Stance | None:
        """The robot's attitude (its IMU) and body height, from the last rt/sportmodestate: /scan's band
        is measured from the floor (geometry/scan.py). None before a valid one: the base frame's band."""
        s = self.state
        if s is None:
            return None
        q = np.array([float(v) for v in s.imu_state.quaternion])
        height = float(s.body_height)
        if not (np.isfinite(q).all() and abs(np.linalg.norm(q) - 1.0) < 0.05 and math.isfinite(height) and height > 0):
            return None
        return Stance.of(quat_to_mat(q / np.linalg.norm(q)), height)

    def _on_state(self, msg: SportModeState) -> None:
        self.state = msg
        now = self.clock.monotonic()
        self._state_time = now
        if not self._stood_on_start and self.sport.matched and not self.estop.engaged:
            self._stood_on_start = True
            self.log.info("stand_on_start: StandUp + BalanceStand")
            self.run_command("stand")
        if now - self._last_state_pub < 1.0 / self.config.state_rate_hz - 1e-4:
            return
        self._last_state_pub = now
        self._publish_state(msg)

    def _on_lowstate(self, msg: LowState) -> None:
        now = self.clock.monotonic()
        if now - self._last_lowstate_pub < 1.0 / self.config.state_rate_hz - 1e-4:
            return
        self._last_lowstate_pub = now
        self.pub_lowstate.publish(msg)

    # -- motion ------------------------------------------------------------------------------
    def _move_tick(self) -> None:
        now = self.clock.monotonic()
        if self.estop.engaged:
            retry_due = now - self._damp_last_try > RETRY_S
            if not self._damp_acked and not self._damp_in_flight and retry_due:
                self._damp()  # keep trying while the e-stop holds: it must not be lost
            return
        cmd = self.command()
        zero = not any(cmd)
        if zero:
            if self.moving:
                self._stop_move()
            elif not self._stop_acked and not self._stop_in_flight and now - self._stop_last_try > RETRY_S:
                self._stop_move()  # the last StopMove was not answered ok: it must not be lost
            return
        if self._busy_command is not None:
            return
        if self.sport.send_noreply(p.MOVE, {"x": cmd[0], "y": cmd[1], "z": cmd[2]}):
            self.moving = True
            self.moves_sent += 1
        else:
            self.count("not_connected")
            self.log.throttled("warning", 5.0, "no sport service matched: is the robot reachable on this interface?")

    def _stop_move(self) -> None:
        self.moving = False
        self.stops_sent += 1
        self._stop_acked = False
        self._stop_in_flight = True
        self._stop_last_try = self.clock.monotonic()

        def done(result: p.RpcResult) -> None:
            self._stop_in_flight = False
            self._stop_acked = result.ok
            if not result.ok:
                self._rpc_failed("StopMove", result)

        self.sport.call_async(p.STOP_MOVE).add_done_callback(done)

    def _damp(self) -> None:
        self.moving = False
        self.damps_sent += 1
        self._damp_in_flight = True
        self._damp_last_try = self.clock.monotonic()

        def done(result: p.RpcResult) -> None:
            self._damp_in_flight = False
            self._damp_acked = result.ok
            if not result.ok:
                self._rpc_failed("Damp", result)

        self.sport.call_async(p.DAMP).add_done_callback(done)

    def _rpc_failed(self, what: str, result: p.RpcResult) -> None:
        self.count("rpc_errors")
        self.log.throttled("error", 2.0, f"{what} failed: {result.describe()}", key=f"rpc:{what}")

    # -- state -------------------------------------------------------------------------------
    def _publish_state(self, s: SportModeState) -> None:
        cfg: Go2DriverConfig = self.config
        qw, qx, qy, qz = (float(v) for v in s.imu_state.quaternion)
        norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        if not math.isfinite(norm) or norm < 1e-6:
            self.count("bad_state")
            self.log.throttled("error", 2.0, f"rt/sportmodestate has an invalid quaternion {s.imu_state.quaternion}")
            return
        qw, qx, qy, qz = qw / norm, qx / norm, qy / norm, qz / norm
        # velocity is in the odom (world) frame; Odometry's twist is in base_link.
        rot = quat_to_mat(np.array([qw, qx, qy, qz]))
        v_body = rot.T @ np.array([float(v) for v in s.velocity])
        odom, imu, tf = base_state_messages(
            self.stamp(),
            cfg.odom_frame,
            cfg.base_frame,
            s.position,
            (qw, qx, qy, qz),
            v_body,
            (0.0, 0.0, s.yaw_speed),
            s.imu_state.gyroscope,
            s.imu_state.accelerometer,
        )
        self.pub_odom.publish(odom)
        self.pub_imu.publish(imu)
        self.pub_tf.publish(tf)

    def status(self) -> dict[str, Any]:
        s = self.state
        status: dict[str, Any] = {
            "connected": self.sport.matched,
            "state_age_s": None if s is None else round(self.clock.monotonic() - self._state_time, 3),
            "moving": self.moving,
            "command": [round(v, 3) for v in self.command()],
            "mode": None if s is None else p.SPORT_MODES.get(int(s.mode), str(int(s.mode))),
            "body_height": None if s is None else round(float(s.body_height), 3),
            "busy": self._busy_command,
            "moves_sent": self.moves_sent,
            "stops_sent": self.stops_sent,
            "damps_sent": self.damps_sent,
            "stop_acked": self._stop_acked,
            "foreign_sport": {"policy": self.config.foreign_sport, **self.foreign},
            "frames": self.frames,
            "errors": dict(self.counters),
            "transport": self.config.transport,
        }
        if self.link is not None:
            status["link"] = self.link.status()
        return status

    # -- camera ------------------------------------------------------------------------------
    def _poll_camera(self) -> None:
        if self._camera_pending or not self.video.matched:
            return  # one request in flight: a slow link gets fewer, not older, frames
        self._camera_pending = True
        stamp = self.now()
        self.video.call_async(p.GET_IMAGE_SAMPLE).add_done_callback(lambda r: self._on_frame(r, stamp))

    def _on_frame(self, result: p.RpcResult, stamp: float) -> None:
        self._camera_pending = False
        if not result.ok:
            self.count("camera_errors")
            self.log.throttled("warning", 5.0, f"videohub GetImageSample failed: {result.describe()}", key="cam")
            return
        jpeg = result.binary
        if not jpeg or len(jpeg) > p.MAX_IMAGE_BYTES or jpeg[:2] != b"\xff\xd8":
            self.count("bad_frames")
            self.log.throttled("error", 2.0, f"videohub returned {len(jpeg)} bytes that are not a JPEG", key="camjpg")
            return
        import cv2

        bgr = cv2.imdecode(np.frombuffer(jpeg, dtype=np.uint8), cv2.IMREAD_COLOR)
        if bgr is None:
            self.count("bad_frames")
            self.log.throttled("error", 2.0, "videohub JPEG does not decode", key="camdec")
            return
        self._publish_camera(bgr, stamp, bytes(jpeg))

    def _publish_camera(self, bgr: np.ndarray, stamp: float, jpeg: bytes | None) -> None:
        """One camera frame out: the JPEG as it came (DDS videohub), the bgr8 image, the camera info."""
        cfg: Go2DriverConfig = self.config
        header = self.header(cfg.camera_frame, t=stamp)
        if jpeg is not None and self.pub_jpeg is not None:
            self.pub_jpeg.publish(CompressedImage(header=header, format="jpeg", data=jpeg))
        if self.pub_image is not None:
            self.pub_image.publish(numpy_to_image(bgr, "bgr8", header))
        h, w = bgr.shape[:2]
        self.pub_info.publish(camera_info(PinholeCamera.from_hfov(w, h, math.radians(cfg.camera_hfov_deg)), header))
        self.frames += 1
