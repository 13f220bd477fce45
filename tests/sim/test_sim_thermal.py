"""The sim's motor temperature and battery models (sim/thermal.py) and its rt/lowstate
(robots/go2_sim/lowstate.py), pure: no MuJoCo, no DDS."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.robots.go2_sim.lowstate import HOTTEST, Faults, low_state
from go2vlm.sim.state import RobotState
from go2vlm.sim.thermal import AMBIENT_C, K_HEAT, TAU_THERMAL, Battery, MotorThermal


def test_a_held_torque_settles_at_its_steady_temperature() -> None:
    m = MotorThermal()
    torques = [10.0] * 12
    m.step(TAU_THERMAL, torques)  # one time constant: 63 % of the way
    assert np.allclose(m.temps, AMBIENT_C + K_HEAT * 100 * (1 - math.exp(-1)))
    for _ in range(20):
        m.step(TAU_THERMAL, torques)
    assert np.allclose(m.temps, AMBIENT_C + K_HEAT * 100, atol=1e-3)
    for _ in range(30):
        m.step(TAU_THERMAL, [0.0] * 12)  # unloaded, it cools back to the ambient
    assert np.allclose(m.temps, AMBIENT_C, atol=1e-3)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 10), st.floats(-40, 40), st.floats(-30, 30)), min_size=1, max_size=30))
def test_the_battery_only_drains_and_stays_in_range(steps: list[tuple[float, float, float]]) -> None:
    b = Battery(80.0)
    last = b.soc_pct
    for dt, tau, omega in steps:
        soc = b.step(dt, [tau] * 12, [omega] * 12)
        assert 0.0 <= soc <= last
        last = soc
        assert 8 * 3.3 <= b.voltage <= 8 * 4.2


def state(roll: float = 0.0) -> RobotState:
    z3 = np.zeros(3)
    return RobotState(
        time=1.5, mode="standing", fell=False, position=np.array([0, 0, 0.32]),
        quaternion=np.array([1.0, 0, 0, 0]), lin_vel_world=z3, lin_vel_body=z3, ang_vel_body=z3,
        ang_vel_world=z3, imu_gyro=z3, imu_acc=np.array([0, 0, 9.81]), imu_rpy=np.array([roll, 0.0, 0.0]),
        joint_names=tuple(f"j{i}" for i in range(12)), joint_pos=np.zeros(12), joint_vel=np.zeros(12),
        joint_torque=np.full(12, 5.0), foot_names=("FR", "FL", "RR", "RL"), foot_contact=np.ones(4, bool),
        foot_force=np.full(4, 40.0), command=z3,
    )  # fmt: skip


def test_lowstate_reports_the_models_and_the_injected_faults() -> None:
    temps = np.full(12, 41.4)
    msg = low_state(state(0.1), temps, 77.6, 30.5, Faults())
    assert [m.temperature for m in msg.motor_state] == [41] * 12 + [0] * 8
    assert msg.bms_state.soc == 78 and msg.power_v == 30.5 and msg.tick == 1500
    assert msg.motor_state[0].tau_est == 5.0 and math.isclose(msg.imu_state.rpy[0], 0.1)
    msg = low_state(state(0.1), temps, 77.6, 30.5, Faults(motor_temp_c=300.0, battery_pct=4.0, tilt_deg=30.0))
    assert msg.motor_state[HOTTEST].temperature == 255  # a uint8 on the wire
    assert msg.bms_state.soc == 4
    assert math.isclose(msg.imu_state.rpy[0], 0.1 + math.radians(30.0), rel_tol=1e-6)
    back = type(msg).deserialize(msg.serialize())
    assert back.motor_state[HOTTEST].temperature == 255 and back.bms_state.soc == 4
