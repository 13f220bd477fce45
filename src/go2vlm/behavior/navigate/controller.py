"""The navigator's controller: regulated pure pursuit (Nav2's RPP idea) on a route's waypoints, with
the footprint checked along the command's arc. Pure: a path, a pose and a scan in; a velocity out.

- The robot is projected onto the path (never behind the segment it reached last), and the carrot is
  the point `lookahead` further along it; the lookahead grows with speed (`lookahead_s` x speed,
  within `lookahead_min_m`..`lookahead_max_m`).
- A carrot more than `rotate_to_heading_deg` off the heading: turn in place towards it first (a
  doorway is walked into square-on, not cut at a slant), as fast as the turn's sweep keeps its
  clearance (a slower turn needs less). With no room to turn at all: back along the route where the
  carrot lies behind (`back_up_speed`); where it lies ahead, first creep straight on (`min_speed`:
  out of the doorway it stands in, to turn where it is clear); else back (at half that speed) or
  creep on while turning towards it, a driver's turn in a narrow lane; and with the carrot behind,
  last, straight on out of the doorway all the same. A driver's turn goes in legs (manoeuvre.py),
  each held for its length while it keeps its clearance, until the robot can turn to face the carrot
  (or faces it within `line_up_deg`).
- Otherwise the pure-pursuit arc through the carrot, at `max_linear` regulated down: by curvature
  (a radius under `min_radius_m` slows in proportion), by obstacles (the footprint nearer than
  `slow_near_m` to a scan point slows in proportion), and near the end (`approach_gain` x metres left),
  but never below `min_speed`.
- The arc for `horizon_s` ahead must keep the clearance that its speed needs (the one clearance rule
  that the planners and the guard keep, geometry/footprint.py `Clearance`: a few centimetres at a
  creep, more at speed, by the footprint's fastest point); if it does not, the same arc
  is tried at half and a quarter of the speed, then, the carrot more than `line_up_deg` off, it
  lines up with the route where it stands (the turn above: a doorway met a little askew sweeps a
  corner into the jamb on any arc), and only with no room for that either is the command `blocked`
  (zero): the progress checker and the recoveries
  take it from there. Where the footprint is already nearer than that
  (inside a doorway), an arc that brings it no nearer passes.
- A turn in place that a strategy asks for (`turn_in_place`: a look round, facing a target) is made
  the same way: at the asked rate or slower where its sweep keeps the clearance, else the driver's
  turn (`make_room`, towards the turn's side), else `blocked`.

The safety gate's collision guard still has the last word on every command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from go2vlm.behavior.navigate.manoeuvre import Leg, first_leg
from go2vlm.behavior.navigate.params import NavParams
from go2vlm.behavior.navigate.sweep import Rect, arc_clearance, fits
from go2vlm.geometry.footprint import Clearance

__all__ = ["Drive", "Leg", "Rect", "arc_clearance", "make_room", "project", "pursue", "turn_in_place"]


@dataclass(frozen=True)
class Drive:
    vx: float
    wz: float
    mode: str  # track | rotate | reverse | blocked
    note: str  # what regulated or held it ("" = nothing)
    index: int  # the path segment the robot is on
    remaining: float  # m along the path to its end
    leg: Leg | None = None  # a driver's turn's leg: hand it to the next `pursue`, which holds it


def project(path: np.ndarray, x: float, y: float, start: int = 0) -> tuple[int, np.ndarray, float]:
    """The segment (from `start` on) nearest (x, y), the nearest point on it, and the metres left
    along the path from there."""
    a, b = path[start:-1], path[start + 1 :]
    if len(a) == 0:
        return max(0, len(path) - 2), path[-1], 0.0
    ab = b - a
    L2 = np.maximum((ab**2).sum(axis=1), 1e-12)
    t = np.clip(((np.array((x, y)) - a) * ab).sum(axis=1) / L2, 0.0, 1.0)
    near = a + t[:, None] * ab
    i = int(np.argmin(np.hypot(near[:, 0] - x, near[:, 1] - y)))
    seg = np.sqrt(L2)
    rest = float(seg[i] * (1.0 - t[i]) + seg[i + 1 :].sum())
    return start + i, near[i], rest


def _carrot(path: np.ndarray, index: int, point: np.ndarray, lookahead: float) -> np.ndarray:
    """The point `lookahead` m further along the path than `point` (on segment `index`), or its end."""
    left, at = lookahead, point
    for j in range(index + 1, len(path)):
        step = float(np.hypot(*(path[j] - at)))
        if step >= left:
            return at + (path[j] - at) * (left / max(step, 1e-12))
        left -= step
        at = path[j]
    return path[-1]


def pursue(
    path: np.ndarray, pose: tuple[float, float, float], scan: np.ndarray | None, speed: float, p: NavParams,
    max_linear: float, max_angular: float, start: int = 0, fp: Rect | None = None, rule: Clearance | None = None,
    held: Leg | None = None, now: float = 0.0,
) -> Drive:  # fmt: skip
    """The command that follows `path` ((M, 2) world waypoints) from `pose` (x, y, yaw); `speed` the
    robot's speed now (m/s, for the lookahead); `scan` obstacle points in the base frame (None: no
    fresh scan, no checks here: the guard's blind cap holds it); `held` the last step's `Drive.leg`, and
    `now` the caller's time, which ends it."""
    rule, fp = rule or Clearance(), fp or Rect()
    x, y, yaw = pose
    index, point, remaining = project(path, x, y, start)
    lookahead = min(max(p.lookahead_s * abs(speed), p.lookahead_min_m), p.lookahead_max_m)
    cx, cy = _carrot(path, index, point, lookahead) - (x, y)
    c, s = math.cos(yaw), math.sin(yaw)
    lx, ly = c * cx + s * cy, -s * cx + c * cy
    alpha = math.atan2(ly, lx)
    pts = scan if scan is not None else np.zeros((0, 2))
    now_clear = arc_clearance(pts, 0.0, 0.0, 0.0, fp)
    d2 = lx * lx + ly * ly
    kappa = 2.0 * ly / max(d2, 1e-9)

    def keeps(vx: float, wz: float, duration: float = p.horizon_s) -> bool:
        return fits(pts, vx, wz, duration, fp, rule, now_clear)

    def turn() -> Drive:
        """Face the carrot where it stands, when the whole turn keeps the clearance; no room: a driver's
        turn in a narrow lane (`make_room`)."""
        fast = min(max(p.rotate_gain * abs(alpha), p.min_turn_rate), max_angular)
        w = _turn_rate(pts, math.copysign(fast, alpha), abs(alpha), p, fp, rule, max_angular, now_clear)
        if w is not None:
            return Drive(0.0, w, "rotate", "turning to the route", index, remaining)
        return make_room(pts, (lx, ly), kappa, p, fp, rule, max_linear, max_angular, held, now, index, remaining,
                         now_clear)  # fmt: skip

    # A held leg runs on, even where the route's arc would keep again: cut short, the arc walked
    # straight back to where it failed, and the robot rocked between the two.
    turning = held is not None and now < held.until and abs(alpha) > math.radians(p.line_up_deg)
    if abs(alpha) > math.radians(p.rotate_to_heading_deg) or turning:
        return turn()
    v, notes = max_linear, []
    if abs(kappa) > 1e-9 and 1.0 / abs(kappa) < p.min_radius_m:
        v *= (1.0 / abs(kappa)) / p.min_radius_m
        notes.append("curve")
    if now_clear < p.slow_near_m:
        v *= max(now_clear, 0.0) / p.slow_near_m
        notes.append("near an obstacle")
    if v > p.approach_gain * remaining:
        v = p.approach_gain * remaining
        notes.append("arriving")
    v = min(max(v, p.min_speed), max_linear)
    wz = v * kappa
    if abs(wz) > max_angular:  # keep the arc: slow down rather than turn wider
        v, wz = v * max_angular / abs(wz), math.copysign(max_angular, wz)
    for scale in (1.0, 0.5, 0.25):
        if keeps(v * scale, wz * scale):
            if scale < 1.0:
                notes.append("clearance")
            return Drive(v * scale, wz * scale, "track", ", ".join(notes), index, remaining)
    # The arc sweeps a corner into the jamb (a door met a little askew): turn square to the route
    # first, where it stands, as a driver lines up with a narrow gate.
    lined = turn() if abs(alpha) > math.radians(p.line_up_deg) else None
    if lined is not None and lined.mode != "blocked":
        return replace(lined, note=f"the route's arc does not keep its clearance: {lined.note}")
    return Drive(0.0, 0.0, "blocked", "the route's arc does not keep its clearance", index, remaining)


