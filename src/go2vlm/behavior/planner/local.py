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
  and, before all of these, near the way chosen last time (`keep`, within KEEP_WINDOW) while one there
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

- `unstick`: a turn whose sweep would bring the footprint within `margin` of a scan point (or closer
  than it is, if already inside it) is one the guard holds: the robot would stand there at zero for
  ever (beside a table, facing a wall). A walking turn whose next ARC_CHECK_S does so turns in place
  instead, if that is clear; a turn in place that is not becomes a slow back-away (BACK_SPEED)
  turning the way it wanted to at BACK_TURN, if that sweep is clear for BACK_CHECK_M, else straight
  back while that is clear; a straight walk whose first HOLD_CHECK_M the guard would refuse (inside
  the margin already, it allows no step closer) backs straight away; a walking turn with no room
  behind walks on straight (at most BACK_SPEED) where that is clear (room to turn in later), and a turn
  with no room behind turns the other way round where that is clear; a route's turn wedged in a spot
  where none of these is clear edges out along a short forward arc (EDGE_CHECK_M) that gains
  clearance: backed up to a wall inside the guard's margin, with something at the front corner, no
  turn and no straight step kept the margin, and the robot stood at zero for 65 s (rooms 37); with
  none of these clear the command stays as it was (the guard holds it, and says so).
