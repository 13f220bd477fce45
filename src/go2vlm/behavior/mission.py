"""The commander's logic without any I/O: a language goal, the target_tracker's sightings and the VLM's
scene decisions in; a velocity intent, posture commands, the query for the tracker and a state with
its reason out. Driven by explicit timestamps so it can be tested exhaustively.

This module is the goal state machine: it parses goals, takes in the observations, and each step
asks its strategies (behavior/strategies/, each a pure module with its own property tests) in order
what to do: strategies/decide.py (a VLM decision or a turn goal overrides all), approach.py (the
tracker's confirmed target, and a detour that hides it), remembered.py (a remembered object), then
lost, then the search chain (`Mission.searches`, the hook `Mission.search`: search.py's
turn-and-look first; a new search strategy is appended there). The control laws they run are
behavior/control.py's, the local planner behavior/planner/local.py.

    mission = Mission(MissionParams())
    mission.set_goal("go to the blue cylinder", now)
    mission.observe(Sighting(now, "blue cylinder", "tracking", x=0.1, distance=2.0, range_method="bottom"))
    mission.decide('{"action": "stop"}', now)      # a raw VLM answer; parsed against the whitelist here
    intent = mission.step(now)                    # what goes on /behavior/cmd_vel, /go2/command, ...

Rules
- Goals (behavior/goals.py): follow | go to | look for <object>, stop, sit, stand, turn (|angle| <=
  30 deg: turns in place at the decisions' turn rate, then `done`). Text it cannot
  parse is `rejected`: zero velocity, the reply in `reason`, nothing moves. A goal that is already
  running, sent again, carries on.
- The query is the goal's object while a motion goal runs, else '': the target_tracker grounds and
  tracks exactly that.
- The target is *confirmed* while the newest sighting for the goal's object says `tracking` and is
  younger than `lost_timeout_s`. Only a confirmed target is approached or followed: no forward
  speed otherwise. A sighting for another label is ignored; a sighting that
  says lost ends the confirmation at once. A tracker that cannot ground the object (`ungroundable`)
  rejects the goal.
- Follow, go to and look for share one control law and one set of gains (behavior/control.py's
  approach_command / align_command with these params: kp_angular, kp_linear, max_linear,
  max_angular); follow keeps `follow_distance_m` and never ends by itself: `waiting` (still) until
  the target is first confirmed.
- Not confirmed after having been: zero (`lost`) until 2 x `lost_timeout_s` after the last
  confirmed report, then search if `search_on_loss`: turn in place at `search_yaw_rate` towards
  where it was last seen, until found or `search_timeout_s` -> `not_found` (follow: `lost`, still,
  until the target comes back).
- Decisions (behavior/decisions.py, the whitelist: stop | continue | turn |angle| <= max_turn_deg |
  sit; anything else is counted and ignored) act only on a running motion goal: stop holds still for
  `decision_hold_s`, continue ends the hold, turn turns in place at `decision_turn_rate` for
  |angle| / rate seconds, sit sends "sit" and ends the goal. Text never becomes a velocity.
- Terminal states (idle, stopped, rejected, done, reached, found, not_found, sat) output zero: a
  burst of zeros for ZERO_BURST_S, then /behavior/cmd_vel goes quiet.
- Places: with a map and a pose, a go to walks to the target's place with the navigator
  (behavior/navigate/) all the way; the approach law closes the last of the distance once it is there
  (strategies/approach.py). A go to is not `reached` within `reach_settle_s` of a confirmation.
- Obstacles (`avoid_obstacles`, behavior/planner/local.py): follow, and a go to without a map, steer
  round what the newest scan (`observe_scan`, base frame, fresh for `scan_timeout_s`) shows between the robot and
  the target (`detouring`). With the pose (`observe_pose`, odometry, fresh for `pose_timeout_s`) the
  target's last confirmed place is kept in the odometry frame; a detour that takes the target out of
  view carries on towards that place for up to `detour_memory_s` after the last confirmation, but only
  while the direct way is blocked: a free direct way with the target unseen turns in place towards
  where it was (no forward speed), and then the lost/search rules apply. No fresh scan: no planning,
  the straight approach (the safety gate's collision guard still stops it short of anything).
- The world (`observe_memory`: the object memory's remembered objects from /objects, and the stamp
  of the newest answer it has taken in, on this clock): go to and look for use the most confident
  remembered object of the goal's label (at least `memory_min_confidence`) while the tracker does not
  confirm the target, once a tracker report has said how wide the camera's view is (`hfov`). Go to
  turns to it, then approaches its remembered place with the local planner, but only once the memory
  confirms it (at least `memory_confirm_confidence`: two answers that agree on its place); less
  sure, it holds still facing it and looks. At its remembered place it stops and
  looks: `reached` only when an answer about a frame taken there (its stamp after the stop) placed the
  object within reach (stop_distance_m + distance_tolerance_m + `reach_slack_m`), or the tracker
  confirms it within reach. Look for turns to face it and ends `found` when an answer about a frame
  taken facing it saw it. `confirm_looks` answered looks without it: that object is given up (until
  it is seen again) and the search goes on. A goal for an object already remembered goes straight there.
- Search, with a memory whose answers are so slow that turning at `search_yaw_rate` would turn more
  than `search_view_per_answer` of the view between two answers (the latency is measured: the stamps
  of the answers against when the memory had them; the view is the tracker reports' `hfov`, and
  unknown counts as too slow): stop and look. Hold still until an answer about a
  frame taken at this heading has come back (a frame `look_settle_s` after the stop; at most 2.5 x the
  answer latency + 1 s, or `look_timeout_s` before any answer), then turn `search_step_deg` at
  `search_step_rate` and look again. A faster grounder (or no memory) turns continuously at
  `search_yaw_rate`, as before. With stop and look, `not_found` also needs one whole turn looked at.
  Once turn-and-look is exhausted the next search strategy in the chain is asked; none left: `not_found`.
- Speeds stay within 0 <= vx <= max_linear (the navigator's commands: `nav.max_speed`, and back to
  -`nav.back_up_speed`) and |wz| <= max_angular. The navigator makes every move that is not a plain
  walk: its routes, and every turn in place a strategy asks for (`Context.turn`: where the footprint
  cannot sweep the turn, beside a table or facing a wall, a driver's turn in short legs to where it
  can, behavior/navigate/controller.py `turn_in_place`). Nothing rewrites a strategy's command after it.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from go2vlm.behavior.goals import POSTURE_GOALS, TIMED_KINDS, Goal, GoalParseError, parse_goal
from go2vlm.behavior.lease import too_far
from go2vlm.behavior.planner.global_path import Costmap
from go2vlm.behavior.strategies.approach import Approach
from go2vlm.behavior.strategies.base import Command, Context, Pose, SearchStrategy, Sighting, Strategy
from go2vlm.behavior.strategies.decide import Decisions
from go2vlm.behavior.strategies.params import MissionParams
from go2vlm.behavior.strategies.remembered import GoToRemembered, relative
from go2vlm.behavior.strategies.search import TurnAndLook
from go2vlm.world.objects_msg import Remembered

__all__ = ["TERMINAL", "ZERO_BURST_S", "Intent", "Mission", "MissionParams", "Sighting"]

TERMINAL = ("idle", "stopped", "rejected", "done", "reached", "found", "not_found", "sat")
ZERO_BURST_S = 0.5  # zeros sent after a goal ends, then /behavior/cmd_vel goes quiet


@dataclass(frozen=True)
class Intent:
    """What the commander does now."""

    vx: float = 0.0
    wz: float = 0.0
    publish_cmd: bool = False  # send (vx, wz) on /behavior/cmd_vel
    postures: tuple[str, ...] = ()  # "sit" / "stand" for /go2/command, issued since the last step
    query: str = ""  # what the target_tracker should track
    state: str = "idle"
    reason: str = ""


class Mission:
    """The goal state machine over its strategies (module docstring). `searches` is the search chain:
    append a SearchStrategy to it (or pass `searches=`) to search further once turn-and-look is
    exhausted."""

    def __init__(self, params: MissionParams | None = None, searches: tuple[SearchStrategy, ...] | None = None) -> None:
        self.ctx = Context(params if params is not None else MissionParams())
        self.state = "idle"
        self.reason = "no goal yet"
        self.cmd = (0.0, 0.0)
        self.planner_note = ""  # what the local planner did on the last step ("" = nothing)
        self.basis = ""  # what the current motion is based on: tracker | memory | ""
        self._postures: list[str] = []
        self._zero_until = -math.inf
        self.decisions = Decisions()
        self.approach = Approach()
        self.remembered = GoToRemembered()
        self.searches: list[SearchStrategy] = list(searches) if searches is not None else [TurnAndLook()]

    # -- what the strategies share (read-only views of the context) -----------------------------
    @property
    def params(self) -> MissionParams:
        return self.ctx.params

    @params.setter
    def params(self, p: MissionParams) -> None:  # live parameter changes: read on every step
        self.ctx.params = p

    @property
    def goal(self) -> Goal | None:
        return self.ctx.goal

    @property
    def counters(self) -> Counter[str]:
        return self.ctx.counters

    @property
    def sighting(self) -> Sighting | None:
        return self.ctx.sighting

    @property
    def memory(self) -> list[Remembered] | None:
        return self.ctx.memory

    @property
    def answered_through(self) -> float | None:
        return self.ctx.answers.through

    @property
    def answer_latency(self) -> float | None:
        """The measured answer latency (s): the 80th percentile of the last answers, None before any."""
        return self.ctx.answers.latency

    @property
    def view(self) -> float | None:
        return self.ctx.view

    @property
    def target_obj(self) -> Remembered | None:
        return self.ctx.target_obj

    @property
    def last_decision(self) -> dict[str, Any] | None:
        return self.decisions.last

    @property
    def label(self) -> str:
        return self.ctx.label

    @property
    def active(self) -> bool:
        goal = self.ctx.goal
        return goal is not None and goal.kind in TIMED_KINDS and self.state not in TERMINAL

    def confirmed(self, now: float) -> bool:
        """The newest sighting of the goal's object says tracking, and is fresh."""
        return self.ctx.confirmed(now)

    def base_distance(self, now: float, cap: float = 0.0) -> float | None:
        """Base centre -> the object's surface, while confirmed and ranged (as a go-to `cap` judges it)."""
        return self.ctx.capped_distance(now, cap) if cap > 0 else self.ctx.base_distance(now)

    def drop_far_memory(self, now: float, max_go_to_m: float) -> str | None:
        """A go to's remembered target beyond max_go_to_m is given up (most likely misplaced: a
        memory, not a sighting) and the search goes on without it; the reason, or None."""
        o, kind = self.ctx.target_obj, self.goal.kind if self.goal else None
        why = None if o is None else too_far(kind, (self.relative(o, now) or (0.0, None))[1], max_go_to_m)
        if o is None or why is None:
            return None
        self.remembered.give_up(self.ctx, o, "remembered_too_far")
        return f"the remembered {o.label} ({o.id}) is not gone to: {why.removeprefix('refused: ')}"

    def relative(self, o: Remembered, now: float) -> tuple[float, float] | None:
        """(bearing, base centre -> surface) of a remembered object (strategies/remembered.py)."""
        return relative(self.ctx, o, now)

    # -- inputs ------------------------------------------------------------------------------
    def set_goal(self, text: str, now: float) -> None:
        ctx = self.ctx
        try:
            goal = parse_goal(text)
        except GoalParseError as exc:
            ctx.counters["rejected_goals"] += 1
            ctx.goal = Goal("stop", None, str(text)[:200])
            self._enter("rejected", str(exc), now)
            return
        cur = ctx.goal
        if goal.moves and cur is not None and (cur.kind, cur.target) == (goal.kind, goal.target) and self.active:
            return  # the same goal again (a UI re-sending it): carry on, don't restart
        ctx.new_goal(goal)
        strategies: tuple[Strategy, ...] = (self.decisions, self.approach, self.remembered, *self.searches)
        for strategy in strategies:
            strategy.reset(now)
        if goal.kind == "stop":
            self._enter("stopped", "stop requested", now)
        elif goal.kind in POSTURE_GOALS:
            self._postures.append(goal.kind)
            self._enter("done", f"sent {goal.kind!r} on /go2/command", now)
        elif goal.kind == "turn":  # the whitelisted turn of a VLM decision, asked for as a goal
            self.decisions.start_turn(goal.angle_deg, ctx.params, now)
            self._enter("turning", f"turning {goal.angle_deg:+g} deg in place", now)
        elif goal.kind == "follow":
            self._enter("waiting", f"waiting for the {self.label} to come into view", now)
        else:
            self._enter("searching", f"looking for the {self.label}", now)

    def observe(self, s: Sighting) -> None:
        """A target_tracker report; reports about another label are ignored (but for the camera's view)."""
        ctx = self.ctx
        if math.isfinite(s.hfov) and 0.0 < s.hfov < math.pi:
            ctx.view = s.hfov
        if not self.active or s.label != self.label:
            ctx.counters["sightings_ignored"] += 1
            return
        ctx.sighting = s
        if s.state == "ungroundable":
            self._enter(
                "rejected",
                f"the target_tracker cannot ground {s.label!r}: its colour-shape grounder knows "
                "red/green/blue/yellow ball/box/cylinder; run the vlm node (mode=detect) and the "
                "target_tracker with grounding=vlm for other objects",
                s.t,
            )
        elif s.tracked:
            ctx.saw(s)

    def observe_scan(self, points: np.ndarray | None, now: float) -> None:
        """Obstacle points ((N, 2), base frame, x forward) from a scan; None: the scan was garbage."""
        if points is None:
            self.ctx.scan = None
            return
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        self.ctx.scan = (pts[np.isfinite(pts).all(axis=1)], now)

    def observe_pose(self, x: float, y: float, yaw: float, now: float) -> None:
        """The robot's odometry pose (a NaN one is dropped)."""
        self.ctx.pose = Pose(x, y, yaw, now) if all(math.isfinite(v) for v in (x, y, yaw)) else None
        self.ctx.poses.add(now, x, y, yaw)  # not finite: dropped and counted there

    def observe_map(self, costmap: Costmap | None) -> None:
        """The map's newest inflated costmap (None: none, or a bad one), for the global planner."""
        self.ctx.costmap = costmap

    def observe_memory(self, objects: list[Remembered], answered_through: float | None, now: float) -> None:
        """The object memory's newest /objects: every remembered object, and the stamp of the newest
        answer it has taken in, both on this clock (None: no answer yet)."""
        self.ctx.memory = list(objects)
        self.ctx.answers.take(answered_through, now)

    def decide(self, text: str, now: float) -> None:
        """A raw VLM scene decision: applied if it is inside the whitelist, else counted and ignored."""
        d = self.decisions.parse(text, self.params, self.counters)
        if d is None or not self.active:
            return
        if d.action == "sit":
            self._postures.append("sit")
            self._enter("sat", "a VLM decision said sit: sent 'sit' on /go2/command", now)
        else:
            self.decisions.apply(d, self.params, now)

    # -- state ---------------------------------------------------------------------------------
    def _enter(self, state: str, reason: str, now: float) -> None:
        self.state, self.reason = state, reason
        if state in TERMINAL:
            self._zero_until = now + ZERO_BURST_S

    # -- output --------------------------------------------------------------------------------
    def step(self, now: float) -> Intent:
        postures, self._postures = tuple(self._postures), []
        self.planner_note = ""
        goal = self.ctx.goal
        navigated = False
        if goal is None or not self.active:
            vx, wz, publish = 0.0, 0.0, now < self._zero_until
        else:
            self.ctx.observe_view()
            cmd = self._control(now)
            if cmd.state in TERMINAL or (cmd.state, cmd.reason) != (self.state, self.reason):
                self._enter(cmd.state, cmd.reason, now)
            self.planner_note = cmd.note
            if cmd.state != "aligning":
                self.ctx.align_since = None
            vx, wz, publish, navigated = cmd.vx, cmd.wz, True, cmd.navigated
        p = self.params
        back = p.nav.back_up_speed if navigated else 0.0  # only the navigator reverses
        top = p.nav.max_speed if navigated else p.max_linear  # the navigator's own regulations slow it
        vx = min(max(vx, -back), top) if math.isfinite(vx) else 0.0
        wz = max(-p.max_angular, min(p.max_angular, wz)) if math.isfinite(wz) else 0.0
        if publish:
            self.cmd = (vx, wz)
        return Intent(vx, wz, publish, postures, self.label if self.active else "", self.state, self.reason)

    def _control(self, now: float) -> Command:
        """Ask the strategies, in order (the module docstring's rules): a VLM decision or a turn goal
        overrides all; the tracker's confirmed target (or a detour that hides it); a remembered
        object; lost; then the search chain; all searches exhausted: not_found."""
        ctx, p = self.ctx, self.params
        goal = ctx.goal
        assert goal is not None
        cmd = self.decisions.step(ctx, now)
        if cmd is not None:
            return cmd
        seen = ctx.confirmed(now)
        self.basis = "tracker" if seen else ""
        ctx.target_obj = self.remembered.pick(ctx)
        if seen:
            for search in self.searches:
                search.pause(now, "seen")
            ctx.look.forget()
        cmd = self.approach.step(ctx, now)
        if cmd is None:
            cmd = self.remembered.step(ctx, now)
            if cmd is not None:
                for search in self.searches:
                    search.pause(now, "memory")
        if cmd is not None:
            self.basis = cmd.basis or self.basis
            return cmd
        if ctx.last_seen is None and goal.kind == "follow":
            return Command.still("waiting", "target not in view yet")
        if ctx.last_seen is not None and (now - ctx.last_seen < 2 * p.lost_timeout_s or not p.search_on_loss):
            return Command.still("lost", "target not in view: stopped")
        return self.search(now)

    def search(self, now: float) -> Command:
        """The search hook: ask the chain (`searches`, in order) what next; the first that has
        something to do answers. None left: not_found (a follow never ends by itself: it waits)."""
        for strategy in self.searches:
            cmd = strategy.step(self.ctx, now)
            if cmd is not None:
                return cmd
        after = f"no {self.label} in view after {self.params.search_timeout_s:g} s"
        if self.ctx.goal is not None and self.ctx.goal.kind == "follow":
            return Command.still("lost", f"{after} of searching: waiting for it to come back")
        return Command.still("not_found", after)
