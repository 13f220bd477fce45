"""The simulator's side of Unitree's DDS protocol: what a real Go2 serves, answered from a `Go2Sim`.

Serves (DDS topic names as on the robot):
  rt/api/sport/request -> rt/api/sport/response       unitree_api/Request_ -> Response_
      Damp 1001, BalanceStand 1002, StopMove 1003, StandUp 1004, StandDown 1005, RecoveryStand 1006,
      Move 1008 {"x","y","z"} (noreply), Sit 1009, RiseSit 1010, Hello 1016; api 1 = API version
  rt/api/videohub/request -> rt/api/videohub/response  GetImageSample 1001: head camera JPEG in `binary`
  rt/sportmodestate                                    unitree_go/SportModeState_ at `state_rate_hz`
  rt/lowstate                                          unitree_go/LowState_: the SimNode's own /lowstate,
                                                       which is this DDS topic (motors, battery, IMU)

Like the robot's sport service:
- Move is obeyed only in balance stand (after BalanceStand, RecoveryStand, or StandUp+BalanceStand;
  the sim starting up standing counts as balance stand, as a Go2 after boot). A Move while lying,
  damped, sitting or after a bare StandUp (joints locked) is ignored, not an error: it has no reply.
- A Move holds for `move_timeout_s`; without a newer Move the robot stops (a lost link must not
  leave it walking).
- Bad requests get a status code, never a crash: unknown api id -> 3203 (API not implemented),
  malformed JSON / missing or non-numeric Move fields / oversized parameter or binary -> 3204
  (bad parameter), a handler failure -> 3202 (internal). Noreply requests are never answered.

Stops are never dropped (unlike a real Go2, whose queue we cannot see, the sim promises this):
- An answer means "applied": a request is answered on the physics thread after its action ran, so
  code 0 for a Damp means the robot is damped. A request that is never applied is never answered
  with 0: its client times out, or gets an error code, and retries (the go2 driver does).
- Damp and StopMove (protocol.STOP_APIS) go in a priority lane, applied before anything else at
  the next physics step. A Damp supersedes what is still pending from before it (postures are
  answered 3202 "superseded", a pending Move is dropped); a StopMove supersedes a pending Move.
- Moves do not queue: only the newest pending Move is applied (a burst of thousands of Moves after a
  Damp is one ignored Move on a damped robot). Other postures wait in a bounded queue; when it is
  full the new request is answered 3202 (busy) at once, never silently lost.
- The request reader keeps a deep history (QOS_UNITREE_SERVER), so a burst does not push a Damp
  out of the DDS cache before it is read.
- `estop` (a callable, the owning SimNode's e-stop latch): while it says latched, only Damp,
  StandDown and StopMove (protocol.ESTOP_ALLOWED_APIS) are obeyed; other requests are answered
  3205 (lease denied) and Moves are ignored and counted. A real Go2 knows nothing of our e-stop;
  the sim honours it because it is our own robot end (docs/safety.md).

Threading: requests arrive on the node's executor thread; everything that touches the `Go2Sim`
runs on the physics thread, which calls `on_step(state)` after each physics chunk (SimNode does;
any other owner of a Go2Sim must do the same), with the state as the robot's odometry reports it
(`odometry`: the sim node's `odom_drift`; the truth by default). Camera frames are rendered on the bridge's own
render thread from a snapshot, so a camera request never stalls the physics.

Time: the Move timeout, the rt/sportmodestate rate and its stamps are on the owning node's clock:
the sim's own sim time when it runs with use_sim_time, wall time otherwise.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from go2vlm.bus import QOS_UNITREE_SERVER, QOS_UNITREE_WRITER, Node
from go2vlm.msgs.unitree import IMUState, Request, Response, SportModeState, TimeSpec
from go2vlm.robots.go2 import protocol as p
from go2vlm.sim.render import NewestOnly, camera_scene_option, pose_mirror
from go2vlm.sim.state import RobotState

# The Go2's sport mode for each Go2Sim mode.
_SPORT_MODE = {
    "lying": "lie_down",
    "lying_down": "lie_down",
    "standing_up": "joint_lock",
    "standing": "balance_stand",
    "walking": "locomotion",
    "damped": "damping",
    "fallen": "damping",
    "recovering": "recovery_stand",
}
MAX_PENDING_CAMERA = 16  # answered in one batch per frame; more waiting clients are refused
MAX_PENDING_POSTURES = 64  # postures waiting for the physics thread; more are answered "busy"

_Call = tuple[Request, int, Callable[[], None]]  # request, api id, the action (physics thread)


class UnitreeSimBridge:
    """Serve the Go2's sport + videohub RPC and rt/sportmodestate from a Go2Sim."""

    def __init__(
        self,
        node: Node,
        sim: Any,
        *,
        state_rate_hz: float = 50.0,
        jpeg_quality: int = 80,
        camera_width: int | None = None,
        camera_height: int | None = None,
        move_timeout_s: float = 1.0,
        estop: Callable[[], bool] = lambda: False,
        odometry: Callable[[RobotState], RobotState] = lambda s: s,
    ) -> None:
        if not state_rate_hz > 0:
            raise ValueError(f"state_rate_hz must be positive, got {state_rate_hz}")
        if not 1 <= jpeg_quality <= 100:
            raise ValueError(f"jpeg_quality must be 1..100, got {jpeg_quality}")
        self.node = node
        self.sim = sim
        self.state_period = 1.0 / state_rate_hz
        self.jpeg_quality = int(jpeg_quality)
        self.camera_size = (
            int(camera_width or sim.config.camera_width),
            int(camera_height or sim.config.camera_height),
        )
        self.move_timeout_s = move_timeout_s
        self.estop = estop
        self.odometry = odometry  # the state as the robot's odometry reports it (the sim node's odom_drift)
        self._lock = threading.Lock()
        self._stops: list[_Call] = []  # the priority lane
        self._calls: deque[_Call] = deque()  # postures, in order, at most MAX_PENDING_POSTURES
        self._pending_move: _Call | None = None  # only the newest Move counts
        self._camera_waiting: list[Request] = []
        self._balance = sim.mode in ("standing", "walking")
        self._sitting = False
        self._last_move = -math.inf
        self._moving = False
        self._next_state = -math.inf
        self.requests = 0
        self.errors = 0
        self.moves = 0
        self.ignored_moves = 0
        self.refused = 0  # refused while the e-stop is latched
        self.superseded = 0
        self.frames = 0

        self.pub_state = node.create_publisher(SportModeState, p.SPORT_STATE_TOPIC, QOS_UNITREE_WRITER)
        self.pub_sport = node.create_publisher(Response, p.response_topic(p.SPORT_SERVICE), QOS_UNITREE_WRITER)
        self.pub_video = node.create_publisher(Response, p.response_topic(p.VIDEO_SERVICE), QOS_UNITREE_WRITER)
        node.create_subscription(Request, p.request_topic(p.SPORT_SERVICE), self._on_sport_request, QOS_UNITREE_SERVER)
        node.create_subscription(Request, p.request_topic(p.VIDEO_SERVICE), self._on_video_request, QOS_UNITREE_SERVER)
        self._render = _JpegRenderer(self)
        self._render.start()  # GL context up front: the first camera request must not time out

    # -- requests (node thread) ------------------------------------------------------------------
    def _answer(self, pub: Any, request: Request, code: int, data: str = "", binary: bytes = b"") -> None:
        if code != p.OK:
            self.errors += 1
        if request.header.policy.noreply:
            return
        pub.publish(p.build_response(request, code, data, binary))

    def _reject(self, pub: Any, request: Request, code: int, why: str) -> None:
        self.node.count("unitree_bad_requests")
        api = request.header.identity.api_id
        self.node.log.throttled("error", 2.0, f"unitree request api {api} rejected with {p.describe_code(code)}: {why}")
        self._answer(pub, request, code)

    def _on_sport_request(self, request: Request) -> None:
        self.requests += 1
        api = int(request.header.identity.api_id)
        try:
            params = p.parse_parameter(request)
            if api == p.API_VERSION:
                self._answer(self.pub_sport, request, p.OK, p.SPORT_API_VERSION)
                return
            if api not in p.SPORT_API_NAMES:
                raise p.ProtocolError(p.ERR_SERVER_API_NOT_IMPL, f"api id {api} is not implemented")
            action = self._sport_action(api, params)
        except p.ProtocolError as exc:
            self._reject(self.pub_sport, request, exc.code, str(exc))
            return
        except Exception as exc:  # a bug of ours must still produce an answer, not a hang
            self._reject(self.pub_sport, request, p.ERR_SERVER_INTERNAL, f"{type(exc).__name__}: {exc}")
            return
        busy = False
        superseded: list[_Call] = []
        with self._lock:
            call = (request, api, action)
            if api in p.STOP_APIS:
                self._stops.append(call)
                if self._pending_move is not None:
                    superseded.append(self._pending_move)
                    self._pending_move = None
                if api == p.DAMP:
                    superseded.extend(self._calls)
                    self._calls.clear()
            elif api == p.MOVE:
                if self._pending_move is not None:
                    superseded.append(self._pending_move)
                self._pending_move = call
            elif len(self._calls) >= MAX_PENDING_POSTURES:
                busy = True
            else:
                self._calls.append(call)
        for old, _, _ in superseded:  # never applied, so never answered "ok"
            self.superseded += 1
            self.node.count("unitree_superseded")
            self._answer(self.pub_sport, old, p.ERR_SERVER_INTERNAL)
        if busy:
            self._reject(self.pub_sport, request, p.ERR_SERVER_INTERNAL, "busy: too many requests waiting")

    def _sport_action(self, api: int, params: Any) -> Callable[[], None]:
        """Validate on the node thread; the returned action runs on the physics thread."""
        sim = self.sim
        if api == p.MOVE:
            vx, vy, vyaw = p.parse_move(params)
            return lambda: self._move(vx, vy, vyaw)
        if api == p.STOP_MOVE:
            return self._stop
        if api == p.DAMP:
            return lambda: self._posture(sim.damp, balance=False)
        if api == p.STAND_UP:
            return lambda: self._posture(sim.stand_up, balance=False)
        if api == p.STAND_DOWN:
            return lambda: self._posture(sim.lie_down, balance=False)
        if api == p.RECOVERY_STAND:
            return lambda: self._posture(sim.recovery_stand, balance=True)
        if api == p.BALANCE_STAND:
            return self._balance_stand
        if api == p.SIT:
            return self._sit
        if api == p.RISE_SIT:
            return self._rise
        if api == p.HELLO:
            return self._stop  # a wave of the paw; the sim only makes sure it stands still for it
        raise p.ProtocolError(p.ERR_SERVER_API_NOT_IMPL, f"api id {api} is not implemented")

    def _on_video_request(self, request: Request) -> None:
        self.requests += 1
        api = int(request.header.identity.api_id)
        try:
            p.parse_parameter(request)
            if api == p.API_VERSION:
                self._answer(self.pub_video, request, p.OK, p.VIDEO_API_VERSION)
                return
            if api != p.GET_IMAGE_SAMPLE:
                raise p.ProtocolError(p.ERR_SERVER_API_NOT_IMPL, f"videohub api id {api} is not implemented")
        except p.ProtocolError as exc:
            self._reject(self.pub_video, request, exc.code, str(exc))
            return
        if self._render.error is not None:
            self._reject(self.pub_video, request, p.ERR_SERVER_INTERNAL, self._render.error)
            return
        with self._lock:
            if len(self._camera_waiting) >= MAX_PENDING_CAMERA:
                busy = True
            else:
                busy = False
                self._camera_waiting.append(request)
        if busy:
            self._reject(self.pub_video, request, p.ERR_SERVER_INTERNAL, "too many camera requests waiting")

    # -- physics thread ----------------------------------------------------------------------
    def on_step(self, state: RobotState | None = None) -> None:
        """Apply queued sport commands, publish rt/sportmodestate when due, hand camera snapshots
        to the render thread. Call on the thread that steps the sim, after each step or chunk."""
        with self._lock:
            calls = [*self._stops, *self._calls]
            if self._pending_move is not None:
                calls.append(self._pending_move)
            self._stops, self._pending_move = [], None
            self._calls.clear()
            want_frame = bool(self._camera_waiting)
        for request, api, fn in calls:
            self._apply(request, api, fn)
        now = self.node.clock.monotonic()
        if self._moving and now - self._last_move > self.move_timeout_s:
            self._moving = False
            self.sim.stop()
            self.node.log.info(f"no Move for {self.move_timeout_s:g} s: stopping")
        if want_frame:
            d = self.sim.data
            self._render.submit(d.qpos.copy(), d.mocap_pos.copy(), d.mocap_quat.copy())
        if now >= self._next_state:
            self._next_state = max(self._next_state + self.state_period, now)
            self.pub_state.publish(self.sport_state(state if state is not None else self.odometry(self.sim.state())))

    tick = on_step

    def _apply(self, request: Request, api: int, fn: Callable[[], None]) -> None:
        """Run one action on the physics thread, then answer: the answer says it was applied."""
        if self.estop() and api not in p.ESTOP_ALLOWED_APIS:
            self.refused += 1
            self.node.count("unitree_refused_estop")
            name = p.SPORT_API_NAMES.get(api, str(api))
            self.node.log.throttled("warning", 2.0, f"sport {name} refused: the e-stop is latched", key="estop")
            self._answer(self.pub_sport, request, p.ERR_SERVER_LEASE_DENIED)
            return
        try:
            fn()
        except Exception as exc:
            self.node.count("unitree_action_errors")
            self.node.log.throttled("error", 2.0, f"sport action failed: {type(exc).__name__}: {exc}")
            self._answer(self.pub_sport, request, p.ERR_SERVER_INTERNAL)
            return
        self._answer(self.pub_sport, request, p.OK)

    def _move(self, vx: float, vy: float, vyaw: float) -> None:
        if not self._balance or self._sitting or self.sim.mode not in ("standing", "walking"):
            self.ignored_moves += 1
            self.node.log.throttled(
                "warning", 5.0, f"Move ignored in mode {self.sim.mode!r}: send BalanceStand or RecoveryStand first"
            )
            return
        self.sim.set_command(vx, vy, vyaw)
        self._last_move = self.node.clock.monotonic()
        self._moving = True
        self.moves += 1

    def _stop(self) -> None:
        self._moving = False
        self.sim.stop()

    def damp_now(self) -> None:
        """Damp at once (the owner's e-stop); physics thread only."""
        self._posture(self.sim.damp, balance=False)

    def _posture(self, fn: Callable[[], Any], *, balance: bool) -> None:
        self._stop()
        self._sitting = False
        fn()
        self._balance = balance

    def _balance_stand(self) -> None:
        self._stop()
        self._sitting = False
        if self.sim.mode in ("lying", "damped", "lying_down"):
            self.sim.stand_up()
        self._balance = True

    def _sit(self) -> None:
        self._stop()
        self._sitting = True

    def _rise(self) -> None:
        self._sitting = False

    def sport_state(self, s: RobotState) -> SportModeState:
        now = self.node.now()
        mode = p.SPORT_MODE_CODES["sit" if self._sitting else _SPORT_MODE.get(s.mode, "idle")]
        if mode == 1 and not self._balance:
            mode = 6  # upright but joints locked (StandUp without BalanceStand)
        forces = [int(min(max(f, -32768), 32767)) for f in s.foot_force]
        return SportModeState(
            stamp=TimeSpec(sec=int(now), nanosec=int((now % 1.0) * 1e9)),
            error_code=0,
            imu_state=IMUState(
                quaternion=[float(v) for v in s.quaternion],
                gyroscope=[float(v) for v in s.imu_gyro],
                accelerometer=[float(v) for v in s.imu_acc],
                rpy=[float(v) for v in s.imu_rpy],
                temperature=30,
            ),
            mode=mode,
            progress=0.0,
            gait_type=1 if s.mode == "walking" else 0,
            foot_raise_height=0.08,
            position=[float(v) for v in s.position],
            body_height=float(s.position[2]),
            velocity=[float(v) for v in s.lin_vel_world],
            yaw_speed=float(s.ang_vel_world[2]),
            foot_force=forces,
        )

    # -- render thread -------------------------------------------------------------------------
    def _frame_ready(self, jpeg: bytes | None, error: str | None) -> None:
        with self._lock:
            waiting, self._camera_waiting = self._camera_waiting, []
        for req in waiting:
            if jpeg is None:
                self._reject(self.pub_video, req, p.ERR_SERVER_INTERNAL, error or "no frame")
            else:
                self._answer(self.pub_video, req, p.OK, "", jpeg)
        if jpeg is not None:
            self.frames += 1

    def close(self) -> None:
        self._render.stop()


