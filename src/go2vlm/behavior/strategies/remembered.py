"""Navigation to a remembered place: go to / look for on the object memory's remembered objects
while the tracker does not confirm the target, once a tracker report has said how wide the camera's
view is. Pure, timestamp-driven.

- The target is the most confident remembered object of the goal's label (at least
  `memory_min_confidence`, not given up: a given-up one counts again once it is seen again).
- Go to walks to its remembered place, but only once the memory confirms it (at least
  `memory_confirm_confidence`); less sure, it holds still facing it and looks. With a costmap the
  place is handed to the navigator (behavior/navigate/: route, controller, progress, recoveries),
  within reach of it (stop_distance_m + its radius + distance_tolerance_m); a place the navigator
  gives up on (no route: a misplaced memory beyond a wall; or no progress after every recovery) is
  given up (`remembered_unreachable`). Without a costmap: turn, then walk straight with the local
  planner, the guard having the last word. The navigator there short of the stop distance, the last
  bit is walked straight the same way, and like a route it must near (by `distance_tolerance_m`
  within the navigator's `progress_s`): else it is held (`last_bit_held`) and looks from there
  before it walks again. At its remembered place it turns to face it, stops and
  looks: `reached` only when an answer about a frame taken there placed it within reach
  (stop_distance_m + distance_tolerance_m + `reach_slack_m`). A look begun is held until answered
  while the place stays within that reach: its range flickers about the stop distance's edge.
- Look for turns to face it and ends `found` when an answer about a frame taken facing it saw it.
- One out of sight on the map (a look for's or a go to's) is first walked towards with the navigator
  until it is in sight: a look through a wall neither confirms it nor counts against it, and a scan
  return on its bearing is the wall, not its surface (not while the tracker confirmed it within
  `SEEN_LATELY_S`: the camera saw it, whatever the map says).
- `confirm_looks` answered looks without it: that object is given up and the search goes on; so is
  a go to's whose looks saw it from short of its reach `confirm_looks` times in a row, each no nearer
  than the nearest before (`remembered_no_nearer`: the way to it comes no nearer).
"""

from __future__ import annotations

import math

import numpy as np

from go2vlm.behavior.control import approach_command, face_command
from go2vlm.behavior.navigate import in_view, line_of_sight
from go2vlm.behavior.navigate.progress import Progress
from go2vlm.behavior.strategies.base import Command, Context
from go2vlm.world.labels import label_fits
from go2vlm.world.objects_msg import Remembered

__all__ = ["SEEN_LATELY_S", "GoToRemembered", "relative"]

SEEN_LATELY_S = 5.0  # look for: the tracker confirmed it this recently: it is in sight, whatever the map says


def relative(ctx: Context, o: Remembered, now: float) -> tuple[float, float] | None:
    """(bearing from the base, base centre -> the object's surface) of a remembered object, with a
    fresh pose; None without one. Where the fresh scan has returns on it (within its bearings, no
    nearer than its remembered near side less 0.4 m), the nearest one is its surface: the lidar
    knows a box's face better than the memory knows its size."""
    pose = ctx.fresh_pose(now)
    if pose is None:
        return None
    dx, dy = o.x - pose.x, o.y - pose.y
    bearing = math.atan2(math.sin(math.atan2(dy, dx) - pose.yaw), math.cos(math.atan2(dy, dx) - pose.yaw))
    centre = math.hypot(dx, dy)
    surface = centre - o.radius
    pts = ctx.fresh_scan(now)
    if pts is not None and len(pts) and centre > o.radius:
        off = np.abs(np.angle(np.exp(1j * (np.arctan2(pts[:, 1], pts[:, 0]) - bearing))))
        d = np.hypot(pts[:, 0], pts[:, 1])
        on = (off <= math.asin(min(1.0, o.radius / centre))) & (d <= centre) & (d >= surface - 0.4)
        if on.any():
            surface = float(d[on].min())
    return bearing, surface


