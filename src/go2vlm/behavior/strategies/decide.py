"""VLM scene decisions on a running goal, and turn goals: the only strategy that overrides all others
while it acts. The whitelist and its parser are behavior/decisions.py's; here an accepted decision
becomes timing: stop holds still for `decision_hold_s`, continue ends the hold, turn turns in place at
`decision_turn_rate` (within max_angular) for |angle| / rate seconds. Sit is the mission's (it ends
the goal). The text never becomes a velocity. Pure, timestamp-driven."""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

from go2vlm.behavior.decisions import Decision, DecisionRejected, parse_decision
from go2vlm.behavior.strategies.base import Command, Context
from go2vlm.behavior.strategies.params import MissionParams

__all__ = ["Decisions"]


class Decisions:
    def __init__(self) -> None:
        self.last: dict[str, Any] | None = None  # the last decision, accepted or not (for the status)
        self.hold_until = -math.inf
        self.turn_until = -math.inf
        self.turn_dir = 0.0

    def reset(self, now: float) -> None:
        self.hold_until = self.turn_until = -math.inf

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
        self.turn_until = now + (math.radians(abs(angle_deg)) / rate if rate > 0 else 0.0)

    def step(self, ctx: Context, now: float) -> Command | None:
        """Holding, a turn goal, or a decision's turn; None: no decision acts now."""
        p, goal = ctx.params, ctx.goal
        if now < self.hold_until:
            return Command.still("holding", "a VLM decision said stop")
        wz = self.turn_dir * self.turn_rate(p)
        left = abs(wz) * max(0.0, self.turn_until - now)  # rad still to turn
        if goal is not None and goal.kind == "turn":
            if now < self.turn_until:
                return ctx.turn(wz, "turning", f"turning {goal.angle_deg:+g} deg in place", now, angle=left)
            return Command.still("done", f"turned {goal.angle_deg:+g} deg")
        if now < self.turn_until:
            return ctx.turn(wz, "turning", "a VLM decision said turn", now, angle=left)
        return None
