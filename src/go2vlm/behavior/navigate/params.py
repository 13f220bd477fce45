"""The navigator's settings (behavior/navigate/): every threshold the route, the controller, the
progress checker and the recoveries keep, declared once with `param` (help, bounds, live) and
documented in docs/navigation.md#the-navigator. The commander takes them over with `from_core`."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from go2vlm.declare import param

__all__ = ["RECOVERIES", "NavParams"]

# The recoveries, in the order they are tried after the progress checker says "stalled".
RECOVERIES = ("replan", "spin", "back_up", "wait")


@dataclass(frozen=True)
class NavParams:
    # -- the route ---------------------------------------------------------------------------
    goal_moved_m: float = param(
        0.5, help="navigate: a goal that moves less than this (m) keeps its route", min=0.0, max=5.0, live=True
    )
    unknown_cost: float = param(
        20.0, help="navigate: to a remembered place, cost per unknown cell crossed (free: 1; known ways first)",
        min=1.0, max=1000.0, live=True,
    )  # fmt: skip
    arrive_m: float = param(0.25, help="navigate: this near the route's end (m) is there", min=0.05, max=2.0, live=True)
    place_error_m: float = param(
        0.3, help="navigate: a remembered place may be this far (m) off its object: a piece of obstacle wholly within "
        "the object's radius plus this of the place is the object itself, and does not hide it from a stand",
        min=0.0, max=2.0, live=True,
    )  # fmt: skip
    # -- the controller (regulated pure pursuit) -----------------------------------------------
    lookahead_s: float = param(
        1.5, help="navigate: lookahead = this x speed (s), within the two bounds below", min=0.1, max=5.0, live=True
    )
    lookahead_min_m: float = param(0.5, help="navigate: shortest lookahead (m)", min=0.1, max=3.0, live=True)
    lookahead_max_m: float = param(1.5, help="navigate: longest lookahead (m)", min=0.2, max=5.0, live=True)
    rotate_to_heading_deg: float = param(
        45.0, help="navigate: the lookahead point this far off the heading (deg): turn in place first",
        min=5.0, max=180.0, live=True,
    )  # fmt: skip
    line_up_deg: float = param(
        5.0, help="navigate: an arc that does not keep its clearance, with the lookahead point this far off "
        "the heading (deg): turn in place to face it first", min=0.5, max=45.0, live=True,
    )  # fmt: skip
    rotate_gain: float = param(
        1.5, help="navigate: turn rate (rad/s) per rad of heading error when turning in place", min=0.1, max=10.0,
        live=True,
    )  # fmt: skip
    min_turn_rate: float = param(
        0.25, help="navigate: slowest turn in place (rad/s): the gait turns no slower", min=0.0, max=1.0, live=True
    )
    min_radius_m: float = param(
        0.9, help="navigate: curves tighter than this radius (m) slow in proportion", min=0.0, max=5.0, live=True
    )
    slow_near_m: float = param(
        0.6, help="navigate: an obstacle nearer the footprint than this (m) slows in proportion", min=0.0,
        max=3.0, live=True,
    )  # fmt: skip
    approach_gain: float = param(
        0.8, help="navigate: within reach of the end, speed <= this x the metres left (1/s)", min=0.1, max=5.0,
        live=True,
    )  # fmt: skip
    max_speed: float = param(
        1.0, help="navigate: top speed (m/s) in open space; the regulations here, the clearance at speed "
        "(horizon_s) and the gate's guard (its stopping envelope, and max_vx_forward) slow it wherever they "
        "do not hold", min=0.05, max=2.0, live=True, bound="max",
    )  # fmt: skip
    min_speed: float = param(
        0.08, help="navigate: slowest walk (m/s) the regulations leave", min=0.0, max=0.5, live=True
    )
    horizon_s: float = param(
        1.0, help="navigate: the command's arc this long ahead must keep the clearance (s)", min=0.1, max=5.0,
        live=True,
    )  # fmt: skip
    turn_leg_s: float = param(
        1.0, help="navigate: with no room to turn in place, a driver's turn goes in legs of this long (s), each held "
        "while it keeps its clearance", min=0.1, max=5.0, live=True,
    )  # fmt: skip
    turn_legs: int = param(
        4, help="navigate: a driver's turn searches this many legs ahead for a pose it can turn from", min=0, max=6,
        live=True,
    )  # fmt: skip
    turn_search_moves: int = param(
        400, help="navigate: a driver's turn's search tries at most this many legs (its cost: it runs once per leg, "
        "never per step)", min=1, max=5000, live=True,
    )  # fmt: skip
    # -- progress and recoveries ---------------------------------------------------------------
    progress_m: float = param(0.3, help="navigate: moving this far (m) ...", min=0.05, max=3.0, live=True)
    progress_deg: float = param(
        60.0, help="navigate: ... or turning this far (deg) from the heading it had there ...", min=5.0, max=360.0,
        live=True,
    )  # fmt: skip
    progress_s: float = param(
        10.0, help="navigate: ... within this long (s) is progress; else a recovery", min=1.0, max=120.0, live=True
    )
    nearing_s: float = param(
        30.0, help="navigate: ... and the way left to go falling progress_m within this long (s); else a recovery "
        "(only nearing starts the recoveries from the first again)", min=5.0, max=600.0, live=True,
    )  # fmt: skip
    reroute_gain: float = param(
        0.2, help="navigate: as the map grows, a new route replaces the one being walked only if it costs this share "
        "less (the planner's cost, both from the robot on the newest map)", min=0.0, max=0.9, live=True,
    )  # fmt: skip
    setbacks: int = param(
        3, help="navigate: blocks that lengthen the way with the robot no nearer since the block before: after this "
        "many the goal is given up (failed: its way keeps growing back)", min=1, max=100, live=True,
    )  # fmt: skip
    spin_deg: float = param(90.0, help="navigate: the spin recovery's turn (deg)", min=10.0, max=360.0, live=True)
    back_up_m: float = param(0.3, help="navigate: the back-up recovery's distance (m)", min=0.05, max=2.0, live=True)
    back_up_speed: float = param(0.15, help="navigate: the back-up recovery's speed (m/s)", min=0.05, max=0.5,
                                 live=True)  # fmt: skip
    wait_s: float = param(2.0, help="navigate: the wait recovery's pause (s)", min=0.0, max=30.0, live=True)
    recovery_s: float = param(
        8.0, help="navigate: a recovery that has not finished in this long (s) is over", min=1.0, max=60.0, live=True
    )

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"navigate {f.name} must be a finite number >= 0, got {v}")
        if self.lookahead_min_m > self.lookahead_max_m:
            raise ValueError("navigate: need lookahead_min_m <= lookahead_max_m")
