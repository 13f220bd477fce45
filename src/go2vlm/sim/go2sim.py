"""``Go2Sim``: one MuJoCo world with our Go2, a controller, cameras and a ball."""

from __future__ import annotations

import mujoco
import numpy as np

from go2vlm.geometry.camera import PinholeCamera
from go2vlm.geometry.rotations import mat_to_rpy, quat_to_mat, tilt_angle, yaw_quat
from go2vlm.robot_profile.go2 import GO2
from go2vlm.sim import go2_model as gm
from go2vlm.sim import legs
from go2vlm.sim.ball import BallPath
from go2vlm.sim.config import SimConfig
from go2vlm.sim.controller import JointTrajectory, RobotInput, TrotController
from go2vlm.sim.gl import RenderingUnavailable, patch_late_import
from go2vlm.sim.kinematic_gait import KinematicGait
from go2vlm.sim.render import camera_scene_option, render_segmentation
from go2vlm.sim.state import Pose, RobotState
from go2vlm.sim.worlds import build_world_xml

RECOVERY_ATTEMPTS = 4
MODES = ("lying", "standing_up", "standing", "walking", "lying_down", "damped", "fallen", "recovering")


class Go2Sim:
    """Simulated Go2.  Not thread-safe; render from the thread that created the renderer."""

    def __init__(self, config: SimConfig | None = None) -> None:
        self.config = cfg = config or SimConfig()
        if cfg.mode not in ("dynamic", "kinematic"):
            raise ValueError(f"mode must be 'dynamic' or 'kinematic', got {cfg.mode!r}")
        off = (
            max(1920, cfg.camera_width, cfg.world_camera_width),
            max(1080, cfg.camera_height, cfg.world_camera_height),
        )
        xml, self.world_info = build_world_xml(cfg.world, cfg.spawn, off, seed=cfg.seed)
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.model.opt.timestep = cfg.timestep
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._base_id = m.body("base").id
        self._head_cam = m.camera("head_camera").id
        m.cam_fovy[self._head_cam] = cfg.camera_fovy_deg
        self._world_cam = m.camera("world_camera").id if "world_camera" in _names(m, mujoco.mjtObj.mjOBJ_CAMERA) else -1
        self._qadr = np.array([m.jnt_qposadr[m.joint(n).id] for n in gm.JOINT_NAMES])
        self._vadr = np.array([m.jnt_dofadr[m.joint(n).id] for n in gm.JOINT_NAMES])
        self._foot_geoms = np.array([m.geom(g).id for g in gm.FOOT_GEOMS])
        self._robot_bodies = {int(b) for b in np.flatnonzero(m.body_rootid == self._base_id)}
        self._gyro = m.sensor("imu_gyro").adr[0]
        self._acc = m.sensor("imu_acc").adr[0]

        self._ball_mocap = -1
        self.ball: BallPath | None = None
        if "red_ball" in _names(m, mujoco.mjtObj.mjOBJ_BODY) and m.body("red_ball").mocapid[0] >= 0:
            self._ball_mocap = int(m.body("red_ball").mocapid[0])
            info = self.world_info
            if info.ball_path is not None:
                kind = cfg.ball_path or info.ball_path_type or "ellipse"
                self.ball = BallPath(kind, info.ball_path, cfg.ball_speed, info.ball_radius)

        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._head_opt = camera_scene_option(hide_robot=True)  # robot visuals invisible to its own head camera
        self._world_opt = camera_scene_option(hide_robot=False)
        self.reset()

    # ------------------------------------------------------------------ setup
    def reset(self) -> None:
        cfg, m, d = self.config, self.model, self.data
        mujoco.mj_resetData(m, d)
        x, y, yaw = self.world_info.spawn
        q0 = gm.STAND_Q if cfg.start_standing else gm.LIE_Q
        rng = np.random.default_rng(cfg.seed)
        d.qpos[self._qadr] = q0 + rng.uniform(-1, 1, 12) * cfg.init_noise
        # Spawn with the lowest foot just touching the ground (no initial penetration).
        feet = legs.foot_positions(d.qpos[self._qadr].reshape(4, 3))
        z0 = gm.FOOT_RADIUS - float(np.min(feet[:, 2])) + 0.002
        d.qpos[0:3] = (x, y, z0 if cfg.start_standing else gm.LIE_HEIGHT)
        d.qpos[3:7] = yaw_quat(yaw)
        self._ball_s = 0.0
        if self.ball is not None:
            self.ball.speed = cfg.ball_speed
        self._update_ball()
        mujoco.mj_forward(m, d)
        self._cmd = np.zeros(3)
        self._mode = "standing" if cfg.start_standing else "lying"
        self.fell = False
        self._traj: JointTrajectory | None = None
        self._after_traj: str = "standing"
        self._recovery_attempts = 0
        self._tau = np.zeros(12)
        self._step_count = 0
        self.controller = TrotController(
            gm.TOTAL_MASS, self._composite_inertia(), cfg.timestep * cfg.control_decimation, cfg.gait
        )
        self._kin = KinematicGait(cfg.gait.period, cfg.gait.duty)
        self._kin_height = gm.STAND_HEIGHT if cfg.start_standing else gm.LIE_HEIGHT
        self._kin_yaw = yaw
        self._kin_q = d.qpos[self._qadr].copy()
        self._kin_transition: tuple[float, float, np.ndarray, np.ndarray, float, float, str] | None = None
        if self._mode == "lying":
            self._hold_lying()

    def _composite_inertia(self) -> np.ndarray:
        """Whole-robot inertia about its CoM in the base frame, at the spawn posture."""
        m, d = self.model, self.data
        bodies = sorted(self._robot_bodies)
        com = d.subtree_com[self._base_id]
        rot = d.xmat[self._base_id].reshape(3, 3)
        inertia = np.zeros((3, 3))
        for b in bodies:
            rb = d.ximat[b].reshape(3, 3)
            inertia += rb @ np.diag(m.body_inertia[b]) @ rb.T
            r = d.xipos[b] - com
            inertia += m.body_mass[b] * (r @ r * np.eye(3) - np.outer(r, r))
        return rot.T @ inertia @ rot

    # --------------------------------------------------------------- commands
    @property
    def mode(self) -> str:
        if self._mode == "standing" and self.config.mode == "dynamic" and self.controller.walking:
            return "walking"
        if self._mode == "standing" and self.config.mode == "kinematic" and np.any(self._cmd != 0):
            return "walking"
        return self._mode

    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def dt(self) -> float:
        return float(self.model.opt.timestep)

    def set_command(self, vx: float, vy: float, vyaw: float) -> np.ndarray:
        """Velocity command in the heading frame, clamped to the Go2 sport-mode limits."""
        self._cmd = np.array(GO2.ceilings.clamp(vx, vy, vyaw), dtype=float)
        self.controller.set_command(*self._cmd)
        return self._cmd.copy()

    def stop(self) -> None:
        self.set_command(0.0, 0.0, 0.0)

    def stand_up(self, duration: float = 1.2) -> None:
        """From lying/damped: unfold to the standing posture, then balance (mode "standing").

        Ignored while fallen: use :meth:`recovery_stand`, which also rolls the robot over.
        """
        if self._mode in ("standing", "standing_up", "fallen"):
            return
        self._start_transition(gm.STAND_Q, gm.STAND_HEIGHT, duration, "standing_up", "standing")

    def lie_down(self, duration: float = 1.5) -> None:
        """Stop and fold the legs until the belly rests on the ground (mode "lying")."""
        if self._mode in ("lying", "lying_down", "fallen"):
            return
        self.stop()
        self._start_transition(gm.LIE_Q, gm.LIE_HEIGHT, duration, "lying_down", "lying")

    def damp(self) -> None:
        """Passive mode: joints only damped (the robot sinks down)."""
        self.stop()
        if self.config.mode == "kinematic":  # animate the sinking
            self._start_transition(gm.LIE_Q, gm.LIE_HEIGHT, 0.6, "damped", "damped")
        self._traj = None
        self._mode = "damped"

    def recovery_stand(self) -> bool:
        """Get up from wherever the robot lies: fold the legs, roll onto the belly if needed, stand.

        From the side or back the legs rotate past the trunk (thighs ~3.3 rad) and
        push the ground to roll it over; up to ``RECOVERY_ATTEMPTS`` tries.  Returns
        False if already standing/walking (nothing to do), True once started.
        """
        if self._mode in ("standing", "standing_up"):
            return False
        self.stop()
        self._recovery_attempts = 0
        self._start_transition(gm.LIE_Q, gm.LIE_HEIGHT, 0.4, "recovering", "recover_check", hold=0.2)
        return True

    def push(self, dv_world: tuple[float, float, float], dw_body: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        """Instantaneous velocity kick on the base (disturbance tests)."""
        self.data.qvel[0:3] += dv_world
        self.data.qvel[3:6] += dw_body

    def _start_transition(
        self, q_goal: np.ndarray, height: float, duration: float, mode: str, after: str, hold: float = 0.0
    ) -> None:
        q = self.data.qpos[self._qadr].copy()
        self._mode, self._after_traj = mode, after
        self._traj = JointTrajectory(q, q_goal.copy(), self.time, duration, kp=120.0, kd=4.0, hold=hold)
        self._kin_transition = (self.time, duration, q, q_goal.copy(), self._kin_height, height, after)

    def _hold_lying(self) -> None:
        q = self.data.qpos[self._qadr].copy()
        self._traj = JointTrajectory(q, gm.LIE_Q.copy(), self.time, 0.5, kp=40.0, kd=2.0)

    # ------------------------------------------------------------- stepping
    def step(self, n: int = 1) -> None:
        for _ in range(n):
            if self.config.mode == "dynamic":
                self._dynamic_step()
            else:
                self._kinematic_step()

    def advance(self, dt_s: float) -> None:
        self.step(max(0, int(round(dt_s / self.dt))))

    def _update_ball(self, dt: float = 0.0) -> None:
        if self.ball is not None and self._ball_mocap >= 0:
            # integrate arc length so the speed can change at run time without jumps
            self._ball_s += self.ball.speed * dt
            self.data.mocap_pos[self._ball_mocap] = self.ball.at(self._ball_s)

    def set_ball_speed(self, speed: float) -> None:
        """Ball speed along its path in m/s (0 stops it, negative reverses)."""
        if self.ball is not None:
            self.ball.speed = float(speed)

    def _rot(self) -> np.ndarray:
        return self.data.xmat[self._base_id].reshape(3, 3).copy()

    def _robot_input(self) -> RobotInput:
        d = self.data
        return RobotInput(
            t=float(d.time),
            q=d.qpos[self._qadr].copy(),
            dq=d.qvel[self._vadr].copy(),
            pos=d.qpos[0:3].copy(),
            rot=quat_to_mat(d.qpos[3:7]),
            vel=d.qvel[0:3].copy(),
            omega_body=d.qvel[3:6].copy(),
            com=d.subtree_com[self._base_id].copy(),
            bias=d.qfrc_bias[self._vadr].copy(),
        )

    def _dynamic_step(self) -> None:
        d = self.data
        if self._step_count % self.config.control_decimation == 0:
            self._tau = self._control()
        d.ctrl[:] = self._tau
        self._update_ball(self.dt)
        mujoco.mj_step(self.model, d)
        self._step_count += 1

    def _control(self) -> np.ndarray:
        x = self._robot_input()
        t = x.t
        if self._mode in ("standing", "standing_up", "walking") and self._check_fall(x):
            self._mode, self.fell, self._traj = "fallen", True, None
            self.controller.walking = False
        if self._mode == "standing":
            return self.controller.compute(x)
        if self._mode in ("damped", "fallen"):
            return np.clip(-1.5 * x.dq, -gm.TORQUE_LIMITS, gm.TORQUE_LIMITS)
        assert self._traj is not None
        tau = self._traj.torques(t, x.q, x.dq)
        if self._traj.done(t) and self._mode != "lying":
            self._finish_transition(x)
        return tau

    def _finish_transition(self, x: RobotInput) -> None:
        after = self._after_traj
        if after == "standing":
            self._mode, self._traj, self.fell = "standing", None, False
            self.controller.reset(x)
        elif after == "lying":
            self._mode = "lying"
            self._hold_lying()
        elif after == "recover_check":
            tilt = tilt_angle(x.rot)
            roll = float(np.arctan2(x.rot[2, 1], x.rot[2, 2]))
            if abs(roll) < 0.6 and tilt < 1.0:  # on the belly (a pitch settles while standing up)
                self._mode = "lying"
                self.stand_up()
            elif self._recovery_attempts >= RECOVERY_ATTEMPTS:
                self._mode, self._traj, self.fell = "fallen", None, True
            else:
                self._recovery_attempts += 1
                # On the back any direction works; on a side, push towards the raised side.
                side = 1.0 if tilt > 2.0 else float(np.sign(roll) or 1.0)
                q_roll = np.tile([0.9 * side, 3.3, -0.9], 4)
                self._start_transition(q_roll, gm.LIE_HEIGHT, 0.6, "recovering", "recover_fold", hold=0.3)
        elif after == "recover_fold":
            self._start_transition(gm.LIE_Q, gm.LIE_HEIGHT, 0.6, "recovering", "recover_check", hold=0.4)

    def _check_fall(self, x: RobotInput) -> bool:
        low = x.pos[2] < self.config.fall_height and self._mode != "standing_up"
        return tilt_angle(x.rot) > self.config.fall_tilt or low

    def _kinematic_step(self) -> None:
        m, d, dt = self.model, self.data, self.dt
        t = d.time + dt
        q_prev = d.qpos[self._qadr].copy()
        moving = self._mode == "standing" and bool(np.any(self._cmd != 0))
        vel_w = np.zeros(3)
        if self._kin_transition is not None and self._mode in ("standing_up", "lying_down", "recovering", "damped"):
            t0, dur, qa, qb, ha, hb, after = self._kin_transition
            s = min(1.0, (t - t0) / dur)
            w = 0.5 - 0.5 * np.cos(np.pi * s)
            self._kin_q = qa + (qb - qa) * w
            self._kin_height = ha + (hb - ha) * w
            if s >= 1.0:
                self._kin_transition = None
                self._mode = {"recover_check": "lying"}.get(after, after)
                if after == "recover_check":  # kinematic robot is always upright
                    self.stand_up()
        elif self._mode == "standing":
            c, s_ = np.cos(self._kin_yaw), np.sin(self._kin_yaw)
            vel_w = np.array([c * self._cmd[0] - s_ * self._cmd[1], s_ * self._cmd[0] + c * self._cmd[1], 0.0])
            d.qpos[0:2] += vel_w[:2] * dt
            self._kin_yaw += self._cmd[2] * dt
            self._kin.step(dt, self._cmd, moving)
            self._kin_q = self._kin.joint_positions(self._cmd, self._kin_height, moving)
        self.fell = False
        d.qpos[2] = self._kin_height
        d.qpos[3:7] = yaw_quat(self._kin_yaw)
        d.qpos[self._qadr] = self._kin_q
        d.qvel[:] = 0.0
        d.qvel[0:3] = vel_w
        d.qvel[5] = self._cmd[2] if self._mode == "standing" else 0.0
        d.qvel[self._vadr] = (self._kin_q - q_prev) / dt
        d.time = t
        self._update_ball(dt)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_camlight(m, d)  # cameras follow the base; mj_step does this in dynamic mode
        self._step_count += 1

    # ----------------------------------------------------------------- output
    def state(self) -> RobotState:
        d = self.data
        rot = self._rot()
        lin_w = d.qvel[0:3].copy()
        omega_b = d.qvel[3:6].copy()
        if self.config.mode == "kinematic":
            gyro, acc = omega_b.copy(), rot.T @ np.array([0.0, 0.0, 9.81])
            tau = np.zeros(12)
        else:
            gyro = d.sensordata[self._gyro : self._gyro + 3].copy()
            acc = d.sensordata[self._acc : self._acc + 3].copy()
            tau = d.actuator_force.copy()
        contact, force = self._foot_contacts()
        return RobotState(
            time=float(d.time),
            mode=self.mode,
            fell=self.fell,
            position=d.qpos[0:3].copy(),
            quaternion=d.qpos[3:7].copy(),
            lin_vel_world=lin_w,
            lin_vel_body=rot.T @ lin_w,
            ang_vel_body=omega_b,
            ang_vel_world=rot @ omega_b,
            imu_gyro=gyro,
            imu_acc=acc,
            imu_rpy=mat_to_rpy(rot),
            joint_names=gm.JOINT_NAMES,
            joint_pos=d.qpos[self._qadr].copy(),
            joint_vel=d.qvel[self._vadr].copy(),
            joint_torque=tau,
            foot_names=gm.LEG_NAMES,
            foot_contact=contact,
            foot_force=force,
            command=self._cmd.copy(),
        )

    def _foot_contacts(self) -> tuple[np.ndarray, np.ndarray]:
        d = self.data
        force = np.zeros(4)
        if self.config.mode == "kinematic":
            feet_z = d.geom_xpos[self._foot_geoms, 2]
            contact = feet_z < gm.FOOT_RADIUS + 0.005
            return contact, force
        wrench = np.zeros(6)
        for k in range(d.ncon):
            con = d.contact[k]
            for g in (con.geom1, con.geom2):
                hit = np.flatnonzero(self._foot_geoms == g)
                if hit.size:
                    mujoco.mj_contactForce(self.model, d, k, wrench)
                    force[hit[0]] += abs(wrench[0])
        return force > 1.0, force

    def object_poses(self) -> dict[str, Pose]:
        """Ground-truth poses: "go2" (base) and every named non-robot body."""
        m, d = self.model, self.data
        out = {"go2": Pose(d.xpos[self._base_id].copy(), d.xquat[self._base_id].copy())}
        for b in range(1, m.nbody):
            if b in self._robot_bodies:
                continue
            name = m.body(b).name
            if name:
                out[name] = Pose(d.xpos[b].copy(), d.xquat[b].copy())
        return out

    # -------------------------------------------------------------- cameras
    def head_intrinsics(self, width: int | None = None, height: int | None = None) -> PinholeCamera:
        w, h = width or self.config.camera_width, height or self.config.camera_height
        return PinholeCamera.from_fovy(w, h, self.config.camera_fovy_deg)

    def world_camera_intrinsics(self) -> PinholeCamera:
        fovy = float(self.model.cam_fovy[self._world_cam]) if self._world_cam >= 0 else 45.0
        return PinholeCamera.from_fovy(self.config.world_camera_width, self.config.world_camera_height, fovy)

    def head_camera_pose(self) -> Pose:
        """World pose of the head camera in the ROS optical convention (z forward, x right, y down)."""
        d = self.data
        r_mj = d.cam_xmat[self._head_cam].reshape(3, 3)  # MuJoCo camera: x right, y up, z backwards
        r_opt = r_mj @ np.diag([1.0, -1.0, -1.0])
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, r_opt.ravel())
        return Pose(d.cam_xpos[self._head_cam].copy(), quat)

    def project_to_head(
        self, points_world: np.ndarray, width: int | None = None, height: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (N, 2) of world points in the head image, and a mask of points in front."""
        k = self.head_intrinsics(width, height)
        pose = self.head_camera_pose()
        r_opt = np.zeros(9)
        mujoco.mju_quat2Mat(r_opt, pose.quaternion)
        pts = (np.atleast_2d(points_world) - pose.position) @ r_opt.reshape(3, 3)
        z = pts[:, 2]
        safe = np.where(z > 1e-6, z, 1.0)
        uv = np.stack([k.fx * pts[:, 0] / safe + k.cx, k.fy * pts[:, 1] / safe + k.cy], axis=1)
        return uv, z > 1e-6

    def _renderer(self, width: int, height: int) -> mujoco.Renderer:
        key = (width, height)
        if key not in self._renderers:
            patch_late_import()
            try:
                self._renderers[key] = mujoco.Renderer(self.model, height=height, width=width)
            except Exception as exc:  # noqa: BLE001 - any GL failure means "no rendering here"
                raise RenderingUnavailable(exc) from exc
        return self._renderers[key]

    def render_head(self, width: int | None = None, height: int | None = None) -> np.ndarray:
        """RGB (H, W, 3) uint8 from the head camera; the robot itself is not drawn."""
        w, h = width or self.config.camera_width, height or self.config.camera_height
        r = self._renderer(w, h)
        r.update_scene(self.data, camera=self._head_cam, scene_option=self._head_opt)
        return r.render().copy()

    def render_head_segmentation(self, width: int | None = None, height: int | None = None) -> np.ndarray:
        """(H, W) int32 geom ids seen by the head camera (-1: background)."""
        w, h = width or self.config.camera_width, height or self.config.camera_height
        return render_segmentation(self._renderer(w, h), self.data, self._head_cam, self._head_opt)

    def robot_geom_ids(self) -> np.ndarray:
        return np.flatnonzero(np.isin(self.model.geom_bodyid, sorted(self._robot_bodies)))

    def render_world_camera(self, width: int | None = None, height: int | None = None) -> np.ndarray:
        """RGB frame from the world's static "world_camera" (the VLM article's: 640x480)."""
        if self._world_cam < 0:
            raise ValueError(f"world {self.world_info.name!r} has no 'world_camera'")
        w, h = width or self.config.world_camera_width, height or self.config.world_camera_height
        r = self._renderer(w, h)
        r.update_scene(self.data, camera=self._world_cam, scene_option=self._world_opt)
        return r.render().copy()

    def close(self) -> None:
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()

    def __enter__(self) -> Go2Sim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _names(m: mujoco.MjModel, objtype: mujoco.mjtObj) -> set[str]:
    count = {mujoco.mjtObj.mjOBJ_BODY: m.nbody, mujoco.mjtObj.mjOBJ_CAMERA: m.ncam}[objtype]
    return {mujoco.mj_id2name(m, objtype, i) or "" for i in range(count)}
