"""Approach a target the tracker confirms: go to (walk, stop `stop_distance_m` from its surface:
`reached`), look for (turn until it is centred: `found`; confirmed in view but not centred after
`align_found_s`, the turn held by the gate in a doorway: `found` all the same, saying how far off),
follow (keep `follow_distance_m`).

A go to hands the target's place (the memory's place for it, else its last confirmed one) to the
navigator (behavior/navigate/) all the way wherever there is a map and a pose: its route, its
controller, its progress checker and its recoveries, the same as for a remembered place or a
frontier. Once the navigator is there (near the place and in sight of it on the map), the approach
law closes the last of the distance by the frame's range; where the fresh scan shows that last bit
blocked (the object against furniture or a wall), the go to is `reached` as near as the way lets it,
within `reach_slack_m` of the stop distance (the remembered place's rule), rather than going round
an obstacle it is already beside; where the local planner has a free way that keeps it in view (a
door's jamb beside the way), the way lets it nearer, and the go to takes it. Out of view on the
way, it walks on to the last confirmed place for up to `detour_memory_s`.

Follow, and a go to without a map, steer with the approach law; the local planner steers round what
the fresh scan shows in the way (`detouring`), and out of view during such a detour it carries on
round the obstacle towards the target's last confirmed place for up to `detour_memory_s`, only while
the direct way is blocked. The laws are behavior/control.py's. Pure."""

from __future__ import annotations

import math

from go2vlm.behavior.control import align_command, approach_command
from go2vlm.behavior.strategies.base import Command, Context
from go2vlm.world.poses import wrap_angle

__all__ = ["Approach"]


