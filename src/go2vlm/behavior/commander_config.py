"""The commander's parameters (its contract: behavior/commander_node.py). Those its pure cores share,
the mission's (MissionParams), the local planner's margin (PlannerParams), the navigator's
(NavParams, as `nav_<name>`) and exploring's (ExploreParams), are declared once on the cores' fields
and taken over here with `from_core`
(go2vlm/declare.py), some under the node's own name (`planner_margin_m` is PlannerParams' `margin`);
`core_params` builds the cores' params back from a config. The camera mount is the robot profile's."""

from __future__ import annotations

from dataclasses import dataclass

from go2vlm.behavior.mission import MissionParams
from go2vlm.behavior.navigate import NavParams
from go2vlm.behavior.planner import PlannerParams
from go2vlm.behavior.strategies.explore import ExploreParams
from go2vlm.bus import core_params, from_core, param
from go2vlm.bus.topics import MAP_COSTMAP, OBJECTS, ODOM, SCAN
from go2vlm.robot_profile import DEFAULT_ROBOT, PROFILES, profile

__all__ = ["CommanderConfig"]


@dataclass
class CommanderConfig:
    """The commander's parameters: the Mission core's, the local planner's margin and exploring's are
    their params' fields (`from_core`: default, help, bounds, written there once)."""

    goal: str = param("", help="goal to start with, e.g. 'follow the red ball' or 走到蓝色圆柱 ('' = wait for /goal)")
    stop_distance_m: float = from_core(MissionParams, "stop_distance_m")
    follow_distance_m: float = from_core(MissionParams, "follow_distance_m")
    distance_tolerance_m: float = from_core(MissionParams, "distance_tolerance_m")
    max_linear: float = from_core(MissionParams, "max_linear")
    max_angular: float = from_core(MissionParams, "max_angular")
    kp_linear: float = from_core(MissionParams, "kp_linear")
    kp_angular: float = from_core(MissionParams, "kp_angular")
    search_yaw_rate: float = from_core(MissionParams, "search_yaw_rate")
    search_timeout_s: float = from_core(MissionParams, "search_timeout_s")
    search_on_loss: bool = from_core(MissionParams, "search_on_loss")
    lost_timeout_s: float = from_core(MissionParams, "lost_timeout_s")
    robot: str = param(
        DEFAULT_ROBOT, help="the robot whose head camera the target is seen with: its mount, for base distances",
        choices=tuple(PROFILES),
    )  # fmt: skip
    avoid_obstacles: bool = from_core(MissionParams, "avoid_obstacles")
    scan_topic: str = param(SCAN.name, help="sensor_msgs/LaserScan in base_link for the local planner")
    odom_topic: str = param(ODOM.name, help="nav_msgs/Odometry: the target's place while a detour hides it")
    scan_timeout_s: float = from_core(MissionParams, "scan_timeout_s")
    planner_margin_m: float = from_core(PlannerParams, "margin")
    detour_memory_s: float = from_core(MissionParams, "detour_memory_s")
    reach_settle_s: float = from_core(MissionParams, "reach_settle_s")
    align_found_s: float = from_core(MissionParams, "align_found_s")
    use_memory: bool = from_core(MissionParams, "use_memory")
    objects_topic: str = param(OBJECTS.name, help="vision_msgs/Detection3DArray: the object memory")
    memory_min_confidence: float = from_core(MissionParams, "memory_min_confidence")
    memory_confirm_confidence: float = from_core(MissionParams, "memory_confirm_confidence")
    reach_slack_m: float = from_core(MissionParams, "reach_slack_m")
    confirm_looks: int = from_core(MissionParams, "confirm_looks")
    search_step_deg: float = from_core(MissionParams, "search_step_deg")
    search_view_per_answer: float = from_core(MissionParams, "search_view_per_answer")
    search_step_rate: float = from_core(MissionParams, "search_step_rate")
    look_settle_s: float = from_core(MissionParams, "look_settle_s")
    look_timeout_s: float = from_core(MissionParams, "look_timeout_s")
    max_goal_s: float = param(900.0, help="any goal stops after this long (s)", min=1.0, max=86400.0, live=True,
                              bound="max")  # fmt: skip
    max_go_to_m: float = param(
        25.0, help="go to: an object farther than this (m) is refused", min=0.5, max=500.0, live=True, bound="max"
    )
    nav_goal_moved_m: float = from_core(NavParams, "goal_moved_m")
    nav_arrive_m: float = from_core(NavParams, "arrive_m")
    nav_place_error_m: float = from_core(NavParams, "place_error_m")
    nav_lookahead_s: float = from_core(NavParams, "lookahead_s")
    nav_lookahead_min_m: float = from_core(NavParams, "lookahead_min_m")
    nav_lookahead_max_m: float = from_core(NavParams, "lookahead_max_m")
    nav_rotate_to_heading_deg: float = from_core(NavParams, "rotate_to_heading_deg")
    nav_line_up_deg: float = from_core(NavParams, "line_up_deg")
    nav_rotate_gain: float = from_core(NavParams, "rotate_gain")
    nav_min_turn_rate: float = from_core(NavParams, "min_turn_rate")
    nav_min_radius_m: float = from_core(NavParams, "min_radius_m")
    nav_slow_near_m: float = from_core(NavParams, "slow_near_m")
    nav_approach_gain: float = from_core(NavParams, "approach_gain")
    nav_max_speed: float = from_core(NavParams, "max_speed")
    nav_min_speed: float = from_core(NavParams, "min_speed")
    nav_horizon_s: float = from_core(NavParams, "horizon_s")
    nav_turn_leg_s: float = from_core(NavParams, "turn_leg_s")
    nav_turn_legs: int = from_core(NavParams, "turn_legs")
    nav_turn_search_moves: int = from_core(NavParams, "turn_search_moves")
    nav_progress_m: float = from_core(NavParams, "progress_m")
    nav_progress_deg: float = from_core(NavParams, "progress_deg")
    nav_progress_s: float = from_core(NavParams, "progress_s")
    nav_nearing_s: float = from_core(NavParams, "nearing_s")
    nav_setbacks: int = from_core(NavParams, "setbacks")
    nav_reroute_gain: float = from_core(NavParams, "reroute_gain")
    nav_spin_deg: float = from_core(NavParams, "spin_deg")
    nav_back_up_m: float = from_core(NavParams, "back_up_m")
    nav_back_up_speed: float = from_core(NavParams, "back_up_speed")
    nav_wait_s: float = from_core(NavParams, "wait_s")
    nav_recovery_s: float = from_core(NavParams, "recovery_s")
    explore: bool = param(True, help="go to / look for: walk to frontiers of costmap_topic once turn-and-look "
                          "finds nothing", live=True)  # fmt: skip
    frontier_choice: str = from_core(ExploreParams, "frontier_choice")
    explore_unknown_cost: float = from_core(ExploreParams, "unknown_cost")
    explore_timeout_s: float = from_core(ExploreParams, "timeout_s")
    explore_regrown_share: float = from_core(ExploreParams, "regrown_share")
    explore_unreachable_wait_s: float = from_core(ExploreParams, "unreachable_wait_s")
    explore_gain_radius_m: float = from_core(ExploreParams, "gain_radius_m")
    explore_gain_per_m: float = from_core(ExploreParams, "gain_per_m")
    explore_look_stall_s: float = from_core(ExploreParams, "look_stall_s")
    explore_look_stall_rad: float = from_core(ExploreParams, "look_stall_rad")
    explore_look_slack: float = from_core(ExploreParams, "look_slack")
    costmap_topic: str = param(MAP_COSTMAP.name, help="nav_msgs/OccupancyGrid: the inflated costmap (global planner)")
    control_rate_hz: float = param(20.0, help="control loop rate", min=2.0, max=100.0)
    status_period_s: float = param(1.0, help="/commander/status period besides on-change", min=0.1, max=60.0)
    decision_hold_s: float = from_core(MissionParams, "decision_hold_s")
    decision_turn_rate: float = from_core(MissionParams, "decision_turn_rate")
    max_turn_deg: float = from_core(MissionParams, "max_turn_deg")

    def validate(self) -> None:
        self.mission_params()  # e.g. memory_min_confidence above memory_confirm_confidence: refused at start-up

    def explore_params(self) -> ExploreParams:
        return core_params(ExploreParams, self)

    def mission_params(self) -> MissionParams:
        return core_params(
            MissionParams,
            self,
            planner=core_params(PlannerParams, self),
            nav=core_params(NavParams, self),
            camera_forward_m=profile(self.robot).head_camera.pos[0],
        )
