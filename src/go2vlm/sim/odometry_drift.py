"""Leg-odometry drift: what a Go2 believes of its own pose, from the truth the simulator knows.

A real Go2 reports its pose (rt/sportmodestate `position` and IMU yaw, hence /odom) from leg
kinematics and its IMU, and that estimate drifts with the distance walked. `OdometryDrift` turns
the simulator's true planar poses, in time order, into such an estimate: each step's true motion,
taken in the robot's own frame, is replayed from the estimated pose with

- a scale error `scale` on the distance (a stride misjudged by a fixed fraction),
- a heading bias `heading_deg_per_m` (degrees of yaw gained per metre walked: the error that
  bends a straight walk and grows the position error with the square of the distance),
- random walks on the position (`walk_m_per_sqrt_m`) and the heading (`yaw_walk_deg_per_sqrt_m`)
  whose variance grows in proportion to the distance (so the same walk sampled at 25 or 50 Hz drifts
  alike).

Standing or turning on the spot adds nothing: drift accrues with distance walked. `gain` scales
all four (0: the truth, exactly; 1: the size below). Each sign and every random step are drawn from
the seed: one seed, one drift, whatever else runs.

The size (`GO2_LEG_ODOMETRY`, gain 1): the Unitree Go2's proprioceptive odometry closes a ~120 m
horizontal loop with 2.21 m of error, 1.8 % of the distance, with a research estimator
(M. Sun and Y. Mao, "Contact-Anchored Proprioceptive Odometry for Quadruped Robots",
arXiv:2602.17393, 2026, on a Go2 EDU); users of the Go2's own odometry report more
(github.com/dfl-rlab/dddmr_navigation issue 75: "very inaccurate and drifts heavily";
github.com/andy-zhuo-02/go2_ros2_toolbox issue 25: the heading drifts, the position less). We take
a 1.5 % scale error and 0.03 deg/m of heading bias: on a 100 m straight walk 1.5 m along the path
and about 2.6 m across it (0.03 deg/m x 100 m^2 / 2), about 3 % of the distance in all, between the
research figure and what the Go2's own estimate is reported to do.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from go2vlm.sim.state import RobotState

__all__ = ["GO2_LEG_ODOMETRY", "DriftSpec", "OdometryDrift"]


@dataclasses.dataclass(frozen=True)
class DriftSpec:
    """The size of the drift at gain 1 (see the module docstring for where it comes from)."""

    scale: float = 0.015  # fraction of the distance walked
    heading_deg_per_m: float = 0.03  # yaw bias per metre walked
    walk_m_per_sqrt_m: float = 0.01  # position random walk: sigma after 1 m
    yaw_walk_deg_per_sqrt_m: float = 0.1  # heading random walk: sigma after 1 m


GO2_LEG_ODOMETRY = DriftSpec()


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


class OdometryDrift:
    """The drifting estimate of a planar pose. Feed it the true pose (x, y, yaw) in time order with
    `update`; it returns the estimate, which starts at the first true pose."""

    def __init__(self, gain: float = 0.0, seed: int = 0, spec: DriftSpec = GO2_LEG_ODOMETRY) -> None:
        if not (math.isfinite(gain) and gain >= 0):
            raise ValueError(f"odometry drift gain must be finite and >= 0, got {gain}")
        self.gain = gain
        self._rng = np.random.default_rng([int(seed) % 2**32, 4171])
        signs = self._rng.choice((-1.0, 1.0), size=2)
        self.scale = gain * spec.scale * float(signs[0])
        self.heading_rad_per_m = gain * math.radians(spec.heading_deg_per_m) * float(signs[1])
        self._walk = gain * spec.walk_m_per_sqrt_m
        self._yaw_walk = gain * math.radians(spec.yaw_walk_deg_per_sqrt_m)
        self._true: tuple[float, float, float] | None = None
        self._est: tuple[float, float, float] | None = None
        self.distance_m = 0.0  # true distance walked so far
        self._last: RobotState | None = None

    @property
    def enabled(self) -> bool:
        return self.gain > 0

    def update(self, x: float, y: float, yaw: float) -> tuple[float, float, float]:
        """The estimate at this true pose (the truth itself at gain 0)."""
        if self.gain == 0:
            return x, y, yaw
        if self._true is None or self._est is None:
            self._true = self._est = (x, y, _wrap(yaw))
            return self._est
        tx, ty, tyaw = self._true
        c, s = math.cos(tyaw), math.sin(tyaw)
        fwd, left = c * (x - tx) + s * (y - ty), -s * (x - tx) + c * (y - ty)  # the step in the robot's frame
        turn = _wrap(yaw - tyaw)
        d = math.hypot(fwd, left)
        ex, ey, eyaw = self._est
        n = self._rng.standard_normal(3) * math.sqrt(d)  # drawn every step: one seed, one sequence
        k = 1.0 + self.scale
        ce, se = math.cos(eyaw), math.sin(eyaw)  # the step replayed from the estimated pose
        fwd, left = k * fwd + self._walk * n[0], k * left + self._walk * n[1]  # errors in the robot's frame
        ex += ce * fwd - se * left
        ey += se * fwd + ce * left
        eyaw += self.heading_rad_per_m * d + self._yaw_walk * n[2]
        self.distance_m += d
        eyaw = _wrap(eyaw + turn)
        self._true, self._est = (x, y, _wrap(yaw)), (ex, ey, eyaw)
        return self._est

    def reported(self, state: RobotState) -> RobotState:
        """The state as the robot's odometry reports it: the base's planar pose and heading (position,
        quaternion, the IMU's yaw) drifted, its linear velocity scaled by the scale error; height, roll,
        pitch, the gyro and the accelerometer as they are. The same state at gain 0."""
        if self.gain == 0:
            return state
        if self._last is not None and self._last.time == state.time:
            return self._last  # one instant, one answer (the /odom and the Unitree state of one step agree)
        w, qx, qy, qz = (float(v) for v in state.quaternion)
        yaw = math.atan2(2 * (w * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
        x, y, eyaw = self.update(float(state.position[0]), float(state.position[1]), yaw)
        half = _wrap(eyaw - yaw) / 2  # turn the true attitude about the world's z by the heading error
        cz, sz = math.cos(half), math.sin(half)
        quat = np.array([cz * w - sz * qz, cz * qx - sz * qy, cz * qy + sz * qx, cz * qz + sz * w])
        cd, sd = math.cos(2 * half), math.sin(2 * half)
        k = 1.0 + self.scale
        vw = state.lin_vel_world
        rpy = state.imu_rpy.copy()
        rpy[2] = eyaw
        self._last = dataclasses.replace(
            state,
            position=np.array([x, y, float(state.position[2])]),
            quaternion=quat,
            lin_vel_body=state.lin_vel_body * k,
            lin_vel_world=np.array([k * (cd * vw[0] - sd * vw[1]), k * (sd * vw[0] + cd * vw[1]), k * vw[2]]),
            imu_rpy=rpy,
        )
        return self._last
