"""Navigation to a remembered place: go to / look for on the object memory's remembered objects
while the tracker does not confirm the target, once a tracker report has said how wide the camera's
view is. Pure, timestamp-driven.

- The target is the most confident remembered object of the goal's label (at least
  `memory_min_confidence`, not given up: a given-up one counts again once it is seen again).
- Go to turns to it, then approaches its remembered place with the local planner, but only once the
  memory confirms it (at least `memory_confirm_confidence`); less sure, it holds still facing it and
  looks. A place it cannot see straight on the map (a wall or unknown space on the straight line:
  another room) is walked to along the global route (route.RouteTo), through the doorway. At its
  remembered place it stops and looks: `reached` only when an answer about a frame taken there placed
  it within reach (stop_distance_m + distance_tolerance_m + `reach_slack_m`). A place with no route
  on the map whose straight way stays blocked UNREACHABLE_S is given up (a misplaced memory). One in
  sight that the local planner makes no headway to is walked to along the route (headway.py).
- Look for turns to face it and ends `found` when an answer about a frame taken facing it saw it;
  one out of sight on the map is first walked towards along the global route until it is in sight
  (not while the tracker confirmed it within `SEEN_LATELY_S`: the camera saw it, whatever the map says).
- `confirm_looks` answered looks without it: that object is given up and the search goes on.
"""

from __future__ import annotations

import math

import numpy as np

from go2vlm.behavior.control import approach_command, face_command
from go2vlm.behavior.strategies.base import Command, Context
from go2vlm.behavior.strategies.headway import Headway
from go2vlm.behavior.strategies.route import RouteTo, follow_waypoint
from go2vlm.world.labels import label_fits
from go2vlm.world.objects_msg import Remembered

__all__ = ["SEEN_LATELY_S", "UNREACHABLE_S", "GoToRemembered", "relative"]

SEEN_LATELY_S = 5.0  # look for: the tracker confirmed it this recently: it is in sight, whatever the map says
# go to: no route on the map and the straight way blocked this long: given up (`remembered_unreachable`);
# a teddy bear placed 0.15 m beyond the outer wall by bad ranges held the robot at that wall for 100 s,
# 1.2 m from the bear, which a look round would have seen (rooms 14)
UNREACHABLE_S = 15.0


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
        self.router = RouteTo()
        self.headway = Headway()
        self.unreachable_since: float | None = None  # go to: no route, the straight way blocked, since

    def reset(self, now: float) -> None:
        self.given_up.clear()
        self.failed_looks = 0
        self.router.reset()
        self.headway.reset()
        self.unreachable_since = None

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
        self.unreachable_since = None
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
        seen_lately = ctx.last_seen is not None and now - ctx.last_seen < SEEN_LATELY_S
        if goal.kind == "look_for" and not seen_lately:  # out of sight on the map (another room): walk to where it is
            via = self.router.next(ctx, (o.x, o.y), ap.stop_distance + o.radius, now)
            ctx.route = self.router.route
            if via is not None:
                ctx.look.forget()
                b, d, rest = via
                reason = f"walking to where {where} can be seen, {rest:.1f} m along the route (memory)"
                return follow_waypoint(ctx, b, d, rest, now, "aligning", reason, basis="memory")
        if goal.kind == "go_to" and o.confidence >= p.memory_confirm_confidence and not at_place:
            # Walk: the approach turns before it walks, the planner steers round what is in the way.
            ctx.look.forget()
            self.failed_looks = 0
            via = self.router.next(ctx, (o.x, o.y), ap.stop_distance + o.radius, now)
            ctx.route = self.router.route
            if via is not None:  # out of sight on the map: along the global route
                b, d, rest = via
                reason = f"{where}, {rest:.1f} m along the route (memory, confidence {o.confidence:.2f})"
                return follow_waypoint(ctx, b, d, rest, now, "approaching", reason, basis="memory")
            out = self.headway.walk(ctx, (o.x, o.y), ap.stop_distance + o.radius, now, where, basis="memory")
            if out is not None:  # in sight, and no headway: along the global route all the same
                return out
            st = ctx.avoid(vx, wz, ap, (bearing, surface), now)
            if st is None or not st.blocked or not self.router.reason:
                self.unreachable_since = None
            elif self.unreachable_since is None:
                self.unreachable_since = now
            elif now - self.unreachable_since >= UNREACHABLE_S:
                self.give_up(ctx, o, "remembered_unreachable")
                return None
            if st is not None and st.blocked:
                return Command.detour(st, f"{where}, {surface:.2f} m (memory): {st.note}", basis="memory")
            reason = f"{where}, {surface:.2f} m away (memory, confidence {o.confidence:.2f})"
            if self.router.reason:  # out of sight and no route on the map: straight, the guard has the last word
                reason += f"; no route on the map ({self.router.reason})"
            return Command(vx, wz, "approaching", reason, basis="memory")
        state = "aligning" if goal.kind == "look_for" else "approaching"
        facing = p.planner.step if goal.kind == "look_for" else 0.25
        if abs(bearing) > facing:  # turn to it (looks are only taken facing it)
            ctx.look.forget()
            return Command(0.0, face_command(bearing, ap), state, f"turning to {where}")
        # Hold still facing it (not sure enough to walk, or at its place) and look.
        look = ctx.look_at(key, now)
        if look == "answered":  # an answer about this view came back without it
            if self._looked_without(ctx, o):
                return None
        elif look == "timeout":
            ctx.look.forget()  # no answer at all: look again (the search's timeout still runs)
        why = "confirming it is there" if at_place or goal.kind == "look_for" else "looking again before walking"
        return Command.still(state, f"holding still facing {where} ({surface:.2f} m): {why}")
