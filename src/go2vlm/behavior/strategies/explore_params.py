"""The frontier search's settings (strategies/explore.py): what it walks to, when it gives up, how
it looks. The three the commander exposes are declared with `param` (behavior/commander_config.py:
frontier_choice, explore_unknown_cost, explore_timeout_s)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from go2vlm.behavior.planner.global_path import GlobalParams
from go2vlm.declare import param

__all__ = ["FRONTIER_CHOICES", "ExploreParams"]

FRONTIER_CHOICES = ("gain", "nearest", "vlm")


@dataclass(frozen=True)
class ExploreParams:
    # gain (what it would reveal against its path cost) | nearest (by path cost) | vlm (a whitelisted
    # model answer); declared with `param`, the commander's (behavior/commander_config.py)
    frontier_choice: str = param(
        "gain", choices=FRONTIER_CHOICES,
        help="explore: the frontier to walk to: gain (the unknown and unseen area near it, less gain_per_m x its "
        "path cost), nearest by path cost, or vlm (the best-scored way on /vlm/way first)",
    )  # fmt: skip
    gain_radius_m: float = param(
        3.0, help="explore (gain): a frontier's gain counts the unknown and unseen area within this of it (m)",
        min=0.5, max=20.0, live=True,
    )  # fmt: skip
    gain_per_m: float = param(
        1.0, help="explore (gain): m^2 of area to reveal worth one metre more of path", min=0.0, max=100.0,
        live=True,
    )  # fmt: skip
    unknown_cost: float = param(3.0, help="explore: cost per unknown cell crossed (free: 1)", min=1.0, max=1000.0,
                                live=True)  # fmt: skip
    min_frontier_m: float = 0.5  # a shorter frontier is dropped
    arrive_m: float = 0.5  # this near the frontier's goal: look around
    # unseen regions this near a place looked from, frontiers this near a given-up one: skipped
    visited_radius_m: float = 1.0
    regrown_share: float = param(
        0.2, help="explore: a frontier given up comes back once this share more of the map round it is known",
        min=0.0, max=10.0, live=True,
    )  # fmt: skip
    unreachable_wait_s: float = param(
        8.0, help="explore: 'no reachable frontier' ends the search only once it has held this long (s), "
        "planned again on each new map (a plan from a doorway at an angle, a scan that closed a gap)",
        min=0.0, max=120.0, live=True,
    )  # fmt: skip
    map_timeout_s: float = 10.0  # no map at all this long after the search began: done
    min_view_m2: float = 1.0  # a region of free space the camera has not looked at, smaller than this, is dropped
    look_done_m2: float = 0.5  # a look ends once less unlooked free space than this is left in sight, in range
    second_pass_m: float = 2.0  # all seen and time left: look at it all again, a frame counting out to this
    # A look held by the safety gate (near a wall, in a corridor) ends: one that gains less than
    # look_stall_rad in look_stall_s, or is not all round in look_slack whole turns' time (the net turn
    # counts, so rocking in place is no turn).
    look_stall_s: float = param(
        4.0, help="explore: a look round that turns less than look_stall_rad in this long (s) is held, and ends",
        min=0.5, max=60.0, live=True,
    )  # fmt: skip
    look_stall_rad: float = param(
        0.2, help="explore: ... this much net turn (rad) in look_stall_s is headway", min=0.01, max=3.0, live=True
    )
    look_slack: float = param(
        3.0, help="explore: a look round not done in this many whole turns' time at search_yaw_rate ends", min=1.0,
        max=20.0, live=True,
    )  # fmt: skip
    timeout_s: float = param(300.0, help="explore: give the goal up this long after it began (s)", min=10.0,
                             max=3600.0, live=True, bound="max")  # fmt: skip
    planner: GlobalParams = field(default_factory=GlobalParams)

    def __post_init__(self) -> None:
        if self.frontier_choice not in FRONTIER_CHOICES:
            raise ValueError(f"frontier_choice {self.frontier_choice!r} is not one of {list(FRONTIER_CHOICES)}")
        for name in ("min_frontier_m", "arrive_m", "visited_radius_m", "regrown_share", "map_timeout_s",
                     "timeout_s", "unreachable_wait_s", "min_view_m2", "look_done_m2", "second_pass_m", "gain_radius_m",
                     "gain_per_m", "look_stall_s", "look_stall_rad", "look_slack"):  # fmt: skip
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"explore {name} must be a finite number >= 0, got {v}")
        if not self.unknown_cost >= 1.0:
            raise ValueError(f"unknown_cost must be >= 1 (or inf), got {self.unknown_cost}")

    @property
    def global_params(self) -> GlobalParams:
        return replace(self.planner, unknown_cost=self.unknown_cost)
