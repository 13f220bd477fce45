"""The leg-odometry drift model (sim/odometry_drift.py), pure: no MuJoCo stepping, no DDS."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.sim.odometry_drift import GO2_LEG_ODOMETRY, OdometryDrift
from go2vlm.sim.state import RobotState

Path = list[tuple[float, float, float]]


def _walk(steps: list[tuple[float, float]], start: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Path:
    """True poses of a robot that walks `forward` metres then turns `turn` radians, step by step."""
    x, y, yaw = start
    out = [(x, y, yaw)]
    for fwd, turn in steps:
        x, y = x + fwd * math.cos(yaw), y + fwd * math.sin(yaw)
        yaw = math.atan2(math.sin(yaw + turn), math.cos(yaw + turn))
        out.append((x, y, yaw))
    return out


def _run(drift: OdometryDrift, path: Path) -> Path:
    return [drift.update(*p) for p in path]


steps_st = st.lists(st.tuples(st.floats(0, 0.05), st.floats(-0.2, 0.2)), min_size=1, max_size=200)
seed_st = st.integers(0, 2**31 - 1)


@settings(max_examples=60, deadline=None)
@given(steps_st, seed_st, st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-3.1, 3.1)))
def test_gain_zero_is_the_truth(steps: list[tuple[float, float]], seed: int, start: tuple[float, float, float]) -> None:
    path = _walk(steps, start)
    assert _run(OdometryDrift(0.0, seed), path) == path


@settings(max_examples=60, deadline=None)
@given(steps_st, seed_st, st.floats(0.1, 5))
def test_one_seed_one_drift(steps: list[tuple[float, float]], seed: int, gain: float) -> None:
    path = _walk(steps)
    assert _run(OdometryDrift(gain, seed), path) == _run(OdometryDrift(gain, seed), path)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-0.3, 0.3), min_size=1, max_size=100), seed_st, st.floats(0.1, 5))
def test_turning_on_the_spot_adds_no_drift(turns: list[float], seed: int, gain: float) -> None:
    path = _walk([(0.0, t) for t in turns], (1.0, 2.0, 0.5))
    for (x, y, yaw), (ex, ey, eyaw) in zip(path, _run(OdometryDrift(gain, seed), path), strict=True):
        assert (ex, ey) == (x, y) and math.isclose(eyaw, yaw, abs_tol=1e-9)


@settings(max_examples=40, deadline=None)
@given(steps_st, seed_st, st.floats(0.1, 3), st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-3.1, 3.1)))
def test_the_drift_is_the_same_wherever_the_walk_starts(
    steps: list[tuple[float, float]], seed: int, gain: float, start: tuple[float, float, float]
) -> None:
    """Drift is in the robot's own frame: a walk moved and turned in the world drifts the same way."""
    here, there = _walk(steps), _walk(steps, start)
    a, b = _run(OdometryDrift(gain, seed), here), _run(OdometryDrift(gain, seed), there)
    c, s = math.cos(start[2]), math.sin(start[2])
    for (ax, ay, ayaw), (bx, by, byaw) in zip(a, b, strict=True):
        assert math.isclose(start[0] + c * ax - s * ay, bx, abs_tol=1e-6)
        assert math.isclose(start[1] + s * ax + c * ay, by, abs_tol=1e-6)
        assert math.isclose(math.cos(ayaw + start[2]), math.cos(byaw), abs_tol=1e-6)
        assert math.isclose(math.sin(ayaw + start[2]), math.sin(byaw), abs_tol=1e-6)


def test_the_size_of_a_100_m_walk() -> None:
    """At gain 1 a 100 m straight walk ends a few percent of its length off: the cited Go2 size
    (1.5 % along, ~2.6 m across from the heading bias); twice the gain, about twice the error;
    sampled twice as often, about the same."""
    path = _walk([(0.02, 0.0)] * 5000)  # 100 m in 2 cm steps (0.5 m/s at 25 Hz)
    errors = []
    for seed in range(20):
        drift = OdometryDrift(1.0, seed)
        ex, ey, _ = _run(drift, path)[-1]
        errors.append(math.hypot(ex - 100.0, ey))
        assert math.isclose(drift.distance_m, 100.0, rel_tol=1e-9)
    assert 1.5 <= float(np.median(errors)) <= 5.0, errors
    fine = _walk([(0.01, 0.0)] * 10000)
    e_fine = [math.hypot(p[0] - 100, p[1]) for p in (_run(OdometryDrift(1.0, s), fine)[-1] for s in range(20))]
    assert float(np.median(e_fine)) == pytest.approx(float(np.median(errors)), rel=0.15)
    e2 = [math.hypot(p[0] - 100, p[1]) for p in (_run(OdometryDrift(2.0, s), path)[-1] for s in range(20))]
    assert float(np.median(e2)) == pytest.approx(2 * float(np.median(errors)), rel=0.2)
    assert GO2_LEG_ODOMETRY.scale == 0.015


def test_seeds_differ_and_bad_gains_are_refused() -> None:
    path = _walk([(0.05, 0.01)] * 100)
    ends = {_run(OdometryDrift(1.0, s), path)[-1] for s in range(5)}
    assert len(ends) == 5
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="gain"):
            OdometryDrift(bad)


def _state(x: float, y: float, yaw: float, v: float, t: float = 0.0) -> RobotState:
    z = np.zeros(3)
    q = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    return RobotState(
        time=t, mode="walking", fell=False, position=np.array([x, y, 0.3]), quaternion=q,
        lin_vel_world=np.array([v * math.cos(yaw), v * math.sin(yaw), 0.0]), lin_vel_body=np.array([v, 0.0, 0.0]),
        ang_vel_body=z, ang_vel_world=z, imu_gyro=z, imu_acc=np.array([0, 0, 9.81]), imu_rpy=np.array([0, 0, yaw]),
        joint_names=(), joint_pos=z, joint_vel=z, joint_torque=z, foot_names=(), foot_contact=z, foot_force=z,
        command=z,
    )  # fmt: skip


def test_a_reported_state_carries_the_drifted_pose_whole() -> None:
    """Position, quaternion, IMU yaw and velocities agree with one another; height and gyro are the truth."""
    drift = OdometryDrift(3.0, 7)
    assert OdometryDrift(0.0).reported(s := _state(1, 2, 0.3, 0.5)) is s
    for k in range(400):
        true = _state(0.05 * k * math.cos(0.3), 0.05 * k * math.sin(0.3), 0.3, 0.5, 0.1 * k)
        rep = drift.reported(true)
        assert drift.reported(true) is rep, "one instant, one answer"
    q = rep.quaternion
    yaw = math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2))
    assert math.isclose(yaw, rep.imu_rpy[2], abs_tol=1e-9) and not math.isclose(yaw, 0.3, abs_tol=1e-3)
    assert math.isclose(float(np.linalg.norm(q)), 1.0, abs_tol=1e-9)
    assert rep.position[2] == true.position[2] and rep.imu_gyro is true.imu_gyro
    k = 1 + drift.scale
    assert np.allclose(rep.lin_vel_body, [0.5 * k, 0, 0])
    assert np.allclose(rep.lin_vel_world[:2], [0.5 * k * math.cos(yaw), 0.5 * k * math.sin(yaw)])
    assert math.hypot(rep.position[0] - true.position[0], rep.position[1] - true.position[1]) > 0.05
