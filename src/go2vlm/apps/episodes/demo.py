"""`go2vlm demo` and `go2vlm demo --goal TEXT`: one episode each, with a progress bar and a summary.

    go2vlm demo                                   the follow article's loop: the Go2 follows the red ball
    go2vlm demo --goal "go to the blue cylinder"  a language goal through the commander
    go2vlm demo --world household --spawn kitchen --goal "go to the duck"
                                                  the robot starts in a room of the world (its
                                                  `spawn_<room>` pose) or at --spawn x,y,yaw
    go2vlm demo --perception vlm --model PATH_OR_HUB_ID [--base-url URL] [--goal TEXT]
                                                  the same, grounded by a Qwen2.5-VL (local or served);
                                                  without --goal: "follow the red ball" through the tracker

Both are thin users of the episode runner (runner.py): the same graph files, recorder, metrics and
run folder as `go2vlm eval`.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import Any

from go2vlm.apps.episodes.episode import Episode
from go2vlm.apps.episodes.latch import stopped_line
from go2vlm.apps.episodes.runner import EpisodeResult, RunOptions, run_episode
from go2vlm.bus import ShutdownRequested

__all__ = [
    "default_out_dir",
    "demo_duration",
    "demo_spawn",
    "demo_world",
    "goal_episode",
    "goal_summary",
    "memory_lines",
    "perception_lines",
    "run_with_progress",
    "summary",
]


def demo_world(goal: str | None) -> str:
    """follow_ball for the follow loop and for following a ball, else vision_test (the VLM article's world)."""
    if goal is None:
        return "follow_ball"
    from go2vlm.behavior.goals import GoalParseError, parse_goal

    try:
        g = parse_goal(goal)
    except GoalParseError:
        return "vision_test"
    if g.kind == "follow" and g.target is not None and g.target.shape in (None, "ball"):
        return "follow_ball"
    return "vision_test"


DEMO_S = 60.0  # sim seconds a demo runs without --duration


def demo_duration(world: str, goal: str | None) -> float:
    """The demo's length without --duration: DEMO_S, or for a goal in a generated house the houses
    suite's own timeout (a search through several rooms takes minutes)."""
    if goal is None or not world.startswith("house:"):
        return DEMO_S
    from go2vlm.apps.episodes.suites import load_suite

    durations = [float(t["duration_s"]) for t in load_suite("houses").tasks if "duration_s" in t]
    return max(durations, default=DEMO_S)


def demo_spawn(world: str, text: str) -> tuple[float, float, float]:
    """`--spawn`: a room of the world ("kitchen": its `spawn_kitchen` pose, sim/worlds.py) or a pose
    "x,y,yaw" (metres, radians). ValueError naming the world's rooms otherwise."""
    parts = text.replace(",", " ").split()
    if len(parts) == 3:
        try:
            x, y, yaw = (float(v) for v in parts)
        except ValueError:
            pass
        else:
            if all(math.isfinite(v) for v in (x, y, yaw)):
                return x, y, yaw
            raise ValueError(f"--spawn {text!r}: x, y and yaw must be finite numbers")
    from go2vlm.sim.worlds import world_info

    return world_info(world).room_spawn(text.strip())


def default_out_dir(goal: str | None) -> Path:
    return Path("runs") / time.strftime(f"{'demo' if goal is None else 'goal'}-%Y%m%d-%H%M%S")


def run_with_progress(ep: Episode, opts: RunOptions, stop: ShutdownRequested, progress: bool = True) -> EpisodeResult:
    """`run_episode` with a progress bar in sim seconds on a terminal (a line every 10 s otherwise)."""
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(
            total=ep.duration_s,
            unit="sim s",
            desc="demo",
            file=sys.stderr,
            bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.1f}/{total:.0f} sim s [{elapsed}<{remaining}{postfix}]",
            disable=None,  # no bar when stderr is not a terminal
        )
    next_line = [time.monotonic() + 10.0]  # wall time: how often a line goes to a log

    def tick(t: float, rec: Any, sim: Any) -> None:
        rtf = getattr(sim, "rtf", 0.0)
        state = rec.latest_state() if ep.goal is not None else None
        if bar is not None and not bar.disable:
            bar.n = min(t, ep.duration_s)
            bar.set_postfix_str(f"rtf {rtf:.2f}{f' {state}' if state else ''}{' FELL' if rec.fell else ''}")
        elif progress and time.monotonic() >= next_line[0]:
            next_line[0] += 10.0
            more = f", state {state}" if state else ""
            print(f"demo: sim time {t:.1f}/{ep.duration_s:g} s, real-time factor {rtf:.2f}{more}", file=sys.stderr)

    try:
        return run_episode(ep, opts, stop, tick)
    finally:
        if bar is not None:
            bar.close()


def _fmt(v: Any, unit: str = "") -> str:
    return "n/a" if v is None else (f"{v:.2f}{unit}" if isinstance(v, float) else f"{v}{unit}")


def summary(result: EpisodeResult) -> str:
    """The follow loop's summary (`go2vlm demo`)."""
    m = result.metrics
    pct = 100 * m["target_visible_fraction"]
    lines = [
        f"go2vlm demo: {m['duration_s']:.1f} s of sim time in {m['wall_s']:.1f} s "
        f"(real-time factor {m['real_time_factor']:.2f}, {m['mode']} physics, robot={m['robot']})",
        f"  ball in view:      {pct:.1f} % of {m['frames']} camera frames",
        f"  mean |x| error:    {_fmt(m['mean_abs_x_error'])} (normalised, 0 = centred)",
        f"  distance to ball:  mean {_fmt(m['mean_distance_to_ball_m'], ' m')}, "
        f"min {_fmt(m['min_distance_to_ball_m'], ' m')}, max {_fmt(m['max_distance_to_ball_m'], ' m')}",
        f"  /cmd_vel rate:     {m['cmd_rate_hz']:.1f} Hz",
        f"  fell:              {'YES' if m['fell'] else 'no'}",
        f"  wrote:             {', '.join(result.files.values())}",
    ]
    stopped = stopped_line(m.get("estop"))
    if stopped is not None:
        lines.insert(1, f"  {stopped}")
    if m.get("interrupted"):
        lines.insert(1, "  (interrupted: partial run)")
    return "\n".join(lines)