class GoToRemembered:
    """The remembered-place strategy; `pick` chooses the object, `step` drives to / looks at it."""

    def __init__(self) -> None:
        self.given_up: dict[str, float] = {}  # remembered object id -> its last_seen when given up
        self.failed_looks = 0
        self.closing = Progress()  # the last bit's nearing, the navigator's rule (navigate/progress.py)
        self.closing_to: str | None = None  # ... to this object, walked since the navigator was there
        self.held: str | None = None  # the object whose last bit came no nearer: look before walking again
        self.stood: tuple[str, float, float] | None = None  # (object, nearest surface, look) seen from short of it
        self.stood_again = 0  # looks in a row that saw it from no nearer than that

    def reset(self, now: float) -> None:
        self.given_up.clear()
        self.failed_looks = 0
        self.closing.new_goal()
        self.closing_to = self.held = self.stood = None
        self.stood_again = 0

    def pick(self, ctx: Context) -> Remembered | None:
        """The most confident remembered object of the goal's label worth going to (not given up)."""
        p, label = ctx.params, ctx.label
        if not p.use_memory or not ctx.memory or not label:
            return None
        best: tuple[int, float] | None = None
        pick = None
        for o in ctx.memory:
            fit = label_fits(label, o.label)
            if fit == 0 or o.confidence < p.memory_min_confidence:
                continue
            if o.id in self.given_up and o.last_seen <= self.given_up[o.id]:
                continue
            key = (fit, o.confidence)
            if best is None or key > best:
                best, pick = key, o
        return pick

    def give_up(self, ctx: Context, o: Remembered, counter: str) -> None:
        """Go no more to `o` (unless it is seen again): the next pick, or the search, takes over."""
        self.given_up[o.id] = o.last_seen
        ctx.counters[counter] += 1
        if ctx.target_obj is o:
            ctx.target_obj = None

    def _looked_without(self, ctx: Context, o: Remembered) -> bool:
        """After an answered look that did not see `o`: count it; True when `o` is given up."""
        self.failed_looks += 1
        ctx.look.forget()  # look again: a new look waits for a newer frame
        if self.failed_looks >= ctx.params.confirm_looks:
            self.give_up(ctx, o, "remembered_given_up")
            self.failed_looks = 0
            return True
        return False

    def step(self, ctx: Context, now: float) -> Command | None:
        """Go to / look for `ctx.target_obj` (chosen by `pick`); None: no remembered target, no view
        or no fresh pose, or it was just given up (search)."""
        p, goal, o, view, label = ctx.params, ctx.goal, ctx.target_obj, ctx.view, ctx.label
        if goal is None or goal.kind not in ("go_to", "look_for") or o is None or view is None:
            return None
        rel = relative(ctx, o, now)
        if rel is None:
            return None
        bearing, surface = rel
        where = f"the remembered {o.label} at ({o.x:.2f}, {o.y:.2f})"
        ap = ctx.approach_params()
        vx, wz, at_place = approach_command(-bearing / (view / 2.0), surface, ap)
        key = (o.id, "look")
        if ctx.look.key == key:  # looking at it: has an answer about a frame taken since the stop seen it?
            seen_here = o.last_seen >= ctx.look.still_since
            if goal.kind == "look_for" and seen_here:
                return Command.still("found", f"the {label} is straight ahead, {where} ({surface:.2f} m)")
            if goal.kind == "go_to" and seen_here and surface - ap.stop_distance <= ap.tolerance + p.reach_slack_m:
                return Command.still("reached", f"{surface:.2f} m from the {label}: an answer about this view "
                                     f"placed it here ({where})")  # fmt: skip
            if goal.kind == "go_to" and seen_here and self._no_nearer_looks(ctx, o, surface):
                return None
            if seen_here and self.held == o.id:  # seen from as near as it got: the last bit afresh
                self.held = None
        seen_lately = ctx.last_seen is not None and now - ctx.last_seen < SEEN_LATELY_S
        reach = ap.stop_distance + o.radius + ap.tolerance  # the navigator's "there": its centre this near
        if not seen_lately and ctx.costmap is not None and ctx.pose is not None:
            # out of sight on the map (another room, behind a wall): no look from here can see it, so
            # none counts for or against it, and a scan return on its bearing is the wall's; walk to
            # where it is until it is in sight
            cm, at, planner = ctx.costmap, (ctx.pose.x, ctx.pose.y), ctx.place_planner
            sight = line_of_sight(cm, at, (o.x, o.y), planner, reach) and in_view(cm, at, (o.x, o.y), planner, o.radius)
            if not sight:
                state = "aligning" if goal.kind == "look_for" else "approaching"
                out = self._walk(ctx, o, reach, now, state, f"walking to where {where} can be seen")
                if out is not None or ctx.target_obj is None:
                    return out
        # A look begun at its place is answered before it walks again, while within the reach slack:
        # the range flickers about the stop distance's edge, and each flicker out forgot the look.
        # So is one begun where the last bit came no nearer (`held`).
        looking = ctx.look.key == key and (surface - ap.stop_distance <= ap.tolerance + p.reach_slack_m
                                           or self.held == o.id)  # fmt: skip
        if goal.kind == "go_to" and o.confidence >= p.memory_confirm_confidence and not at_place and not looking:
            ctx.look.forget()
            self.failed_looks = 0
            mapped = ctx.costmap is not None
            if mapped:
                out = self._walk(ctx, o, reach, now, "approaching", f"{where} (memory, confidence {o.confidence:.2f})")
                if out is not None or ctx.target_obj is None:
                    return out
            # No map, or the navigator is there (near its route's end) short of the stop distance: turn,
            # then walk the last bit straight; the local planner steers round what the scan shows.
            st = ctx.avoid(vx, wz, ap, (bearing, surface), now)
            held = mapped and self._no_nearer(ctx, o, surface, now)  # the guard holds what the planner passed
            if not held and (st is None or not st.blocked):
                why = "the last bit" if mapped else "no map"
                reason = f"{where}, {surface:.2f} m away (memory, confidence {o.confidence:.2f}); {why}"
                return Command(vx, wz, "approaching", reason, basis="memory")
            if not mapped and st is not None:
                return ctx.detour(st, f"{where}, {surface:.2f} m (memory): {st.note}", now, basis="memory")
            # blocked, or no nearer, with a map: as near as the way lets it; look (below)
        state = "aligning" if goal.kind == "look_for" else "approaching"
        facing = p.planner.step if goal.kind == "look_for" else 0.25
        if abs(bearing) > facing:  # turn to it (looks are only taken facing it)
            ctx.look.forget()
            return ctx.turn(face_command(bearing, ap), state, f"turning to {where}", now, angle=abs(bearing))
        # Hold still facing it (not sure enough to walk, or at its place) and look.
        look = ctx.look_at(key, now)
        if look == "answered":  # an answer about this view came back without it
            self.held = None
            if self._looked_without(ctx, o):
                return None
        elif look == "timeout":
            ctx.look.forget()  # no answer at all: look again (the search's timeout still runs)
        why = "confirming it is there" if at_place or goal.kind == "look_for" else "looking again before walking"
        return Command.still(state, f"holding still facing {where} ({surface:.2f} m): {why}")

    def _no_nearer_looks(self, ctx: Context, o: Remembered, surface: float) -> bool:
        """A look saw `o` from `surface` m, short of its reach (once a look): was it no nearer (by
        `distance_tolerance_m`) than the nearest such look before? `confirm_looks` of them in a row:
        the way to it comes no nearer (walked, held, looked, walked again), and it is given up
        (`remembered_no_nearer`). A mug behind a coffee table's corner was looked at from 1.24 m,
        walked to and looked at again for 130 s."""
        since = ctx.look.still_since
        if self.stood is not None and self.stood[0] == o.id and self.stood[2] == since:
            return False  # this look is counted
        nearest = self.stood[1] if self.stood is not None and self.stood[0] == o.id else math.inf
        self.stood_again = self.stood_again + 1 if surface > nearest - ctx.params.distance_tolerance_m else 0
        self.stood = (o.id, min(nearest, surface), since)
        if self.stood_again < ctx.params.confirm_looks:
            return False
        self.give_up(ctx, o, "remembered_no_nearer")
        self.stood, self.stood_again = None, 0
        return True

    def _no_nearer(self, ctx: Context, o: Remembered, surface: float, now: float) -> bool:
        """Has the last bit to `o` come no nearer (by `distance_tolerance_m`) within the navigator's
        `progress_s`? Then it is `held`: it looks from there before it walks again. A walk the local
        planner passed (the object's own surroundings are the goal to it), the gate's guard held at
        zero, and the robot stood by a mug for 160 s."""
        if self.held == o.id:
            return True
        if self.closing_to != o.id:  # a last bit begins: its clock starts now
            self.closing.new_goal()
            self.closing_to = o.id
        self.closing.to_go(surface, now, ctx.params.distance_tolerance_m)
        t = self.closing.neared_t
        if t is None or now - t < ctx.params.nav.progress_s:
            return False
        self.held, self.closing_to = o.id, None
        ctx.counters["last_bit_held"] += 1
        return True

    def _walk(self, ctx: Context, o: Remembered, reach: float, now: float, state: str, why: str) -> Command | None:
        """The navigator's step to `o`'s place; None: it is there (the caller faces it and looks), or it
        gave the place up (`o` given up, `ctx.target_obj` None: the search goes on)."""
        nav = ctx.navigate((o.x, o.y), reach, now, ctx.place_planner, o.radius)
        if nav.status == "arrived":
            return None
        self.closing_to = None  # walking with the navigator: a later last bit starts afresh
        if nav.status == "failed":
            self.give_up(ctx, o, "remembered_unreachable")
            ctx.navigator.reset()
            return None
        return Command(nav.vx, nav.wz, state, f"{why}: {nav.reason}", note=nav.note, basis="memory", navigated=True)