def _turn_rate(pts: np.ndarray, wz: float, angle: float, p: NavParams, fp: Rect, rule: Clearance, max_angular: float,
               here: float) -> float | None:  # fmt: skip
    """The fastest of `wz`, half of it and `min_turn_rate` (a slower turn needs less room; none faster
    than `wz`) whose sweep keeps the clearance for `horizon_s` and for the whole `angle` (rad) it is to
    turn; None: none."""
    fast = min(abs(wz), max_angular)
    slow = min(p.min_turn_rate, fast)  # never faster than asked
    for rate in sorted({fast, max(fast / 2, slow), slow}, reverse=True):
        w = math.copysign(rate, wz)
        spans = {p.horizon_s, max(p.horizon_s, angle / rate)} if rate > 0 else set()
        if spans and all(fits(pts, 0.0, w, t, fp, rule, here) for t in spans):
            return w
    return None


def make_room(
    pts: np.ndarray, carrot: tuple[float, float], kappa: float, p: NavParams, fp: Rect, rule: Clearance,
    max_linear: float, max_angular: float, held: Leg | None, now: float, index: int = 0, remaining: float = 0.0,
    here: float | None = None,
) -> Drive:  # fmt: skip
    """No room to turn in place towards `carrot` (base frame): a driver's turn, in legs (manoeuvre.py),
    each held for the rest of its length while that keeps its room (the search checked it whole).
    `kappa`: the curvature of the way back along a route (0: none); `here`: the footprint's clearance
    where it stands, when the caller has it."""
    if here is None:
        here = arc_clearance(pts, 0.0, 0.0, 0.0, fp)

    def keeps(vx: float, wz: float, duration: float = p.horizon_s) -> bool:
        return fits(pts, vx, wz, duration, fp, rule, here)

    def leg(held: Leg) -> Drive:
        mode = "reverse" if held.vx < 0 else "track"
        return Drive(held.vx, held.wz, mode, f"no room to turn: {held.how}", index, remaining, held)

    if held is not None and now < held.until and keeps(held.vx, held.wz, held.until - now):
        return leg(held)
    alpha = math.atan2(carrot[1], carrot[0])
    slow = min(p.min_turn_rate, max_angular)
    side, slow_back = math.copysign(slow, alpha), -p.back_up_speed
    behind = abs(alpha) > math.pi / 2
    v, wz = slow_back, slow_back * kappa
    if abs(wz) > max_angular:
        v, wz = v * max_angular / abs(wz), math.copysign(max_angular, wz)
    # The route lies behind: back along it; but between the legs of a driver's turn, its next leg first
    # (the backing undid the leg just driven: forward a leg, back to where it began, and so on).
    back: Drive | None = None
    if behind and keeps(v, wz):
        back = Drive(v, wz, "reverse", "no room to turn: backing along the route", index, remaining)
        if not (held is not None and held.more):
            return back
    found = first_leg(pts, carrot, p, fp, rule, max_linear, max_angular)
    if found is not None:
        how = f"leg 1 of {found[2]} to where it can turn"
        return leg(Leg(found[0], found[1], now + p.turn_leg_s, how, found[2] > 1))
    if back is not None:
        return back
    # No pose to turn from within reach: creep on straight, out of the doorway it stands in, to turn
    # where it is clear (first where the carrot lies ahead, last where behind); back or creep on
    # while it turns towards it.
    creep = min(p.min_speed, max_linear)
    on = (creep, 0.0, "on straight to turn where it is clear")
    moves = [(slow_back / 2, side, "backing while it turns"), (creep, side, "creeping while it turns")]
    moves = [*moves, on] if behind else [on, *moves]
    for v, wz, how in moves:
        if abs(wz) > max_angular:
            v, wz = v * max_angular / abs(wz), math.copysign(max_angular, wz)
        if keeps(v, wz):
            return leg(Leg(v, wz, now + p.turn_leg_s, how))
    return Drive(0.0, 0.0, "blocked", "no room to turn", index, remaining)


