"""The commander's messages, worked out without I/O (behavior/commander_node.py does the I/O): a
/vlm/way answer -> its score; the Mission core (behavior/mission.py) -> /commander/status, its route
-> a /plan Path, and the question on /explore/way_query. (A /target/tracked -> a Sighting:
behavior/sighting.py.)"""

from __future__ import annotations

from collections.abc import Mapping

from go2vlm.behavior.mission import Mission
from go2vlm.behavior.planner.route import Route
from go2vlm.behavior.view_scores import parse_view_answer
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.geometry_msgs import Point, Pose, PoseStamped, Quaternion
from go2vlm.msgs.nav_msgs import Path
from go2vlm.msgs.std_msgs import Header
from go2vlm.perception.way import WayMessageRejected, parse_way_message

__all__ = ["WAY_STATES", "commander_status", "plan_status", "route_path", "way_answer", "way_query"]

WAY_STATES = ("searching", "exploring")  # frontier_choice vlm asks which way while looking round or exploring


def commander_status(
    m: Mission,
    now: float,
    *,
    counters: Mapping[str, int],
    lease: dict[str, object] | None,
    explore: dict[str, object] | None,
    route: Route | None,
) -> dict[str, object]:
    """/commander/status (its fields: behavior/commander_node.py), rounded for JSON. The node gives what
    only it knows: its own `counters`, the goal's `lease` (Lease.status), `explore` (Explore.status,
    None without explore) and the `route` last published on /plan."""
    goal = m.goal
    seen = m.confirmed(now)
    s = m.sighting
    dist = m.base_distance(now)
    return {
        "goal": goal.text if goal else "",
        "kind": goal.kind if goal else None,
        "target": m.label or None,
        "state": m.state,
        "reason": m.reason,
        "seen": seen,
        "x": round(s.x, 4) if seen and s is not None else None,
        "distance_m": None if dist is None else round(dist, 3),
        "range_method": s.range_method if seen and s is not None else None,
        "tracker": s.state if s is not None else None,
        "cmd": [round(m.cmd[0], 4), round(m.cmd[1], 4)],
        "planner": m.planner_note,
        "decision": m.last_decision,
        "counters": {**m.counters, **counters},
        "basis": m.basis,
        "lease": lease,
        "remembered": _remembered(m, now),
        "explore": explore,
        "plan": plan_status(route),
        "navigate": m.ctx.navigator.status(),
        "memory": None if m.memory is None else {
            "objects": len(m.memory),
            "answer_latency_s": None if m.answer_latency is None else round(m.answer_latency, 3),
        },
    }  # fmt: skip


def _remembered(m: Mission, now: float) -> dict[str, object] | None:
    o = m.target_obj
    if o is None:
        return None
    rel = m.relative(o, now)
    return {
        "id": o.id, "label": o.label, "x": round(o.x, 3), "y": round(o.y, 3),
        "confidence": round(o.confidence, 3), "distance_m": None if rel is None else round(rel[1], 3),
    }  # fmt: skip


def plan_status(route: Route | None) -> dict[str, object] | None:
    """The route on /plan: its length, waypoints and why it was planned; None without one."""
    if route is None:
        return None
    return {"length_m": round(route.plan.length, 2), "waypoints": len(route.plan.waypoints),
            "reason": route.plan.reason}  # fmt: skip


def route_path(route: Route | None, stamp: float, frame_id: str) -> Path:
    """The route's waypoints as a nav_msgs/Path in `frame_id` (odom); an empty path without one."""
    header = Header(stamp=Time.from_sec(stamp), frame_id=frame_id)
    poses = [] if route is None else [
        PoseStamped(header=header, pose=Pose(position=Point(x=float(x), y=float(y)), orientation=Quaternion(w=1.0)))
        for x, y in route.plan.waypoints
    ]  # fmt: skip
    return Path(header=header, poses=poses)


def way_query(query: str, state: str, explore: bool, frontier_choice: str) -> str:
    """The object to ask the model about the ways (frontier_choice vlm, while it searches or explores), or ''."""
    return query if explore and frontier_choice == "vlm" and state in WAY_STATES else ""


def way_answer(text: str, asked: str) -> tuple[float, float]:
    """A /vlm/way message (perception/way.py) about the question `asked` -> (its frame's stamp, its
    whitelisted score); WayMessageRejected or ViewAnswerRejected, with a reason, otherwise."""
    stamp, obj, answer = parse_way_message(text)
    if not asked or obj != asked:
        raise WayMessageRejected("way_not_asked", f"no question about {obj!r} stands")
    return stamp, parse_view_answer(answer)
