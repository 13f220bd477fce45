"""Model-based trot controller (torque output) for the simulated Go2.

* Gait scheduler: diagonal trot (FR+RL / FL+RR), fixed period and duty.
* Stance legs: a single-rigid-body balance controller computes the desired
  net wrench (PD on position/height/attitude, velocity tracking via a
  reference that integrates the command), a QP distributes it to the stance
  feet and the forces become joint torques through tau = -J^T R^T f.
* Swing legs: Raibert foot placement, minimum-jerk + lift swing trajectory,
  Cartesian PD (tau = J^T F) plus gravity feed-forward.
Everything works on torques; MuJoCo integrates the dynamics.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from go2vlm.sim import legs
from go2vlm.sim.force_qp import ForceQP
from go2vlm.sim.go2_model import FOOT_RADIUS, HIP_OFFSETS, LEG_SIDE, STAND_HEIGHT, THIGH_OFFSET, TORQUE_LIMITS

GRAVITY = 9.81
TROT_OFFSETS = np.array([0.0, 0.5, 0.5, 0.0])  # FR, FL, RR, RL


@dataclass
class GaitParams:
    period: float = 0.36  # trot period up to 1 m/s
    period_fast: float = 0.28  # period at 2 m/s and above (shorter steps reach higher speeds)
    duty: float = 0.5
    body_height: float = STAND_HEIGHT - 0.01
    swing_height: float = 0.08
    kp_xy: float = 40.0  # 1/s^2, on the integrated position reference
    kd_xy: float = 10.0  # 1/s
    ki_xy: float = 40.0  # 1/s^3, heading-frame integral: removes the steady lag on curves
    max_integral: float = 0.03  # m*s
    kp_z: float = 120.0
    kd_z: float = 18.0
    kp_rot: tuple[float, float, float] = (250.0, 250.0, 120.0)
    kd_rot: tuple[float, float, float] = (25.0, 25.0, 20.0)
    max_pos_err: float = 0.12
    max_yaw_err: float = 0.3
    k_raibert: float = 0.06
    kp_swing: tuple[float, float, float] = (800.0, 800.0, 800.0)
    kd_swing: tuple[float, float, float] = (25.0, 25.0, 25.0)
    mu: float = 0.6
    stop_delay: float = 0.3
    max_lin_acc: float = 2.0  # m/s^2, command slew limit (smooth starts and stops)
    max_yaw_acc: float = 4.0  # rad/s^2


@dataclass
class RobotInput:
    """What the controller reads each tick (all from the simulator state)."""

    t: float
    q: np.ndarray  # (12,)
    dq: np.ndarray  # (12,)
    pos: np.ndarray  # base origin, world
    rot: np.ndarray  # base rotation matrix, body -> world
    vel: np.ndarray  # base linear velocity, world
    omega_body: np.ndarray  # base angular velocity, body frame
    com: np.ndarray  # whole-robot CoM, world
    bias: np.ndarray = field(default_factory=lambda: np.zeros(12))  # gravity+Coriolis joint torques


def _yaw_of(rot: np.ndarray) -> float:
    return float(np.arctan2(rot[1, 0], rot[0, 0]))


def _rz(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    # np.cross costs ~40 us per call; this runs every tick
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _wrap(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


class TrotController:
    """Stand (all feet loaded) or trot; call :meth:`compute` once per control tick."""

    def __init__(self, mass: float, inertia: np.ndarray, dt: float, params: GaitParams | None = None) -> None:
        self.p = params or GaitParams()
        self.mass, self.inertia, self.dt = mass, inertia, dt
        self.qp = ForceQP(mu=self.p.mu)
        self.cmd = np.zeros(3)  # slew-limited command actually tracked
        self.target_cmd = np.zeros(3)
        self.walking = False
        self.phase = 0.0
        self.period = self.p.period
        self.stance = np.ones(4, dtype=bool)
        self.swing_start = np.zeros((4, 3))
        self.pos_ref = np.zeros(2)
        self.pos_integral = np.zeros(2)  # heading frame
        self.yaw_ref = 0.0
        self._idle_time = 0.0
        self._initialised = False
        self.last_forces = np.zeros((4, 3))
        # nominal foot xy under each thigh (base frame)
        self.nominal = HIP_OFFSETS[:, :2] + np.stack([np.zeros(4), LEG_SIDE * THIGH_OFFSET], axis=1)

    def reset(self, x: RobotInput) -> None:
        self.pos_ref = x.pos[:2].copy()
        self.pos_integral = np.zeros(2)
        self.yaw_ref = _yaw_of(x.rot)
        self.walking = False
        self.phase = 0.0
        self.stance[:] = True
        self._idle_time = 0.0
        self.cmd = np.zeros(3)
        self._initialised = True

    def set_command(self, vx: float, vy: float, vyaw: float) -> None:
        self.target_cmd = np.array([vx, vy, vyaw], dtype=float)

    def _slew_command(self) -> None:
        step = self.dt * np.array([self.p.max_lin_acc, self.p.max_lin_acc, self.p.max_yaw_acc])
        self.cmd += np.clip(self.target_cmd - self.cmd, -step, step)

    # ---------------------------------------------------------------- gait
    def _update_gait(self, x: RobotInput) -> np.ndarray:
        """Advance the phase; returns the per-leg phase in [0, 1)."""
        moving = bool(np.any(np.abs(self.cmd) > 1e-3) or np.any(self.target_cmd != 0))
        # A push while standing: start stepping (Raibert placement catches the body).
        disturbed = np.linalg.norm(x.vel[:2]) > 0.25 or np.linalg.norm(x.omega_body[:2]) > 1.0
        if not self.walking:
            if moving or disturbed:
                self.walking, self.phase, self._idle_time = True, 0.0, 0.0
            return np.zeros(4)
        settled = np.linalg.norm(x.vel[:2]) < 0.15 and not disturbed
        self._idle_time = 0.0 if (moving or not settled) else self._idle_time + self.dt
        old = self.phase
        self.period = float(
            np.interp(np.hypot(self.cmd[0], self.cmd[1]), [1.0, 2.0], [self.p.period, self.p.period_fast])
        )
        self.phase = (self.phase + self.dt / self.period) % 1.0
        crossed = (old < self.p.duty <= self.phase) or (self.phase < old)
        if crossed and self._idle_time > self.p.stop_delay:
            self.walking = False  # all feet are at a touchdown: stand on four
            return np.zeros(4)
        return (self.phase + TROT_OFFSETS) % 1.0

    # ------------------------------------------------------------- control
    def compute(self, x: RobotInput) -> np.ndarray:
        if not self._initialised:
            self.reset(x)
        p = self.p
        self._slew_command()
        leg_phase = self._update_gait(x)
        new_stance = leg_phase < p.duty if self.walking else np.ones(4, dtype=bool)
        q = x.q.reshape(4, 3)
        dq = x.dq.reshape(4, 3)
        rot = x.rot
        foot_b = legs.foot_positions(q)
        jac = legs.jacobians(q)
        foot_w = x.pos + foot_b @ rot.T
        lifted = self.stance & ~new_stance
        self.swing_start[lifted] = foot_w[lifted]
        self.stance = new_stance

        yaw = _yaw_of(rot)
        rz = _rz(yaw)
        v_des = rz @ np.array([self.cmd[0], self.cmd[1], 0.0])
        omega_w = rot @ x.omega_body

        # References integrate the command; clamped so a push does not wind up.
        self.pos_ref += v_des[:2] * self.dt
        err = self.pos_ref - x.pos[:2]
        n = np.linalg.norm(err)
        if n > p.max_pos_err:
            self.pos_ref = x.pos[:2] + err * (p.max_pos_err / n)
        self.yaw_ref = _wrap(self.yaw_ref + self.cmd[2] * self.dt)
        yaw_err = _wrap(self.yaw_ref - yaw)
        if abs(yaw_err) > p.max_yaw_err:
            self.yaw_ref = _wrap(yaw + np.sign(yaw_err) * p.max_yaw_err)

        tau = np.zeros((4, 3))
        tau[self.stance] = self._stance_torques(x, rot, rz, v_des, omega_w, foot_w, jac)[self.stance]
        if not np.all(self.stance):
            sw = self._swing_torques(x, rot, v_des, foot_b, jac, dq, leg_phase)
            tau[~self.stance] = sw[~self.stance]
        return np.clip(tau.ravel(), -TORQUE_LIMITS, TORQUE_LIMITS)

    def _stance_torques(
        self,
        x: RobotInput,
        rot: np.ndarray,
        rz: np.ndarray,
        v_des: np.ndarray,
        omega_w: np.ndarray,
        foot_w: np.ndarray,
        jac: np.ndarray,
    ) -> np.ndarray:
        p = self.p
        acc = np.empty(3)
        err = self.pos_ref - x.pos[:2]
        if self.walking:
            err_h = rz[:2, :2].T @ err
            self.pos_integral = np.clip(self.pos_integral + err_h * self.dt, -p.max_integral, p.max_integral)
        else:  # standing: let the walking integral fade instead of pushing the body
            self.pos_integral *= 1.0 - self.dt / 0.3
        acc[:2] = p.kp_xy * err + p.kd_xy * (v_des[:2] - x.vel[:2]) + p.ki_xy * (rz[:2, :2] @ self.pos_integral)
        acc[2] = p.kp_z * (p.body_height - x.pos[2]) + p.kd_z * (0.0 - x.vel[2])
        acc[:2] += self.cmd[2] * np.array([-v_des[1], v_des[0]])  # centripetal feed-forward on curves
        force = self.mass * (acc + np.array([0.0, 0.0, GRAVITY]))

        r_des = _rz(self.yaw_ref)
        r_err = r_des @ rot.T
        e_w = 0.5 * np.array([r_err[2, 1] - r_err[1, 2], r_err[0, 2] - r_err[2, 0], r_err[1, 0] - r_err[0, 1]])
        de_w = np.array([0.0, 0.0, self.cmd[2]]) - omega_w
        # gains act in the heading frame (roll/pitch/yaw axes of the robot)
        alpha_h = np.array(p.kp_rot) * (rz.T @ e_w) + np.array(p.kd_rot) * (rz.T @ de_w)
        alpha_w = rz @ alpha_h
        i_w = rot @ self.inertia @ rot.T
        torque = i_w @ alpha_w + _cross(omega_w, i_w @ omega_w)

        f = self.qp.solve(foot_w - x.com, self.stance, np.concatenate([force, torque]))
        self.last_forces = f
        f_b = -(f @ rot)  # force the foot applies on the ground, base frame
        return np.einsum("lij,li->lj", jac, f_b)

    def _swing_torques(
        self,
        x: RobotInput,
        rot: np.ndarray,
        v_des: np.ndarray,
        foot_b: np.ndarray,
        jac: np.ndarray,
        dq: np.ndarray,
        leg_phase: np.ndarray,
    ) -> np.ndarray:
        """Swing-leg torques for all four legs (callers use the swing rows only)."""
        p = self.p
        t_swing = (1.0 - p.duty) * self.period
        t_stance = p.duty * self.period
        s = np.clip((leg_phase - p.duty) / (1.0 - p.duty), 0.0, 1.0)[:, None]
        t_rem = (1.0 - s[:, 0]) * t_swing
        vel_xy = x.vel[:2]
        # Raibert: hip location at touchdown + half the stance sweep + velocity-error feedback.
        yaw_td = _yaw_of(rot) + self.cmd[2] * (t_rem + 0.5 * t_stance)
        c, sn = np.cos(yaw_td), np.sin(yaw_td)
        nx, ny = self.nominal[:, 0], self.nominal[:, 1]
        target = x.pos[:2] + np.outer(t_rem, v_des[:2]) + np.stack([c * nx - sn * ny, sn * nx + c * ny], axis=1)
        target += 0.5 * t_stance * vel_xy + p.k_raibert * (vel_xy - v_des[:2])
        # lean the feet out on curves so the ground force supplies the centripetal force
        target += (p.body_height / GRAVITY) * self.cmd[2] * np.array([vel_xy[1], -vel_xy[0]])
        start = self.swing_start
        b = s**3 * (10 - 15 * s + 6 * s**2)
        db = 30 * s**2 * (1 - s) ** 2 / t_swing
        lift = 64 * s**3 * (1 - s) ** 3
        dlift = 192 * s**2 * (1 - s) ** 2 * (1 - 2 * s) / t_swing
        z_end = FOOT_RADIUS - 0.01  # aim slightly below ground for a firm touchdown
        delta = np.concatenate([target - start[:, :2], (z_end - start[:, 2:3])], axis=1)
        des_w = start + delta * b
        des_w[:, 2:3] += p.swing_height * lift
        vdes_w = delta * db
        vdes_w[:, 2:3] += p.swing_height * dlift
        des_b = (des_w - x.pos) @ rot
        w = x.omega_body
        w_cross_p = np.stack(
            [
                w[1] * foot_b[:, 2] - w[2] * foot_b[:, 1],
                w[2] * foot_b[:, 0] - w[0] * foot_b[:, 2],
                w[0] * foot_b[:, 1] - w[1] * foot_b[:, 0],
            ],
            axis=1,
        )
        vrel_b = (vdes_w - x.vel) @ rot - w_cross_p
        v_b = np.einsum("lij,lj->li", jac, dq)
        force = np.array(p.kp_swing) * (des_b - foot_b) + np.array(p.kd_swing) * (vrel_b - v_b)
        return np.einsum("lij,li->lj", jac, force) + x.bias.reshape(4, 3)


@dataclass
class JointTrajectory:
    """Joint-space PD towards a target, with a smooth (cosine) blend over ``duration``."""

    q_start: np.ndarray
    q_goal: np.ndarray
    t_start: float
    duration: float
    kp: float = 60.0
    kd: float = 3.0
    hold: float = 0.0  # extra time at the goal before done()

    def torques(self, t: float, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        s = np.clip((t - self.t_start) / self.duration, 0.0, 1.0)
        w = 0.5 - 0.5 * np.cos(np.pi * s)
        q_ref = self.q_start + (self.q_goal - self.q_start) * w
        tau = self.kp * (q_ref - q) - self.kd * dq
        return np.clip(tau, -TORQUE_LIMITS, TORQUE_LIMITS)

    def done(self, t: float) -> bool:
        return t >= self.t_start + self.duration + self.hold
