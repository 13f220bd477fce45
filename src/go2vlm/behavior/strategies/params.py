"""The mission's parameters: one flat, frozen set that the goal state machine (behavior/mission.py)
and every strategy read. Those declared with `param` are the commander's parameters too
(go2vlm/declare.py: behavior/commander_config.py takes them over with `from_core`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from go2vlm.behavior.control import ApproachParams
from go2vlm.behavior.navigate.params import NavParams
from go2vlm.behavior.planner import PlannerParams
from go2vlm.declare import param
from go2vlm.robot_profile import go2 as spec
from go2vlm.world.ranging import RangingParams

__all__ = ["MissionParams"]


@dataclass(frozen=True)
class MissionParams:
    stop_distance_m: float = param(
        0.8, help="go to: stop this far from the object's surface (base)", min=0.2, max=5.0, live=True
    )
    follow_distance_m: float = param(1.2, help="follow: keep this far (base -> surface)", min=0.3, max=5.0, live=True)
    distance_tolerance_m: float = param(
        0.05, help="go to: reached within this of stop_distance_m", min=0.0, max=1.0, live=True
    )
    max_linear: float = param(
        0.4, help="forward speed ceiling (m/s); the gate limits again", min=0.0, max=1.0, live=True, bound="max"
    )
    max_angular: float = param(0.8, help="|yaw rate| ceiling (rad/s)", min=0.0, max=2.0, live=True, bound="max")
    kp_linear: float = param(0.8, help="go to: P gain from distance error to linear.x", min=0.0, max=5.0, live=True)
    # follow, go to, look for: one gain (the follower node's own is the article's demo's)
    kp_angular: float = param(
        1.5, help="P gain from horizontal offset x to angular.z (every goal)", min=0.0, max=10.0, live=True
    )
    search_yaw_rate: float = param(0.5, help="turn rate while searching (rad/s)", min=0.05, max=1.5, live=True)
    search_timeout_s: float = param(30.0, help="give up searching after this long", min=1.0, max=600.0, live=True)
    search_on_loss: bool = param(True, help="go to / look for: search again when the target is lost", live=True)
    lost_timeout_s: float = param(
        1.0, help="a tracker report older than this confirms nothing", min=0.1, max=10.0, live=True
    )
    camera_forward_m: float = spec.HEAD_CAMERA_POS[0]  # the node's: its robot profile's head camera
    decision_hold_s: float = param(3.0, help="a 'stop' decision holds still this long", min=0.1, max=60.0, live=True)
    decision_turn_rate: float = param(0.5, help="turn rate of a 'turn' decision (rad/s)", min=0.05, max=1.0, live=True)
    turn_slack: float = param(
        3.0, help="a turn (goal or decision) not done in this many times its time at decision_turn_rate ends, "
        "saying how far it turned", min=1.0, max=20.0, live=True,
    )  # fmt: skip
    max_turn_deg: float = param(
        30.0, help="largest |angle| a 'turn' decision may ask for", min=0.0, max=30.0, live=True, bound="max"
    )
    avoid_obstacles: bool = param(True, help="go to / follow (self): steer round obstacles on scan_topic", live=True)
    scan_timeout_s: float = param(0.5, help="a scan older than this (s) is no scan: no planning", min=0.05, max=5.0)
    pose_timeout_s: float = 0.5  # an odometry pose older than this places nothing
    detour_memory_s: float = param(
        8.0, help="a detour out of view lasts this long after the last sighting (s)", min=0.0, max=60.0, live=True
    )
    # The object memory's place, which overrules a tracker's range far too short (a door leaf in front
    # of the object, Context.base_distance), comes a moment after the tracker's first confirmation.
    reach_settle_s: float = param(
        2.0, help="go to: not reached within this long (s) of a confirmation", min=0.0, max=10.0, live=True
    )
    # The gate may hold the last of a turn in a doorway; a target that flickers at the edge never centres.
    align_found_s: float = param(
        3.0, help="look for: confirmed in view this long (s) but not centred is found all the same",
        min=0.5, max=30.0, live=True,
    )  # fmt: skip
    planner: PlannerParams = field(default_factory=PlannerParams)
    nav: NavParams = field(default_factory=NavParams)  # the navigator's (behavior/navigate/params.py)
    ranging: RangingParams = field(default_factory=RangingParams)  # the target's range (world/ranging.py)
    use_memory: bool = param(True, help="go to / look for remembered objects (objects_topic)", live=True)
    # one sighting: 0.5; then three empty looks: 0.32
    memory_min_confidence: float = param(
        0.3, help="a remembered object this sure is turned to", min=0.01, max=1.0, live=True
    )
    # two sightings that agree: 0.73
    memory_confirm_confidence: float = param(0.7, help="... and this sure walked to", min=0.01, max=1.0, live=True)
    reach_slack_m: float = param(
        0.15, help="go to: within reach where nearer cannot be walked (a remembered place, a blocked last "
        "bit): stop + tolerance + this (m); by default 1.0 m, the success distance go to is judged by "
        "(ObjectNav's, the eval's)", min=0.0, max=2.0, live=True,
    )  # fmt: skip
    confirm_looks: int = param(3, help="answered looks without it before giving up", min=1, max=20, live=True)
    # the view is 73 deg wide
    search_step_deg: float = param(50.0, help="stop and look: the turn between looks", min=5.0, max=90.0, live=True)
    search_view_per_answer: float = param(
        0.5, help="turning on would turn more of the view than this per answer: stop and look", min=0.05, max=2.0,
        live=True,
    )  # fmt: skip
    search_step_rate: float = param(
        0.5, help="stop and look: the turn between looks (rad/s)", min=0.05, max=1.5, live=True
    )
    look_settle_s: float = param(
        0.3, help="frames this long after a stop are taken still (s)", min=0.0, max=5.0, live=True
    )
    # then 2.5 x the answer latency + 1 s
    look_timeout_s: float = param(
        8.0, help="before any answer, a look waits this long (s)", min=0.5, max=120.0, live=True
    )

    def __post_init__(self) -> None:
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