class _JpegRenderer:
    """Owns a GL context and a mirror MjData; renders the head camera and encodes a JPEG."""

    def __init__(self, bridge: UnitreeSimBridge) -> None:
        self.bridge = bridge
        self.error: str | None = None
        self._snapshots: NewestOnly[tuple[np.ndarray, np.ndarray, np.ndarray]] = NewestOnly()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="unitree-bridge:render", daemon=True)
        self._thread.start()

    def submit(self, qpos: np.ndarray, mocap_pos: np.ndarray, mocap_quat: np.ndarray) -> None:
        self._snapshots.put((qpos, mocap_pos, mocap_quat))

    def stop(self) -> None:
        self._snapshots.close()
        if self._thread is not None:
            self._thread.join(5.0)

    def _run(self) -> None:
        import cv2
        import mujoco

        model = self.bridge.sim.model
        width, height = self.bridge.camera_size
        try:
            data = mujoco.MjData(model)
            renderer = mujoco.Renderer(model, height=height, width=width)
        except Exception as exc:  # no GL: camera requests get an error code, the rest keeps working
            self.error = f"rendering unavailable: {type(exc).__name__}: {exc}"
            self.bridge.node.log.error(f"{self.error}; set MUJOCO_GL=egl or osmesa")
            self.bridge._frame_ready(None, self.error)
            return
        opt = camera_scene_option(hide_robot=True)
        cam = model.camera("head_camera").id
        params = [int(cv2.IMWRITE_JPEG_QUALITY), self.bridge.jpeg_quality]
        try:
            while (snap := self._snapshots.take()) is not None:
                pose_mirror(model, data, *snap)
                renderer.update_scene(data, camera=cam, scene_option=opt)
                rgb = renderer.render()
                ok, buf = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), params)
                self.bridge._frame_ready(buf.tobytes() if ok else None, None if ok else "JPEG encoding failed")
        except Exception as exc:
            self.error = f"render thread failed: {type(exc).__name__}: {exc}"
            self.bridge.node.log.error(self.error)
            self.bridge._frame_ready(None, self.error)
        finally:
            renderer.close()
