"""The MCP server's movement rules without any I/O: one motion goal at a time, the deadman, and
the confirmations `--confirm` asks a person for. Driven by explicit timestamps (the server feeds
wall time: an agent's silence is wall time), property-tested in tests/apps/test_mcp_rules.py.

    rules = MotionRules(deadman_s=10.0)
    rules.observe(CommanderState("go to the blue cylinder", "go_to", "approaching"), now)
    rules.check_start("look for the green box", replace=False, estop=False)  # raises Refused: busy
    rules.started("look for the green box", now)                             # ours now; the deadman runs
    rules.poll(now)                                                           # status() was called
    rules.deadman(now)                                                        # a reason to stop, or None

Rules
- Busy: the commander runs a goal that lasts (go to, look for, follow, turn: behavior/goals.py
  TIMED_KINDS) and is not in a terminal state, or a goal this server sent has not been answered
  yet. A new motion goal while busy is refused, naming the current goal, unless `replace`.
- Every motion goal is refused while the e-stop is latched; nothing here releases it.
- Deadman: a goal this server started stops when no `poll` (the agent's status() call) came for
  `deadman_s`; it ends the goal once (the caller sends stop). A goal that ended by itself, was
  stopped, or was replaced by someone else's needs no deadman.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from go2vlm.behavior.goals import TIMED_KINDS, GoalParseError, parse_target, unknown_words
from go2vlm.behavior.mission import TERMINAL
from go2vlm.vocabulary.words import COLORS, SHAPES

__all__ = ["CommanderState", "Confirmations", "MotionRules", "Refused", "object_label"]

MAX_OBJECT_CHARS = 100


def object_label(phrase: str, grounding: str | None) -> str:
    """The label the commander will track for an object phrase ("the blue cylinder" -> "blue cylinder"),
    or Refused saying why. `grounding` is what the target_tracker reports (color | vlm | None: no
    tracker heard): free text ("the person") needs vlm; every word must be understood."""
    if len(phrase) > MAX_OBJECT_CHARS:
        raise Refused(f"the object is {len(phrase)} characters long; at most {MAX_OBJECT_CHARS}")
    try:
        target = parse_target(phrase)
    except GoalParseError as exc:
        raise Refused(str(exc)) from None
    known = f"colours {'/'.join(COLORS)}, shapes {'/'.join(SHAPES)}"
    unknown = unknown_words(phrase)
    if target.classical and unknown:
        raise Refused(f"unknown word(s) {', '.join(map(repr, unknown))} in {phrase!r}; known: {known}")
    if not target.classical and grounding != "vlm":
        seen = f"grounds with {grounding!r}" if grounding else "has not reported (no /target_tracker/status)"
        raise Refused(
            f"unknown object {phrase!r}: the target_tracker {seen}, which knows {known}; other objects need a "
            "VLM (the vlm node in mode=detect and the target_tracker with grounding=vlm)"
        )
    return target.label


class Refused(Exception):
    """A tool call refused by the rules; the message says why (it goes back to the agent)."""


@dataclass(frozen=True)
class CommanderState:
    """What /commander/status says now."""

    goal: str  # the goal's text as it was sent
    kind: str | None  # behavior/goals.py GOAL_KINDS, None when idle
    state: str  # the mission's state

    @property
    def busy(self) -> bool:
        return self.kind in TIMED_KINDS and self.state not in TERMINAL


@dataclass
class _Ours:
    text: str
    sent: float  # when it was sent
    acked: bool = False  # the commander's status has named it


class MotionRules:
    def __init__(self, deadman_s: float = 10.0) -> None:
        if not (math.isfinite(deadman_s) and deadman_s > 0):
            raise ValueError(f"deadman_s must be positive, got {deadman_s}")
        self.deadman_s = deadman_s
        self.commander: CommanderState | None = None
        self.ours: _Ours | None = None
        self.last_poll = -math.inf

    # -- inputs ------------------------------------------------------------------------------
    def observe(self, status: CommanderState, now: float) -> None:
        """A /commander/status."""
        self.commander = status
        ours = self.ours
        if ours is None:
            return
        if status.goal == ours.text:
            ours.acked = True
            if not status.busy:
                self.ours = None  # reached, found, not found, rejected, done: over
        elif ours.acked:
            self.ours = None  # someone else's goal replaced ours

    def poll(self, now: float) -> None:
        """The agent asked for status(): it is still there."""
        self.last_poll = now

    # -- decisions -----------------------------------------------------------------------------
    def busy_with(self) -> str | None:
        """The goal that keeps the robot busy (ours, unanswered, or the commander's), or None."""
        if self.ours is not None and not self.ours.acked:
            return f"{self.ours.text!r} (sent, not yet acknowledged by the commander)"
        c = self.commander
        if c is not None and c.busy:
            return f"{c.goal!r} ({c.state})"
        return None

    def check_start(self, text: str, *, replace: bool, estop: bool) -> None:
        """Raise Refused when a motion goal `text` may not start now."""
        if estop:
            raise Refused(
                "the e-stop is latched: no motion goal until a person releases it with `go2vlm estop --release` "
                "(no tool can release it)"
            )
        busy = self.busy_with()
        if busy is not None and not replace:
            raise Refused(f"the robot is busy with {busy}; call stop() first, or pass replace=true to replace it")

    def started(self, text: str, now: float) -> None:
        """A motion goal was sent: it is ours, and the deadman counts from now."""
        self.ours = _Ours(text, now)
        self.last_poll = max(self.last_poll, now)

    def unanswered(self, now: float, timeout_s: float) -> bool:
        """Our goal has had no answer from the commander for `timeout_s`."""
        return self.ours is not None and not self.ours.acked and now - self.ours.sent >= timeout_s

    def forget(self) -> None:
        """Our goal is over (stopped, e-stopped, unanswered)."""
        self.ours = None

    def deadman(self, now: float) -> str | None:
        """Why our goal must stop now (the agent went silent), or None; reported once."""
        if self.ours is None or now - self.last_poll <= self.deadman_s:
            return None
        text = self.ours.text
        self.ours = None
        return (
            f"deadman: no status() call for {now - self.last_poll:.1f} s (deadman_s {self.deadman_s:g}) during {text!r}"
        )


_ANSWER = re.compile(r"^\s*(?P<word>yes|y|no|n)(?:\s+#?(?P<id>\d+))?\s*$", re.I)


@dataclass
class _Ask:
    id: int
    text: str
    asked: float
    answer: bool | None = None


class Confirmations:
    """`--confirm`: each motion goal waits for a person's yes. One question is open at a time;
    an answer names its question's number ("yes 3"), or, at the terminal, answers the open one
    ("yes"). Anything but yes is no; no answer within the timeout is no."""

    def __init__(self, timeout_s: float = 60.0) -> None:
        self.timeout_s = timeout_s
        self._next = 1
        self.open: _Ask | None = None

    def ask(self, text: str, now: float) -> int:
        """Open a question for goal `text` (closing any earlier one as no); its number."""
        if self.open is not None and self.open.answer is None:
            self.open.answer = False
        self.open = _Ask(self._next, text, now)
        self._next += 1
        return self.open.id

    def answer(self, line: str, *, need_id: bool) -> str:
        """A person's answer; what it did, for the log. `need_id`: the answer must name the question
        (the bus, where an answer may be stale), else a bare yes answers the open question."""
        q = self.open
        if q is None or q.answer is not None:
            return "no question is open"
        m = _ANSWER.match(line[:100])
        if m is None:
            q.answer = False
            return f"#{q.id} refused (the answer was not yes)"
        if m["id"] is not None and int(m["id"]) != q.id:
            return f"ignored: the answer is for #{m['id']}, the open question is #{q.id}"
        if m["id"] is None and need_id:
            return f"ignored: say 'yes {q.id}' (the open question's number)"
        q.answer = m["word"].lower().startswith("y")
        return f"#{q.id} {'confirmed' if q.answer else 'refused'}"

    def result(self, qid: int, now: float) -> bool | None:
        """True (yes), False (no, replaced, or timed out) or None (still waiting)."""
        q = self.open
        if q is None or q.id != qid:
            return False
        if q.answer is None and now - q.asked >= self.timeout_s:
            q.answer = False
        return q.answer
