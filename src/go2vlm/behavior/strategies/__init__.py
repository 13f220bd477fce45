"""The mission's strategies: pure, timestamp-driven modules that the goal state machine
(behavior/mission.py) asks, in order, what to do now. Each has its own property tests
(tests/behavior/test_strategy_*.py).

The interface (base.py)
- `Context`: what the mission knows, shared by all strategies: `params` (MissionParams), `goal`,
  the newest `sighting`, odometry `pose`, `scan`, object `memory`, `answers` (the answers' measured
  latency, latency.py), the camera's `view`, the target's track (`last_seen`, `last_x`, `goal_xy`),
  the chosen remembered object (`target_obj`), and two shared tools: `look` (hold still until an
  answer about a frame taken since the stop is back, look.py) and `navigator` (behavior/navigate/,
  the only planner caller: `ctx.navigate(place, ...)` walks to a place: route, controller, progress,
  recoveries; `ctx.turn(...)` turns in place; `ctx.avoid(...)` steers towards a bearing round the
  fresh scan where there is no route, its `steering`).
- `Strategy`: `reset(now)` when a goal starts; `step(ctx, now) -> Command | None`, None meaning
  "nothing for me to do now: ask the next".
- `Command`: (vx, wz, state, reason) and the planner's note; a terminal state (found, reached,
  done, ...) ends the goal. The mission clamps every velocity to its limits.
- `SearchStrategy`: a Strategy with a `name` and `pause(now, cause)` (the target was 'seen', or a
  'memory' object drove this step: a later search starts afresh). Its `step` returns None once it is
  exhausted.

The order (Mission._control): decide.py (a VLM decision or a turn goal overrides all) ->
approach.py (the tracker's confirmed target, or a detour that hides it) -> remembered.py (go to /
look at a remembered object) -> lost -> the search chain, `Mission.searches` = [search.TurnAndLook]
(Mission.search, the hook: "search: what next?"). A new search strategy (e.g. explore.py: walk to a
frontier, look there) is one module with a class implementing SearchStrategy, appended to the chain
(`Mission(params, searches=(TurnAndLook(), Explore(...)))`); it is asked once turn-and-look is
exhausted, and when every search is exhausted the goal ends not_found.
"""
