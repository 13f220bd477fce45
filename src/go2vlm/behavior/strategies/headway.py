"""Headway on a tracked go to: the reactive approach (the approach law, and the local planner steering
towards the target's bearing) can cycle where the navigator knows the way, beside a doorway's jamb
with the object in view through it. A tracked go to that makes no progress, by the navigator's own
rule (navigate/progress.py: `nav_progress_m` within `nav_progress_s`), hands the target's place to the
navigator (behavior/navigate/) until it is `headway_out_m` from where it stalled, the navigator is
there or gives up, or `nav_progress_s` has passed; then the approach has its turn again and the watch
starts afresh. A pause in the go to longer than 2 x `lost_timeout_s` (a search, a look) starts it
afresh too. Pure, timestamp-driven.
"""

from __future__ import annotations

import math

from go2vlm.behavior.navigate.progress import Progress
from go2vlm.behavior.strategies.base import Command, Context

__all__ = ["Headway"]


class Headway:
    """The stall watch of the tracked go to, and its way out with the navigator."""

    def __init__(self) -> None:
        self.progress = Progress()
        self.stalled: tuple[float, float, float] | None = None  # x, y, t of the stall being walked out of
        self.last = -math.inf  # the last step

    def reset(self) -> None:
        self.progress.reset()
        self.stalled = None
        self.last = -math.inf

    def walk(
        self,
        ctx: Context,
        target: tuple[float, float],
        reach_m: float,
        now: float,
        why: str,
        basis: str = "",
        body: float = 0.0,
    ) -> Command | None:
        """The navigator's command towards `target` (there within `reach_m` of it, its own cells within
        `body`) while walking out of a stall; None: headway is fine (the approach steers as before)."""
        pose, p = ctx.fresh_pose(now), ctx.params
        if pose is None or ctx.costmap is None:
            return None
        if now - self.last > 2 * p.lost_timeout_s:
            self.reset()
        self.last = now
        if self.stalled is not None:
            sx, sy, st = self.stalled
            if math.hypot(pose.x - sx, pose.y - sy) < p.headway_out_m and now - st < p.nav.progress_s:
                nav = ctx.navigate(target, reach_m, now, ctx.place_planner, body)
                if nav.status in ("moving", "recovering", "waiting"):
                    return Command(nav.vx, nav.wz, "approaching", f"{why}: no headway, with the navigator "
                                   f"({nav.reason})", note=nav.note, basis=basis, navigated=True)  # fmt: skip
            self.stalled = None
            ctx.navigator.reset()
            self.progress.reset()
            return None
        self.progress.moved(pose.x, pose.y, now, p.nav.progress_m)
        if not self.progress.stalled(now, p.nav.progress_s):
            return None
        self.stalled = (pose.x, pose.y, now)
        ctx.counters["stalled"] += 1
        return self.walk(ctx, target, reach_m, now, why, basis, body)
