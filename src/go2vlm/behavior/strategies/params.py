"""The mission's parameters: one flat, frozen set that the goal state machine (behavior/mission.py)
and every strategy read (the commander's node config mirrors it, behavior/commander_node.py)."""

from __future__ import annotations

from dataclasses import dataclass, field

from go2vlm.behavior.control import ApproachParams
from go2vlm.behavior.planner import PlannerParams
from go2vlm.robot_profile import go2 as spec

__all__ = ["MissionParams"]


@dataclass(frozen=True)
class MissionParams:
    follow_control: str = "follower"  # follower: /detected_target for the follower; self: own control
    stop_distance_m: float = 0.8  # go to: base -> surface
    follow_distance_m: float = 1.2  # follow_control=self
    distance_tolerance_m: float = 0.05
    max_linear: float = 0.4
    max_angular: float = 0.8
    kp_linear: float = 0.8
    kp_angular: float = 1.5
    search_yaw_rate: float = 0.5
    search_timeout_s: float = 30.0
    search_on_loss: bool = True
    lost_timeout_s: float = 1.0
    camera_forward_m: float = spec.HEAD_CAMERA_POS[0]  # camera ahead of the base centre
    decision_hold_s: float = 3.0
    decision_turn_rate: float = 0.5
    max_turn_deg: float = 30.0
    avoid_obstacles: bool = True
    scan_timeout_s: float = 0.5  # a scan older than this is no scan: no planning
    pose_timeout_s: float = 0.5  # an odometry pose older than this places nothing
    detour_memory_s: float = 8.0  # a detour out of the target's view lasts this long after the last sighting
    planner: PlannerParams = field(default_factory=PlannerParams)
    use_memory: bool = True  # go to / look for the object memory's remembered objects
    memory_min_confidence: float = 0.3  # worth turning to (one sighting: 0.5; then three empty looks: 0.32)
    memory_confirm_confidence: float = 0.7  # ... and this sure worth walking to (two that agree: 0.73)
    reach_slack_m: float = 0.25  # a remembered place within reach: stop distance + tolerance + this
    confirm_looks: int = 3  # answered looks without the object before it is given up
    search_step_deg: float = 50.0  # stop and look: the turn between two looks (the view is 73 deg wide)
    search_view_per_answer: float = 0.5  # turning on would turn more of the view than this per answer: stop and look
    search_step_rate: float = 0.5  # stop and look: rad/s of the turn between two looks
    look_settle_s: float = 0.3  # after a stop, frames this much later are taken at the new heading
    look_timeout_s: float = 8.0  # before the first answer, a look waits this long (then 2.5 x the latency + 1 s)

    def __post_init__(self) -> None:
        if self.follow_control not in ("follower", "self"):
            raise ValueError(f"follow_control {self.follow_control!r} is not follower or self")
        if not 0.0 <= self.max_turn_deg <= 30.0:
            raise ValueError(f"max_turn_deg {self.max_turn_deg} must be within 0..30")
        if not 0.0 < self.memory_min_confidence <= self.memory_confirm_confidence <= 1.0:
            raise ValueError("need 0 < memory_min_confidence <= memory_confirm_confidence <= 1")

    def approach(self, stop_distance: float) -> ApproachParams:
        return ApproachParams(
            stop_distance=stop_distance,
            tolerance=self.distance_tolerance_m,
            kp_linear=self.kp_linear,
            kp_angular=self.kp_angular,
            max_linear=self.max_linear,
            max_angular=self.max_angular,
        )
