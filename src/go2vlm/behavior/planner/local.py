"""A local planner for the commander's approach: steer round what /scan shows between the robot and
its goal.

Pure (no DDS), a vector-field-histogram idea cut to what the approach needs. Candidate headings lie
around the goal's bearing, each a straight corridor as wide as the footprint plus the clearance each
side (geometry/footprint.py `Clearance`, the rule the global planner and the guard keep: `margin` at a
creep, `margin_per_speed_s` more per m/s); the free length of a corridor is how far the footprint's
front could go that way before it comes within that clearance of a scan point. Scan points within
`goal_radius` of the goal's own surface are the goal, not an obstacle.

- The corridor towards the goal is free for `lookahead` (or up to where the robot will stop) at the
  clearance of the approach's speed: its own command passes unchanged (`blocked` False); free only at
  the clearance of half that speed, or of a creep (`creep_mps`), it passes no faster than that speed
  (a narrow doorway is walked through slowly, square-on, not steered away from).
- Otherwise: the free heading closest to the goal's bearing, within `max_offset` of it, preferring
  the side chosen last time (`side`, so that a box dead ahead is not passed left and right in turn),
  and, before all of these, near the way chosen last time (`keep`, within `keep_window`) while one there
  is free at all.
  The robot turns towards it and drives at `speed`, slower the further it has to turn. With none free
  that far, half as far, then `min_free`, at a speed cut by the free length (progress, not a stall).
  A way free only at a creep's clearance is taken no faster than a creep (a gap the footprint fits
  through only slowly), before a shorter way at the approach's speed.
- No free heading at all: turn in place (towards the freest one, or the side it keeps to), forward
  speed zero.

It never drives faster than the `speed` it is given, and `steer` never backwards. The safety gate's
collision guard still has the last word on every command; the planner keeps the approach out of the
guard's way, it does not replace it.

A turn in place that the footprint cannot sweep is the navigator's (behavior/navigate/controller.py
`turn_in_place`): the strategies ask it for every turn in place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from go2vlm.declare import from_core
from go2vlm.geometry.footprint import Clearance
from go2vlm.robot_profile.go2 import FOOTPRINT_LENGTH, FOOTPRINT_WIDTH

__all__ = [
    "PlannerParams",
    "Steer",
    "corridor_free",
    "steer",
]


@dataclass(frozen=True)
class PlannerParams:
    # The clearance rule (geometry/footprint.py), the guard's too; the commander's planner_margin_m
    # (behavior/commander_config.py) is `margin`, the clearance at a creep.
    margin: float = from_core(Clearance, "creep_m")
    margin_per_speed_s: float = from_core(Clearance, "per_speed_s")
    creep_mps: float = from_core(Clearance, "creep_mps")
    lookahead: float = 1.2  # m of free corridor that counts as a free way
    max_offset: float = math.radians(100.0)  # how far from the goal's bearing it may head
    step: float = math.radians(5.0)
    side_bias: float = math.radians(15.0)  # a heading on the other side must be this much closer
    min_free: float = 0.3  # m: the shortest free way it still drives along when nothing longer is free
    goal_radius: float = 0.5  # m round the goal's surface point that is the goal itself
    kp: float = 1.5  # rad/s per rad of heading error (not the approach's kp_angular, which is per offset x)
    turn_only: float = math.radians(60.0)  # |heading| beyond which it only turns
    # a way this near the one chosen last is kept before one nearer the goal's bearing: in a pocket two
    # ways far apart were free in turn as the robot turned, and it swung between them on the spot
    keep_window: float = math.radians(20.0)
    keep_s: float = 3.0  # s the way (and the side) chosen last is kept
    half_length: float = FOOTPRINT_LENGTH / 2
    half_width: float = FOOTPRINT_WIDTH / 2

    def __post_init__(self) -> None:
        names = (
            "margin",
            "margin_per_speed_s",
            "creep_mps",
            "lookahead",
            "max_offset",
            "step",
            "min_free",
            "goal_radius",
            "kp",
            "turn_only",
            "keep_window",
            "keep_s",
        )
        for name in names:
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"planner {name} must be a finite number >= 0, got {v}")
        if self.step <= 0 or self.turn_only <= 0:
            raise ValueError("planner step and turn_only must be positive")

    @property
    def clearance(self) -> Clearance:
        return Clearance(creep_m=self.margin, per_speed_s=self.margin_per_speed_s, creep_mps=self.creep_mps)


@dataclass(frozen=True)
class Steer:
    vx: float
    wz: float
    heading: float  # rad, the chosen heading (robot frame, + left)
    blocked: bool  # the way to the goal is blocked: (vx, wz) is the planner's, not the approach's
    note: str  # why, for the commander's status ("" when the approach's command passed as it was)
    way: bool = False  # blocked, and `heading` is a free way chosen (not a turn with none free, nor an escape)


def corridor_free(points: np.ndarray, heading: float, p: PlannerParams, margin: float | None = None) -> float:
    """How far (m) the footprint's front can go along `heading` before it is within `margin` (default:
    the clearance standing, `p.margin`) of a point."""
    if len(points) == 0:
        return math.inf
    m = p.margin if margin is None else margin
    c, s = math.cos(heading), math.sin(heading)
    along = points[:, 0] * c + points[:, 1] * s
    across = -points[:, 0] * s + points[:, 1] * c
    block = (np.abs(across) < p.half_width + m) & (along > 0)
    if not block.any():
        return math.inf
    return max(0.0, float(along[block].min()) - p.half_length - m)


def steer(
    vx: float,
    wz: float,
    speed: float,
    bearing: float,
    goal_m: float | None,
    points: np.ndarray,
    p: PlannerParams,
    *,
    max_angular: float,
    reach_m: float | None = None,
    side: float = 0.0,
    keep: float | None = None,
) -> Steer:
    """The approach's (vx, wz), or a way round the scan `points` ((N, 2), base frame, x forward).

    `bearing` (rad, + left) and `goal_m` (base centre -> the goal's near surface; None: unknown)
    place the goal; `reach_m` is how far the robot still has to go (default: up to the goal).
    `speed` (>= 0) is the forward speed the approach would like on a free way, `max_angular` its turn
    rate ceiling; `side` (-1, 0, +1) the side chosen last time; `keep` (rad from the goal's bearing)
    the way chosen last time: a way within `keep_window` of it that is free at all (min_free, at the
    clearance of its speed or of a creep) comes before any other."""
    if not (math.isfinite(bearing) and math.isfinite(speed)) or speed <= 0.0:
        return Steer(vx, wz, bearing, False, "")
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if goal_m is not None and math.isfinite(goal_m) and len(pts):
        g = np.array([goal_m * math.cos(bearing), goal_m * math.sin(bearing)])
        pts = pts[np.hypot(pts[:, 0] - g[0], pts[:, 1] - g[1]) > p.goal_radius]
    far = goal_m if reach_m is None else reach_m
    need = p.lookahead if far is None or not math.isfinite(far) else max(0.0, min(p.lookahead, far))
    rule = p.clearance
    if need <= 0.0:
        return Steer(vx, wz, bearing, False, "")
    # Straight on, slower where only a slower speed's clearance is free (one rule: the guard's).
    for v in (speed, speed / 2.0, min(speed, p.creep_mps)):
        if corridor_free(pts, bearing, p, rule.at(v)) >= need:
            if v >= speed:
                return Steer(vx, wz, bearing, False, "")
            return Steer(min(vx, v), wz, bearing, False, f"slowed to {v:.2f} m/s: a narrow way")
    n = int(p.max_offset / p.step)
    offsets = [k * p.step for k in range(-n, n + 1)]

    def cost(off: float) -> float:
        return abs(off) + (p.side_bias if side and off * side < 0 else 0.0)

    heads = sorted(offsets, key=cost)
    free = [(bearing + off, corridor_free(pts, bearing + off, p, rule.at(speed))) for off in heads]
    passes = [(free, "round an obstacle", speed)]
    if p.creep_mps < speed:  # a narrow gap, at a creep's clearance and speed
        tight = [(bearing + off, corridor_free(pts, bearing + off, p, rule.creep)) for off in heads]
        passes.append((tight, "through a gap", p.creep_mps))
    # A long way at a creep before a short one at speed: a doorway before a stub beside it.
    tiers = [(ways, how, fast, want) for want in (need, need / 2, p.min_free) for ways, how, fast in passes]
    # A shorter free way is still progress. Near the way kept, any free way comes first.
    kept = [(keep, t) for t in tiers] if keep is not None else []
    for k, (ways, how, fast, want) in kept + [(None, t) for t in tiers]:
        ok = [(h, f) for h, f in ways if f >= want and (k is None or abs(_wrap(h - bearing - k)) <= p.keep_window)]
        if ok:
            h, f = _wrap(ok[0][0]), ok[0][1]
            turn = max(-max_angular, min(max_angular, p.kp * h))
            fwd = fast * max(0.0, 1.0 - abs(h) / p.turn_only) * min(1.0, f / need)
            note = f"steering {math.degrees(_wrap(h - bearing)):+.0f} deg {how}"
            return Steer(fwd, turn, h, True, note, way=True)
    # Boxed in within max_offset of the goal: turn in place (towards the side it keeps to), never
    # standing still facing a blocked way.
    h = _wrap(max(free, key=lambda hf: hf[1])[0])
    direction = math.copysign(1.0, h) if abs(h) > p.step else (side or 1.0)
    turn = direction * max(min(max_angular, p.kp * abs(h)), max_angular / 2)
    return Steer(0.0, turn, h, True, "no free way towards the goal: turning")


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi
