"""VLM scene decisions on a running goal, and turn goals: the only strategy that overrides all others
while it acts. The whitelist and its parser are behavior/decisions.py's; here an accepted decision
becomes timing: stop holds still for `decision_hold_s`, continue ends the hold, turn turns in place at
`decision_turn_rate` (within max_angular) until odometry says it has turned |angle| (without a fresh
pose, by time at that rate), through the navigator's turn: where it slows the turn, or makes room
with a leg first, the turn goes on; one not done within `turn_slack` times its time ends, and says
how far it turned (a turn by the clock once said "turned" having turned less). Sit is the mission's
(it ends the goal). The text never becomes a velocity. Pure, timestamp-driven."""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

from go2vlm.behavior.decisions import Decision, DecisionRejected, parse_decision
from go2vlm.behavior.strategies.base import Command, Context
from go2vlm.behavior.strategies.params import MissionParams
from go2vlm.world.poses import wrap_angle

__all__ = ["Decisions"]


class Decisions:
    def __init__(self) -> None:
        self.last: dict[str, Any] | None = None  # the last decision, accepted or not (for the status)
        self.hold_until = -math.inf
        self.turn_until = -math.inf  # a turn not done by then ends
        self.turn_dir = 0.0
        self.turn_left = self.turn_asked = 0.0  # rad still to turn, of the rad asked
        self._turn_at: tuple[float, float | None] = (0.0, None)  # the last step's time and yaw
        self.turn_said = ""  # how a turn held before its end ended
        self._clock_end, self._odometry = -math.inf, False

    def reset(self, now: float) -> None:
        self.hold_until = self.turn_until = -math.inf
        self.turn_left = 0.0

    def parse(self, text: str, p: MissionParams, counters: Counter[str]) -> Decision | None:
        """A raw answer -> a whitelisted Decision, or None (counted, and kept in `last` with why)."""
        try:
            d = parse_decision(text, p.max_turn_deg)
        except DecisionRejected as rej:
            counters["decisions_rejected"] += 1
            counters[f"decisions_rejected.{rej.reason}"] += 1
            self.last = {"accepted": False, "reason": rej.reason, "answer": str(text)[:120]}
            return None
        counters["decisions_accepted"] += 1
        self.last = {"accepted": True, **d.to_dict()}
        return d

    def apply(self, d: Decision, p: MissionParams, now: float) -> None:
        """An accepted decision on a running goal: stop, continue or turn (sit is the mission's)."""
        if d.action == "stop":
            self.hold_until = now + p.decision_hold_s
        elif d.action == "continue":
            self.hold_until = -math.inf
        elif d.action == "turn":
            self.start_turn(d.angle_deg, p, now)

    @staticmethod
    def turn_rate(p: MissionParams) -> float:
        return min(p.decision_turn_rate, p.max_angular)

    def start_turn(self, angle_deg: float, p: MissionParams, now: float) -> None:
        rate = self.turn_rate(p)
        self.turn_dir = math.copysign(1.0, angle_deg) if angle_deg else 0.0
        self.turn_left = self.turn_asked = math.radians(abs(angle_deg)) if rate > 0 else 0.0
        self.turn_until = now + p.turn_slack * (self.turn_left / rate if rate > 0 else 0.0)
        self._turn_at = (now, None)
        self._clock_end = now + (self.turn_left / rate if rate > 0 else 0.0)  # no pose yet: the turn by the clock
        self._odometry = False  # a fresh pose seen since the turn began
        self.turn_said = ""

    def _count(self, ctx: Context, now: float, rate: float) -> None:
        """Take off what the robot turned, the turn's way, since the last step: by odometry; without
        a fresh pose, by the clock at `rate` (since the turn began, or since the pose was lost)."""
        pose = ctx.fresh_pose(now)
        t0, yaw0 = self._turn_at
        if pose is None and not self._odometry:
            self.turn_left = rate * max(0.0, self._clock_end - now)
        elif pose is None:
            self.turn_left -= rate * max(0.0, now - t0)
        elif yaw0 is not None:
            self.turn_left -= wrap_angle(pose.yaw - yaw0) * self.turn_dir
        self._odometry = self._odometry or pose is not None
        self._turn_at = (now, None if pose is None else pose.yaw)

    def turning(self) -> bool:
        return self.turn_left > 0.0  # 0 from the start for a turn of 0 degrees

    def step(self, ctx: Context, now: float) -> Command | None:
        """Holding, a turn goal, or a decision's turn; None: no decision acts now."""
        p, goal = ctx.params, ctx.goal
        if now < self.hold_until:
            return Command.still("holding", "a VLM decision said stop")
        rate = self.turn_rate(p)
        if self.turning():
            self._count(ctx, now, rate)
        left = max(0.0, self.turn_left)
        if self.turning() and now >= self.turn_until:  # held: it ends, saying how far it turned
            said = (f"turned {math.degrees(self.turn_asked - left) * self.turn_dir + 0.0:+.0f} of "
                    f"{math.degrees(self.turn_asked) * self.turn_dir:+.0f} deg: held (no room to turn)")  # fmt: skip
            self.turn_left, self.turn_said = 0.0, said
            if goal is not None and goal.kind == "turn":
                return Command.still("done", said)
            return Command.still("turning", f"a VLM decision's turn {said}")
        wz = self.turn_dir * rate
        if goal is not None and goal.kind == "turn":
            if self.turning():
                return ctx.turn(wz, "turning", f"turning {goal.angle_deg:+g} deg in place", now, angle=left)
            return Command.still("done", self.turn_said or f"turned {goal.angle_deg:+g} deg")
        if self.turning():
            return ctx.turn(wz, "turning", "a VLM decision said turn", now, angle=left)
        return None