- A held turn towards a way on that lies behind the robot (`toward`, a route's waypoint) backs towards
  it first (`reverse`: at REVERSE_SPEED, the rear turned onto it, or less where that is not clear), as
  a driver reverses out of a narrow lane rather than turning in it. In a 1.5 m corridor a Go2
  standing askew, off the middle, can turn neither way inside the guard's margin; backing away and
  walking on in turn rocked it where it stood for a minute and more (rooms 12, 14, 18).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from go2vlm.declare import from_core
from go2vlm.geometry.footprint import Clearance, rect_distance
from go2vlm.robot_profile.go2 import FOOTPRINT_LENGTH, FOOTPRINT_WIDTH

__all__ = [
    "BACK_SPEED",
    "BACK_TURN",
    "KEEP_WINDOW",
    "TURN_ONLY_VX",
    "PlannerParams",
    "Steer",
    "behind",
    "corridor_free",
    "reverse",
    "steer",
    "unstick",
]

TURN_ONLY_VX = 0.05  # m/s: a command this slow forward is a turn in place
TURN_SWEEP = math.radians(30.0)  # how far ahead a turn in place is checked (the guard's stopping turn, and more)
BACK_SPEED = 0.15  # m/s: backing away from what a turn in place would sweep into
BACK_CHECK_M = 0.3  # m of room behind it needs to back away
BACK_TURN = 0.4  # rad/s: the turn while backing away, towards the turn it could not make in place
HOLD_CHECK_M = 0.03  # m: a straight walk whose first this much the guard would refuse is held at zero
ARC_CHECK_S = 0.4  # s of a walking turn's arc that must keep the margin (about the guard's stopping path)
REVERSE_SPEED = 0.25  # m/s: backing towards a way on behind the robot (a walk, not an escape)
EDGE_CHECK_M = 0.15  # m of a short forward arc out of a wedge that must keep the margin and gain clearance
# rad: a way this near the one chosen last is kept before one nearer the goal's bearing. Turning in a
# kitchen pocket, a way 5 deg right and one 95 deg left were free in turn, and the robot swung between
# them on the spot for two minutes (rooms 28, 32)
KEEP_WINDOW = math.radians(20.0)


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
    the way chosen last time: a way within KEEP_WINDOW of it that is free at all (min_free, at the
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
        ok = [(h, f) for h, f in ways if f >= want and (k is None or abs(_wrap(h - bearing - k)) <= KEEP_WINDOW)]
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


def _clearances(points: np.ndarray, x: np.ndarray, y: np.ndarray, th: np.ndarray, p: PlannerParams) -> np.ndarray:
    """The footprint's clearance from the nearest point at each pose (x, y, yaw in the base frame now)."""
    dx, dy = points[None, :, 0] - x[:, None], points[None, :, 1] - y[:, None]
    c, s = np.cos(th)[:, None], np.sin(th)[:, None]
    d = rect_distance(c * dx + s * dy, -s * dx + c * dy, p.half_length, p.half_width)
    return np.asarray(d.min(axis=1))


def _sweep_ok(points: np.ndarray, x: np.ndarray, y: np.ndarray, th: np.ndarray, p: PlannerParams) -> bool:
    """Does the footprint keep a creep's clearance (or what it has now, if less) along the poses (the first
    is now)? These moves are slow: the guard lets them through at the speed whose margin they keep."""
    d = _clearances(points, x, y, th, p)
    return bool((d[1:] >= min(p.clearance.creep, float(d[0])) - 1e-9).all())  # as strict as the guard: no closer at all


def unstick(
    vx: float, wz: float, points: np.ndarray | None, p: PlannerParams, walk: float = 0.0, toward: float | None = None
) -> Steer | None:
    """What to do instead of a command the footprint cannot sweep (module docstring), or None: its
    way is clear, or nothing better is (no room behind). `walk` (m/s): a turn in place may become a
    straight walk this fast (its caller walks that way anyway: a route's turn); 0: never. `toward`
    (rad, + left): the way on the command heads for (None: none, a search's turn)."""
    straight = abs(wz) < 1e-3
    if points is None or not (math.isfinite(vx) and math.isfinite(wz)) or vx < 0.0 or (straight and vx <= TURN_ONLY_VX):
        return None
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    reach = math.hypot(p.half_length, p.half_width) + p.clearance.creep + BACK_CHECK_M + vx * ARC_CHECK_S
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= reach]
    if len(pts) == 0:
        return None
    n = 7
    zero = np.zeros(n)
    if straight:  # held at zero only if its very first step comes closer than the guard allows
        if _sweep_ok(pts, np.linspace(0.0, HOLD_CHECK_M, n), zero, zero, p):
            return None
        return _back_away(pts, 0.0, p, n, "too near something to walk on")
    turn = np.linspace(0.0, math.copysign(TURN_SWEEP, wz), n)
    if vx > TURN_ONLY_VX:  # an arc: its next ARC_CHECK_S, as the guard would stop it
        if _sweep_ok(pts, *_arc(vx, wz, np.linspace(0.0, ARC_CHECK_S, n)), p):
            return None
        if _sweep_ok(pts, zero, zero, turn, p):
            return Steer(0.0, wz, wz, True, "too near something to walk on turning: turning in place first")
    elif _sweep_ok(pts, zero, zero, turn, p):
        return None
    why = "too near something to turn"
    if toward is not None and behind(toward):
        back = reverse(pts, toward, p, why)
        if back is not None:
            return back
    return _back_away(pts, wz, p, n, why, walk=vx if vx > TURN_ONLY_VX else walk)


def behind(toward: float) -> bool:
    """Does the way on at `toward` (rad, + left) lie behind the robot (backed towards, not turned to)?"""
    return abs(_wrap(toward)) > math.pi / 2


def reverse(points: np.ndarray | None, toward: float, p: PlannerParams, why: str = "") -> Steer | None:
    """Back towards `toward` (rad, + left; behind the robot) at REVERSE_SPEED, turning the rear onto it
    (at most BACK_TURN), where BACK_CHECK_M of that arc keeps the margin; else half that turn, none,
    or a little the other way (askew in a gap, the full turn swings a corner into its side, and the
    robot rocked where it stood: rooms 1); None: none of them does."""
    if points is None or not math.isfinite(toward):
        return None
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    want = max(-BACK_TURN, min(BACK_TURN, p.kp * _wrap(toward - math.pi)))
    t = np.linspace(0.0, BACK_CHECK_M / REVERSE_SPEED, 7)
    for bw in (want, want / 2.0, 0.0, -want / 4.0):
        if not len(pts) or _sweep_ok(pts, *_arc(-REVERSE_SPEED, bw, t), p):
            note = "backing towards the way on"
            return Steer(-REVERSE_SPEED, bw, toward, True, f"{why}: {note}" if why else note)
    return None


def _arc(vx: float, wz: float, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses (x, y, yaw; base frame now) along the arc of (vx, wz) at times `t`."""
    if abs(wz) < 1e-6:
        return vx * t, 0.0 * t, 0.0 * t
    th = wz * t
    return vx * np.sin(th) / wz, vx * (1.0 - np.cos(th)) / wz, th


def _back_away(pts: np.ndarray, wz: float, p: PlannerParams, n: int, why: str, walk: float = 0.0) -> Steer | None:
    """Out of a spot where the command is held: back away turning the way it wants to turn (`wz`, 0:
    straight) where that sweep is clear, as a driver reverses out of a tight spot (each back-away
    then gains heading: a straight one alone, followed by the same blocked walk, rocked the robot
    where it stood for ever); else straight back; else, with no room behind but a turn to make,
    straight on, no faster than it was walking (`walk`, m/s; room ahead to turn in later; a turn in
    place never becomes a walk), or the turn the other way round; None: nothing is clear (the guard holds it)."""
    zero, room = np.zeros(n), np.linspace(0.0, BACK_CHECK_M, n)
    if wz != 0.0:
        bw = math.copysign(BACK_TURN, wz)
        if _sweep_ok(pts, *_arc(-BACK_SPEED, bw, np.linspace(0.0, BACK_CHECK_M / BACK_SPEED, n)), p):
            return Steer(-BACK_SPEED, bw, math.pi, True, f"{why}: backing away, turning")
    if _sweep_ok(pts, -room, zero, zero, p):
        return Steer(-BACK_SPEED, 0.0, math.pi, True, f"{why}: backing away")
    if wz == 0.0:
        return None
    if walk > 0.0 and _sweep_ok(pts, room, zero, zero, p):
        return Steer(min(walk, BACK_SPEED), 0.0, 0.0, True, f"{why}, nor back: walking on straight to turn later")
    if _sweep_ok(pts, zero, zero, np.linspace(0.0, -math.copysign(TURN_SWEEP, wz), n), p):
        return Steer(0.0, -wz, -wz, True, f"{why}, nor back: turning the other way round")
    return _edge_out(pts, wz, p, n, why, walk)


def _edge_out(pts: np.ndarray, wz: float, p: PlannerParams, n: int, why: str, walk: float) -> Steer | None:
    """A route's turn wedged in (module docstring): the forward arc (no faster than `walk`, turning
    BACK_TURN either way, the wanted way first) whose EDGE_CHECK_M keeps the margin and ends with the
    most clearance, more than now; None: none does, or it may not walk (`walk` 0)."""
    if walk <= 0.0:
        return None
    v = min(walk, BACK_SPEED)
    t = np.linspace(0.0, EDGE_CHECK_M / v, 2 * n)
    now = float(_clearances(pts, np.zeros(1), np.zeros(1), np.zeros(1), p)[0])
    best: tuple[float, float] | None = None
    for w in (math.copysign(BACK_TURN, wz), -math.copysign(BACK_TURN, wz)):
        arc = _arc(v, w, t)
        if _sweep_ok(pts, *arc, p):
            end = float(_clearances(pts, arc[0][-1:], arc[1][-1:], arc[2][-1:], p)[0])
            if end > now + 1e-3 and (best is None or end > best[1]):
                best = (w, end)
    if best is None:
        return None
    return Steer(v, best[0], 0.0, True, f"{why}, nor back: edging out of a tight spot")
