"""The first search strategy: turn and look, where the robot stands. Pure, timestamp-driven.

- A fast enough grounder (turning at `search_yaw_rate` turns at most `search_view_per_answer` of the
  view between two answers), or no object memory: turn continuously at `search_yaw_rate` towards where
  the target was last seen.
- Slower answers (or an unknown latency or view): stop and look. Hold still until an answer about a
  frame taken at this heading has come back (look.py), then turn `search_step_deg` at
  `search_step_rate` (measured by odometry, else by time) and look again.
- Exhausted (`step` returns None) after `search_timeout_s` without the target, and with stop and look
  only once one whole turn has been looked at. With a search after it in the chain (`more_after`:
  the frontier search), already once one whole turn has been looked at: turning on where it stands
  finds nothing the first turn did not.
"""

from __future__ import annotations

import math

from go2vlm.behavior.control import search_command
from go2vlm.behavior.strategies.base import Command, Context

__all__ = ["TurnAndLook"]


class TurnAndLook:
    name = "turn_and_look"

    def __init__(self, more_after: bool = False) -> None:
        self.more_after = more_after  # another search follows in the chain: one whole turn is enough
        self._yaw: float | None = None  # a continuous turn: the last yaw it saw
        self.since = 0.0  # when this search (re)started: the target was last confirmed or remembered
        self.phase = "look"  # stop and look: look | turn
        self.turn_t0 = 0.0  # when this step's turn began
        self.turn_yaw: float | None = None  # the yaw the step started from
        self.turned = 0.0  # rad turned (in steps) since the search began

    def reset(self, now: float) -> None:
        self.since, self.phase, self.turned, self.turn_yaw, self._yaw = now, "look", 0.0, None, None

    def pause(self, now: float, cause: str) -> None:
        self.since, self._yaw = now, None
        if cause == "memory":
            self.phase = "look"  # a search after this starts with a look where it then faces

    def stop_and_look(self, ctx: Context) -> bool:
        p = ctx.params
        fast = ctx.answers.fast_for(p.search_yaw_rate, ctx.view, p.search_view_per_answer)
        return ctx.memory is not None and p.use_memory and not fast

    def step(self, ctx: Context, now: float) -> Command | None:
        p, label = ctx.params, ctx.label
        stop_and_look = self.stop_and_look(ctx)
        full_turn = self.turned >= 2 * math.pi - 1e-6
        if now - self.since > p.search_timeout_s and (not stop_and_look or full_turn):
            return None
        if not stop_and_look:
            pose = ctx.fresh_pose(now)
            if pose is not None:  # how far the continuous turn has turned, by odometry
                if self._yaw is not None:
                    self.turned += abs(math.atan2(math.sin(pose.yaw - self._yaw), math.cos(pose.yaw - self._yaw)))
                self._yaw = pose.yaw
            if self.more_after and self.turned >= 2 * math.pi - (ctx.view or 0.0):
                return None
            wz = search_command(ctx.last_x, p.search_yaw_rate, p.max_angular)
            return ctx.turn(wz, "searching", f"turning in place to find the {label}", now)
        if self.phase == "look":
            if ctx.look_at(("search", self.turned), now) == "waiting":
                lat = ctx.answers.latency
                how = "answer latency unknown" if lat is None else f"answers take {lat:.1f} s"
                return Command.still("searching", f"holding still, looking for the {label} ({how})")
            self.phase, self.turn_t0, self.turn_yaw = "turn", now, None
        wz = search_command(ctx.last_x, p.search_step_rate, p.max_angular)
        pose = ctx.fresh_pose(now)
        if pose is not None:  # how far this step has turned, by odometry
            if self.turn_yaw is None:
                self.turn_yaw = pose.yaw
            done = abs(math.atan2(math.sin(pose.yaw - self.turn_yaw), math.cos(pose.yaw - self.turn_yaw)))
        else:  # no odometry: by time
            self.turn_yaw = None
            done = abs(wz) * (now - self.turn_t0)
        if done >= math.radians(p.search_step_deg) - 0.02:
            self.turned += math.radians(p.search_step_deg)
            self.phase = "look"
            ctx.look_at(("search", self.turned), now)
            return Command.still("searching", f"holding still, looking for the {label}")
        why = f"turning {p.search_step_deg:g} deg to look for the {label}"
        return ctx.turn(wz, "searching", why, now, angle=math.radians(p.search_step_deg))