class Approach:
    """The tracked target's strategy: `step` answers while the tracker confirms it, or while a detour
    hides it; None otherwise."""

    def __init__(self) -> None:
        self.routed = False  # the navigator is walking the go to (its other state is the context's track)
        self.there = False  # ... and it said it is there: the approach law closes the rest

    def reset(self, now: float) -> None:
        self.routed = self.there = False

    def step(self, ctx: Context, now: float) -> Command | None:
        if ctx.confirmed(now):
            return self.tracked(ctx, now)
        return self.detour_unseen(ctx, now)

    def tracked(self, ctx: Context, now: float) -> Command:
        goal, s = ctx.goal, ctx.sighting
        assert goal is not None and s is not None
        label = ctx.label
        ap = ctx.approach_params()
        if goal.kind == "look_for":
            wz, centred = align_command(s.x, ap)
            if centred:
                return Command.still("found", f"the {label} is straight ahead{ctx.where()}")
            since = ctx.align_since = now if ctx.align_since is None else ctx.align_since
            wait = ctx.params.align_found_s
            if now - since > wait and abs(s.x) < 1.0:  # the turn held (a doorway), or it flickers
                off = math.degrees(s.bearing) if math.isfinite(s.bearing) else 0.0
                return Command.still("found", f"the {label} is in view, {abs(off):.0f} deg to the "
                                     f"{'left' if off > 0 else 'right'} (not centred in {wait:g} s)"
                                     f"{ctx.where()}")  # fmt: skip
            off = abs(s.bearing) if math.isfinite(s.bearing) else math.pi / 2
            return ctx.turn(wz, "aligning", "target in view: turning to face it", now, angle=off)
        follow = goal.kind == "follow"
        dist = ctx.base_distance(now)
        method = ctx.ranged_by  # the tracker's, or what ctx.base_distance took instead (lidar, memory)
        vx, wz, reached = approach_command(s.x, dist, ap)
        how = "unknown" if dist is None else f"{dist:.2f} m ({method})"
        if reached and not follow:
            if ctx.seen_since is not None and now - ctx.seen_since < ctx.params.reach_settle_s:
                return Command.still("approaching", f"{dist:.2f} m from the {label} ({method}): just seen, "
                                     "waiting for the memory's place")  # fmt: skip
            return Command.still("reached", f"{dist:.2f} m from the {label} ({method})")
        if not follow and (out := self._route(ctx, ap.stop_distance, f"target at {how}", now)) is not None:
            return out
        self.routed = False
        rel = ctx.seen_in_base(s)
        if method == "memory" and dist is not None:  # what the tracker ranged stands in the way: go round it
            rel = (dist * math.cos(s.bearing), dist * math.sin(s.bearing))
        if rel is not None and not reached:
            bearing = math.atan2(rel[1], rel[0])
            st = ctx.avoid(vx, wz, ap, (bearing, math.hypot(*rel)), now)
            if st is not None and st.blocked:
                slack = ap.tolerance + ctx.params.reach_slack_m
                # a free way that keeps it in view (past a jamb, say) is a way nearer: the way lets it
                nearer = st.way and ctx.view is not None and abs(wrap_angle(st.heading - bearing)) < ctx.view / 2
                if not follow and self.there and not nearer and dist is not None and dist - ap.stop_distance <= slack:
                    return Command.still("reached", f"{dist:.2f} m from the {label} ({method}): as near as the "
                                         f"way lets it ({st.note})")  # fmt: skip
                return ctx.detour(st, f"target at {how}: {st.note}", now)
        if follow:
            return Command(vx, wz, "tracking", "target in view: following")
        return Command(vx, wz, "approaching", f"target at {how}")

    @staticmethod
    def _place(ctx: Context, stop: float) -> tuple[tuple[float, float], float, float] | None:
        """Where the go to goes, how near counts as there, and the target's own extent round it: the
        memory's place for the target (its centre, within `stop` of its surface), else its last
        confirmed place (its near side)."""
        o = ctx.target_obj
        if o is not None:
            return (o.x, o.y), stop + o.radius, o.radius
        if ctx.goal_xy is not None:
            return ctx.goal_xy, stop, 0.0
        return None

    def _route(self, ctx: Context, stop: float, why: str, now: float) -> Command | None:
        """The navigator's command towards the target's place; None: no map, pose or place, or the
        navigator is there (or gave the place up): the approach law steers."""
        place, pose = self._place(ctx, stop), ctx.fresh_pose(now)
        if place is None or pose is None or ctx.costmap is None:
            return None
        return self._walk(ctx, place, now, f"{why}, with the navigator")

    def _walk(
        self, ctx: Context, place: tuple[tuple[float, float], float, float], now: float, why: str
    ) -> Command | None:
        """The navigator's step to `place` (`_place`'s); None (and not `routed`) once it is there or
        gives the place up: the approach, or the search, has its turn."""
        (xy, reach, body), planner = place, ctx.place_planner
        nav = ctx.navigate(xy, reach, now, planner, body)
        self.routed = nav.status in ("moving", "recovering", "waiting")
        self.there = nav.status == "arrived"
        if not self.routed:
            return None
        return Command(nav.vx, nav.wz, "approaching", f"{why} ({nav.reason})", note=nav.note, navigated=True)

    def detour_unseen(self, ctx: Context, now: float) -> Command | None:
        """Out of view during a detour: on round the obstacle while the direct way stays blocked; a
        free way turns back towards where it was. On the navigator's route, on along it to where it
        was. None: the detour is over (no detour, look for, the track too old, no pose or no scan)."""
        p, goal, last = ctx.params, ctx.goal, ctx.last_seen
        if goal is None or goal.kind == "look_for":
            return None
        if self.routed:
            place = self._place(ctx, p.stop_distance_m)
            if last is None or now - last > p.detour_memory_s or place is None:
                self.routed = False
                return None
            return self._walk(ctx, place, now, f"the {ctx.label} is out of view: walking on to where it was seen")
        detour_t = ctx.navigator.steering.detour_t
        if last is None or detour_t is None or detour_t < last - p.lost_timeout_s:
            return None
        if now - last > p.detour_memory_s:
            return None
        rel = ctx.last_place_in_base(now)
        if rel is None:
            return None
        bearing, dist = rel
        turn = max(-p.max_angular, min(p.max_angular, p.planner.kp * bearing))
        st = ctx.avoid(0.0, turn, ctx.approach_params(), rel, now)
        if st is None:
            return None
        if st.blocked:
            return ctx.detour(st, f"the {ctx.label} is out of view: {st.note}", now)
        if abs(bearing) < p.planner.step:
            return None  # facing where it was, and still not seen: lost, then search
        reason = f"turning back towards where the {ctx.label} was last seen ({dist:.1f} m)"
        return ctx.turn(turn, "detouring", reason, now, note="turning back towards the target", angle=abs(bearing))
