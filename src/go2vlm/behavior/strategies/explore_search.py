"""The search that leaves the room, as the mission's SearchStrategy (strategies/base.py): the
Explorer (strategies/explore.py) says where to walk next, the navigator walks there, and this looks
around at each frontier. Pure, timestamp-driven."""

from __future__ import annotations

import math
from dataclasses import replace

from go2vlm.behavior.control import search_command
from go2vlm.behavior.strategies.base import Command, Context
from go2vlm.behavior.strategies.explore import ExploreParams, Explorer
from go2vlm.behavior.strategies.search import TurnAndLook
from go2vlm.world.poses import wrap_angle

__all__ = ["DEFAULT_VIEW", "Explore"]

DEFAULT_VIEW = math.radians(73.0)  # the head camera's, until a tracker report has said


# -- the search strategy ------------------------------------------------------------------------
class Explore:
    """The search that leaves the room: a SearchStrategy (strategies/base.py) over the Explorer,
    asked once turn-and-look is exhausted. Walks to the chosen frontier with the navigator
    (behavior/navigate/), looks around there
    (search.TurnAndLook's stop and look with slow answers, else a continuous turn at
    `search_yaw_rate` the short way round to the free space in sight that the camera has not looked
    at; it ends when none is left, after a whole turn, or, held by the safety gate near a wall, when
    it gains less than `look_stall_rad` in `look_stall_s`, or after `look_slack` times a whole turn's time),
    and repeats; ends the goal `not_found` with the explorer's reason when no frontier is left or none
    is reachable. State `exploring` throughout (`detouring` while the local planner steers)."""

    name = "explore"

    def __init__(self, params: ExploreParams | None = None) -> None:
        self.explorer = Explorer(params)
        self.look = TurnAndLook()
        self.looking = False
        self._yaw: float | None = None  # continuous look: the last yaw, and how far it has turned
        self._turned = 0.0
        self._t: float | None = None
        self._look_t0 = 0.0  # when the look began
        self._mark: tuple[float, float] = (0.0, 0.0)  # (time, turned): the look's last headway check
        self._dir = 0.0  # the look's turn: +1 left, -1 right, 0 not chosen yet

    @property
    def params(self) -> ExploreParams:
        return self.explorer.params

    def reset(self, now: float) -> None:
        self.explorer.reset(now)
        self.looking = False

    def pause(self, now: float, cause: str) -> None:
        self.looking = False  # a look interrupted (the target seen, or remembered) starts afresh
        self.look.pause(now, cause)

    def status(self) -> dict[str, object]:
        return self.explorer.status()

    def scored(self, x: float, y: float, yaw: float, score: float, view: float | None) -> None:
        """The model's score of the view taken at (x, y) facing `yaw` (`frontier_choice: vlm`), placed
        on the value map over what that view could see on the newest costmap."""
        ex = self.explorer
        ex.values.observe(x, y, yaw, view or DEFAULT_VIEW, score, ex.costmap)

    def step(self, ctx: Context, now: float) -> Command | None:
        goal = ctx.goal
        if goal is None or goal.kind not in ("go_to", "look_for"):
            return None
        if ctx.costmap is not None and ctx.costmap is not self.explorer.costmap:
            self.explorer.set_map(ctx.costmap)
        self.explorer.coverage = ctx.coverage
        self.explorer.navigator = ctx.navigator
        pose = ctx.fresh_pose(now)
        x, y, yaw = (pose.x, pose.y, pose.yaw) if pose is not None else (None, None, None)
        st = self.explorer.step(x, y, yaw, now)
        if st.action == "walk":
            gp = self.explorer.route_params()
            nav = ctx.navigate(st.goal, gp.goal_tolerance_m, now, gp)
            if nav.status == "arrived":
                self.explorer.arrived()
            elif nav.status == "failed":
                g = st.goal
                self.explorer.give_up(f"the frontier at ({g[0]:.1f}, {g[1]:.1f}) given up: {nav.reason}")
                ctx.navigator.reset()
                return Command.still("exploring", f"{st.reason}: given up: {nav.reason}")
            else:
                self.looking = False
                return Command(nav.vx, nav.wz, "exploring", f"{st.reason}: {nav.reason}", note=nav.note,
                               navigated=True)  # fmt: skip
        if st.action == "done":
            return Command.still("not_found", f"no {ctx.label} found: {st.reason}")
        if st.action == "wait":
            return Command.still("exploring", st.reason)
        if st.action == "refresh":
            return self._look(ctx, now, st.reason, for_map=True)
        return self._look(ctx, now, st.reason if st.action == "look" else self.explorer.where())

    @staticmethod
    def _stand(ctx: Context, now: float) -> tuple[float, float] | None:
        """Where the robot stands (the place looked from), or None without a fresh pose."""
        pose = ctx.fresh_pose(now)
        return None if pose is None else (pose.x, pose.y)

    def _look(self, ctx: Context, now: float, reason: str, for_map: bool = False) -> Command:
        """A whole turn where it stands, then the explorer is told (looked): done early where the
        camera has seen all it can from there, unless `for_map` (a refresh: the lidar's view round it)."""
        p = ctx.params
        if not self.looking:
            self.looking = True
            self.look.reset(now)
            self._yaw, self._turned, self._t, self._look_t0, self._dir, self._mark = None, 0.0, now, now, 0, (now, 0)
        pose = ctx.fresh_pose(now)
        if pose is not None:
            area, left, right = self.explorer.unseen_visible(pose.x, pose.y, pose.yaw, ctx.view or DEFAULT_VIEW)
            if area < self.params.look_done_m2 and not for_map:
                self.looking = False  # the camera has looked at all it can see from here (on the way, or now)
                self.explorer.looked(now, self._stand(ctx, now))
                return Command.still("exploring", f"{reason}: nothing in sight left unseen")
            if self._dir == 0.0 and math.isfinite(area):  # the short way round to what is left, kept
                self._dir = 1.0 if left <= right else -1.0
        if self.look.stop_and_look(ctx):
            cmd = self.look.step(ctx, now) if self.look.turned < 2 * math.pi - 1e-6 else None
            if cmd is not None:
                return replace(cmd, state="exploring", reason=f"{reason}: {cmd.reason}")
        else:
            pose = ctx.fresh_pose(now)
            wz = search_command(ctx.last_x, p.search_yaw_rate, p.max_angular)
            wz = math.copysign(wz, self._dir) if self._dir else wz
            if pose is not None:  # net, the look's way round: rocking in place turns nothing
                if self._yaw is not None:
                    self._turned += wrap_angle(pose.yaw - self._yaw) * math.copysign(1.0, wz)
                self._yaw = pose.yaw
            elif self._t is not None:
                self._turned += abs(wz) * max(0.0, now - self._t)
            self._t = now
            whole = 2 * math.pi - (ctx.view or 0.0)
            ep = self.params
            held = now - self._look_t0 > ep.look_slack * 2 * math.pi / max(p.search_yaw_rate, 1e-3)
            if now - self._mark[0] >= ep.look_stall_s:  # its headway since the last check
                held, self._mark = held or self._turned - self._mark[1] < ep.look_stall_rad, (now, self._turned)
            if self._turned < whole and not held:
                return ctx.turn(wz, "exploring", reason, now)
            if self._turned < whole:
                self.looking = False
                self.explorer.looked(now, self._stand(ctx, now))
                return Command.still("exploring", f"{reason}: could not turn all round (turned "
                                     f"{math.degrees(self._turned):.0f} deg), going on")  # fmt: skip
        self.looking = False
        self.explorer.looked(now, self._stand(ctx, now))
        return Command.still("exploring", f"{reason}: looked all round")
