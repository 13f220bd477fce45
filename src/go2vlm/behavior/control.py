"""The behaviours' control laws, pure: how a target's place becomes a velocity. Which law runs, and
when, is decided elsewhere (the follower node; the commander's Mission, behavior/mission.py, and its
strategies, with the local planner, behavior/planner/local.py), as Nav2 keeps the planner and the
controller apart. Each behaviour has one law and one set of gains:

- `follow_command`: the article's follower (behavior/follower_node.py, section 5.3), the follow
  article's standalone demo (colour detector -> /detected_target -> follower): turn towards the
  normalised offset x, walk while aligned, slower as the target grows. Its gains are the follower
  node's (kp_angular 0.8).
- `approach_command`: the commander's goals, follow, go to and look for's walk: turn first, then
  walk, and stop `stop_distance` from the object's surface (follow: `follow_distance_m`). Its gains
  are the commander's (MissionParams: kp_angular 1.5). The distance comes from the target_tracker's monocular
  ranging (perception/ranging.py: camera -> the object's near surface) plus the camera's forward
  offset from the base (MissionParams.camera_forward_m: the commander's robot profile's head camera).
- `align_command`: look for: turn in place until the target is centred.
- `face_command`: turn in place towards a bearing (a remembered object).
- `search_command`: turn in place towards where the target was last seen.

Offsets x are the /detected_target convention (geometry/target.py: -1..1 from the image centre, +
right); bearings are radians from the camera's axis, + left. Every command is forward-only and
within the limits it is given; the safety gate limits again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

__all__ = [
    "CENTRED_X",
    "MIN_ALIGN_WZ",
    "ApproachParams",
    "FollowGains",
    "align_command",
    "approach_command",
    "face_command",
    "follow_command",
    "search_command",
]

CENTRED_X = 0.1  # look for: |x| below this counts as centred
MIN_ALIGN_WZ = 0.15  # look for: at least this gentle a turn, so a slow search does not stall near the centre
# look for: at most this fast a turn to centre it: faster, a small far object (a duck at 6 m, 15 px)
# jumps further between two frames than the tracker's window follows, and is lost before it is centred
MAX_ALIGN_WZ = 0.3


def _clamp(v: float, lo: float, hi: float) -> float:
    return max(lo, min(hi, v))


class FollowGains(Protocol):
    """The follower's gains and limits (its node's FollowerConfig)."""

    kp_angular: float
    kd_angular: float
    max_angular: float
    kp_linear: float
    max_linear: float
    align_threshold: float


def follow_command(x: float, size: float, g: FollowGains, dx_dt: float = 0.0) -> tuple[float, float]:
    """(linear.x, angular.z) for a target at normalised offset `x` with normalised size `size`."""
    angular = _clamp(-g.kp_angular * x - g.kd_angular * dx_dt, -g.max_angular, g.max_angular)
    linear = g.kp_linear * (1.0 - size) if abs(x) < g.align_threshold else 0.0
    return _clamp(linear, 0.0, g.max_linear), angular


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
    wz = _clamp(-p.kp_angular * x, -p.max_angular, p.max_angular)
    if distance_base is None:
        return 0.0, wz, False
    err = distance_base - p.stop_distance
    if err <= p.tolerance:
        return 0.0, 0.0, True
    ax = abs(x)
    align = 1.0 if ax <= p.align_start else max(0.0, (p.align_stop - ax) / (p.align_stop - p.align_start))
    vx = min(p.max_linear, max(p.min_linear, p.kp_linear * err)) * align
    return vx, wz, False


def align_command(x: float, p: ApproachParams) -> tuple[float, bool]:
    """(angular.z, centred) that turns a target at normalised offset `x` to the image centre: the
    approach's turn, at least MIN_ALIGN_WZ; zero once |x| < CENTRED_X."""
    if abs(x) < CENTRED_X:
        return 0.0, True
    top = min(p.max_angular, MAX_ALIGN_WZ)
    wz = _clamp(-p.kp_angular * x, -top, top)
    return math.copysign(min(top, max(abs(wz), MIN_ALIGN_WZ)), wz), False


def face_command(bearing: float, p: ApproachParams) -> float:
    """angular.z that turns towards `bearing` (rad, + left), at least MIN_ALIGN_WZ."""
    return math.copysign(max(MIN_ALIGN_WZ, min(p.max_angular, p.kp_angular * abs(bearing))), bearing)


def search_command(last_x: float, rate: float, max_angular: float) -> float:
    """angular.z of a search: `rate` (within max_angular) towards where the target was last seen
    (normalised offset `last_x`; left when it was not seen off to the right)."""
    return (-1.0 if last_x > 0 else 1.0) * min(rate, max_angular)
