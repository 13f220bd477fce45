"""The simulated Go2's rt/lowstate (unitree_go/LowState_): what a real Go2 reports about its motors,
battery and IMU, built from a `RobotState`, the motor and battery models (sim/thermal.py) and the
injected faults. The sim publishes it as the ROS topic /lowstate, which is rt/lowstate on the wire,
as unitree_ros2 shows a Go2's."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from go2vlm.msgs.unitree import BmsState, IMUState, LowState, MotorState
from go2vlm.sim.state import RobotState

__all__ = ["Faults", "low_state"]

HOTTEST = 2  # the FR calf motor: the faulted one (calf motors carry the most torque, run hottest)


@dataclass(frozen=True)
class Faults:
    """Injected faults (the sim's fault_* parameters): a motor temperature (C, 0 = none), a battery
    state of charge (percent, < 0 = none) and a tilt added to the reported roll (degrees)."""

    motor_temp_c: float = 0.0
    battery_pct: float = -1.0
    tilt_deg: float = 0.0


def _byte(x: float) -> int:
    return int(min(max(round(x), 0), 255))


def low_state(s: RobotState, temps: np.ndarray, soc_pct: float, volts: float, faults: Faults) -> LowState:
    temps = np.array(temps, dtype=float)
    if faults.motor_temp_c > 0:
        temps[HOTTEST] = faults.motor_temp_c
    soc = faults.battery_pct if faults.battery_pct >= 0 else soc_pct
    rpy = [float(v) for v in s.imu_rpy]
    rpy[0] += math.radians(faults.tilt_deg)
    motors = [
        MotorState(
            mode=1,
            q=float(s.joint_pos[i]),
            dq=float(s.joint_vel[i]),
            tau_est=float(s.joint_torque[i]),
            temperature=_byte(temps[i]),
        )
        for i in range(len(s.joint_pos))
    ]
    motors += [MotorState() for _ in range(20 - len(motors))]
    return LowState(
        imu_state=IMUState(
            quaternion=[float(v) for v in s.quaternion],
            gyroscope=[float(v) for v in s.imu_gyro],
            accelerometer=[float(v) for v in s.imu_acc],
            rpy=rpy,
            temperature=_byte(temps.mean()),
        ),
        motor_state=motors,
        bms_state=BmsState(status=8, soc=_byte(soc), current=-int(1000 * 60 / max(volts, 1.0))),
        foot_force=[int(min(max(f, -32768), 32767)) for f in s.foot_force],
        tick=int(s.time * 1000) & 0xFFFFFFFF,
        power_v=volts,
    )
