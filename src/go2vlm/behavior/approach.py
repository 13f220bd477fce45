"""Approach control for "go to <object>": which Twist brings the robot to `stop_distance` from an
object seen at normalised offset x, `distance_base` metres away.

The distance comes from the target_tracker's monocular ranging (perception/ranging.py: camera ->
the object's near surface); the robot-centric distance used for the goal is base -> surface = that
plus the camera's forward offset from the base (`camera_forward`, Go2: 0.327 m).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ApproachParams", "approach_command"]


@dataclass(frozen=True)
class ApproachParams:
    """The gains and limits are the commander's (behavior/mission.py MissionParams.approach)."""

    stop_distance: float  # base -> surface (m)
    tolerance: float
    kp_linear: float
    kp_angular: float
    max_linear: float
    max_angular: float
    min_linear: float = 0.08  # below this the gait barely moves: creep at least this fast (max_linear caps it)
    align_start: float = 0.15  # |x| where forward speed starts to drop
    align_stop: float = 0.4  # |x| where the robot only turns


def approach_command(x: float, distance_base: float | None, p: ApproachParams) -> tuple[float, float, bool]:
    """(linear.x, angular.z, reached) towards a target at normalised offset `x` whose surface is
    `distance_base` metres from the robot's base (None: unknown -> turn only)."""
    wz = max(-p.max_angular, min(p.max_angular, -p.kp_angular * x))
    if distance_base is None:
        return 0.0, wz, False
    err = distance_base - p.stop_distance
    if err <= p.tolerance:
        return 0.0, 0.0, True
    ax = abs(x)
    align = 1.0 if ax <= p.align_start else max(0.0, (p.align_stop - ax) / (p.align_stop - p.align_start))
    vx = min(p.max_linear, max(p.min_linear, p.kp_linear * err)) * align
    return vx, wz, False
