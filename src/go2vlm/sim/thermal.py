"""The simulated Go2's motor temperatures and battery: simple, documented models, pure.

Motor temperature, one first-order model per joint motor (copper losses heat it, the housing
cools it towards the ambient temperature):

    dT/dt = (ambient + K_HEAT * tau^2 - T) / TAU_THERMAL

so a joint holding a steady torque tau settles at ambient + K_HEAT * tau^2 after a few TAU_THERMAL.
K_HEAT = 0.5 C/(N*m)^2 puts a calf motor holding ~10 N*m (a standing Go2) about 50 C above the
ambient, as a logged Go2 reads (72-78 C on its calf motors); TAU_THERMAL = 300 s is the slow lag
Unitree's MotorState documents ("slow conduction of temperature leads to lag").

Battery: electrical power = electronics (P_BASE) + mechanical |tau * omega| + copper losses
R_LOSS * tau^2 per motor, drawn from the pack's energy (the robot profile's battery, robot_profile/go2.py); the pack
voltage is linear in the state of charge between 3.3 V and 4.2 V a cell.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from go2vlm.robot_profile.go2 import GO2

__all__ = ["AMBIENT_C", "Battery", "MotorThermal"]

AMBIENT_C = 25.0
K_HEAT = 0.5  # C per (N*m)^2 at steady state
TAU_THERMAL = 300.0  # s
P_BASE = 60.0  # W: computers, sensors, motor drivers at rest
R_LOSS = 0.3  # W per (N*m)^2 per motor
CELL_EMPTY_V, CELL_FULL_V = 3.3, 4.2


@dataclass
class MotorThermal:
    n: int = 12
    ambient_c: float = AMBIENT_C
    temps: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.temps = np.full(self.n, self.ambient_c)

    def step(self, dt: float, torques: Sequence[float] | np.ndarray) -> np.ndarray:
        """Advance by `dt` seconds with these motor torques (N*m); returns the temperatures (C)."""
        if dt > 0:
            tau = np.nan_to_num(np.asarray(torques, dtype=float)[: self.n])
            steady = self.ambient_c + K_HEAT * tau * tau
            self.temps = steady + (self.temps - steady) * np.exp(-dt / TAU_THERMAL)  # exact for constant tau
        return self.temps


@dataclass
class Battery:
    soc_pct: float = 100.0

    def step(self, dt: float, torques: Sequence[float] | np.ndarray, velocities: Sequence[float] | np.ndarray) -> float:
        """Drain for `dt` seconds of this motor load; returns the state of charge (percent)."""
        if dt > 0:
            tau = np.nan_to_num(np.asarray(torques, dtype=float))
            omega = np.nan_to_num(np.asarray(velocities, dtype=float))
            n = min(len(tau), len(omega))
            power = P_BASE + float(np.sum(np.abs(tau[:n] * omega[:n])) + R_LOSS * np.sum(tau * tau))
            self.soc_pct = max(0.0, self.soc_pct - 100.0 * power * dt / (GO2.battery.wh * 3600.0))
        return self.soc_pct

    @property
    def voltage(self) -> float:
        return GO2.battery.cells * (CELL_EMPTY_V + (CELL_FULL_V - CELL_EMPTY_V) * self.soc_pct / 100.0)