def goal_summary(result: EpisodeResult) -> str:
    """A language goal's summary (`go2vlm demo --goal`)."""
    m = result.metrics
    ep = result.episode
    stopped = stopped_line(m.get("estop"))
    verdict = "REACHED" if m["goal_reached"] else ("STOPPED" if stopped else "NOT reached")
    final = f"{m['final_state']} ({m['final_reason']})"
    if stopped:  # not "not found": the e-stop held the robot
        final = f"stopped: the e-stop held the robot (the commander's last state: {final})"
    lines = [
        f"go2vlm demo --goal {m['goal']!r}: {verdict} "
        f"({m['kind']}, world {m['world']}, {m['mode']} physics, {_fmt(m['sim_s'], ' s')} sim in "
        f"{_fmt(m['wall_s'], ' s')})",
        f"  final state:     {final}",
        f"  states:          {' -> '.join(map(str, m['states']))}",
        f"  target body:     {m['target_body']}",
        f"  time to goal:    {_fmt(m['time_to_goal_s'], ' s')}",
        f"  final distance:  {_fmt(m['final_distance_m'], ' m')} (base centre -> object surface)",
        f"  collisions:      {m['collisions']} (min clearance {_fmt(m['min_clearance_m'], ' m')})",
    ]
    if m["kind"] == "follow":
        lines.append(
            f"  follow:          tracked {100 * m['tracked_fraction']:.0f} %, "
            f"within {ep.follow_success_m} m {100 * m['within_follow_distance_fraction']:.0f} %, "
            f"mean distance {_fmt(m['mean_distance_m'], ' m')}"
        )
    if m["kind"] == "go_to":
        lines.append(f"  SPL:             {_fmt(m['spl'])} (path {_fmt(m['path_length_m'], ' m')})")
    lines += perception_lines(m)
    if stopped:
        lines.insert(1, f"  {stopped}")
    lines += memory_lines(m)
    if m.get("interrupted"):
        lines.insert(1, "  (interrupted: partial run)")
    if result.files:
        lines.append(f"  wrote:           {', '.join(result.files.values())}")
    return "\n".join(lines)


def _pct(v: float | None) -> str:
    return "n/a" if v is None else f"{100 * v:.0f} %"


def perception_lines(m: dict[str, Any]) -> list[str]:
    """What the perception did: the VLM's answers (count, hits against the sim's ground truth,
    latency, result age) and how the target_tracker carried the target between answers."""
    lines = [f"  perception:      {m['perception']}"]
    v, g, tr = m.get("vlm"), m.get("grounding"), m.get("tracker")
    if v is not None:
        lines[0] += f" ({v.get('backend')}, model {v.get('model')})"
        lines.append(
            f"  VLM latency:     p50 {_fmt(v['latency_ms_p50'], ' ms')}, p95 {_fmt(v['latency_ms_p95'], ' ms')} "
            f"over {v.get('inferences') or 0} inferences, errors {v.get('errors') or {}}"
        )
    if g is not None and m["perception"] == "vlm":
        lines.append(
            f"  VLM answers:     {g['answers']} ({g['answers_with_box']} with a box for the target; "
            f"hits {g['hits']} of {g['answers_target_visible']} while it was visible, "
            f"wrong object {g['wrong_object']}, false positives {g['false_positives']}; mean IoU {_fmt(g['mean_iou'])})"
        )
        lines.append(
            f"  result age:      mean {_fmt(g['result_age_s_mean'], ' s')}, p95 {_fmt(g['result_age_s_p95'], ' s')} "
            "(frame stamp -> answer, sim time)"
        )
    if tr is not None:
        lines.append(
            f"  tracker:         confirmed the target on {_pct(tr['tracking_fraction'])} of {tr['frames']} frames; "
            f"carried it from an older answer on {_pct(tr['carried_fraction'])} of those "
            f"(grounding age p50 {_fmt(tr['grounding_age_s_p50'], ' s')}, p95 {_fmt(tr['grounding_age_s_p95'], ' s')})"
        )
    return lines


def memory_lines(m: dict[str, Any]) -> list[str]:
    """What the object memory remembers at the end, and where each object really is (the sim's ground truth)."""
    mem = m.get("memory")
    if not mem:
        return []
    lines = [
        f"  remembered:      {len(mem['objects'])} object(s), {mem.get('accurate', 0)} within 0.3 m, "
        f"{mem['phantoms']} phantom(s), "
        f"error max {_fmt(mem['max_error_m'], ' m')}, mean {_fmt(mem['mean_error_m'], ' m')} (odom frame = the world's)"
    ]
    for o in mem["objects"]:
        truth = "no such object" if o["body"] is None else (
            f"really ({o['true_x']:.2f}, {o['true_y']:.2f}) [{o['body']}], error {o['error_m']:.2f} m")  # fmt: skip
        lines.append(f"    {o['label']:<16} at ({o['x']:.2f}, {o['y']:.2f}), confidence {o['confidence']:.2f}; {truth}")
    return lines


def goal_episode(goal: str, world: str | None = None, **kw: Any) -> Episode:
    """The episode `go2vlm demo --goal` runs: the world picked from the goal unless given."""
    return Episode(world=world or demo_world(goal), goal=goal, **kw)