def turn_in_place(
    wz: float, scan: np.ndarray | None, p: NavParams, max_linear: float, max_angular: float,
    fp: Rect | None = None, rule: Clearance | None = None, held: Leg | None = None, now: float = 0.0,
    angle: float = math.pi / 2,
) -> Drive:  # fmt: skip
    """A turn in place at `wz` (rad/s) that a strategy asks for (a look round, facing a target), `angle`
    (rad) still to turn, a quarter turn at most counted: as it is, or slower, where the sweep of that
    much keeps the clearance; else a driver's turn to where it can (`make_room`, towards that
    heading), so that a turn checked only a moment ahead does not stop a few degrees on and ask for
    another leg; else `blocked`. `scan` and `held` as `pursue`'s."""
    rule, fp = rule or Clearance(), fp or Rect()
    pts = scan if scan is not None else np.zeros((0, 2))
    if wz == 0.0 or not math.isfinite(wz):
        return Drive(0.0, 0.0, "blocked", "no turn", 0, 0.0)
    a = min(abs(angle), math.pi / 2) if math.isfinite(angle) else math.pi / 2
    here = arc_clearance(pts, 0.0, 0.0, 0.0, fp)
    if held is None or now >= held.until:
        w = _turn_rate(pts, wz, a, p, fp, rule, max_angular, here)
        if w is not None:
            return Drive(0.0, w, "rotate", "", 0, 0.0)
    toward = (math.cos(a), math.copysign(math.sin(a), wz))  # the heading it turns to, 1 m out
    return make_room(pts, toward, 0.0, p, fp, rule, max_linear, max_angular, held, now, here=here)
