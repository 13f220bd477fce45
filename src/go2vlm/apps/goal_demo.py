"""`go2vlm demo --goal TEXT`: one language goal, run in the simulator, measured.

    sim -> /camera/image_raw -> target_tracker (colour-shape grounder + tracker) -> /target/tracked
        -> commander (-> /target/query) -> /behavior/cmd_vel
        (follow goals: -> /detected_target -> follower -> /follower/cmd_vel) -> safety gate -> /cmd_vel -> sim

World: `vision_test` (the VLM article's Gazebo world: red sphere, green box, blue cylinder; the Go2 starts at (0, -1.5)
facing +x, so only the red sphere is in view at first), or `follow_ball` for "follow the red ball"
(a red ball moving on a circle). All nodes run in this process on their own threads, over DDS, with
use_sim_time (the recorder too): their timers and timeouts are sim time, so --fast and --rtf 1 agree.

Metrics (from the simulator's ground truth, /sim/ground_truth, and the commander's /commander/status):
  goal_reached      go to: the commander reported `reached`, the robot ended within
                    `success_distance_m` (1.0 m) of the object's SURFACE (centre distance minus the
                    radius; for a box: distance to its footprint) and never collided;
                    look for: `found` and the object is inside the camera's field of view;
                    follow: the target was tracked >= 70 % of the time after first contact and the
                    robot stayed within `follow_success_m` of the ball's surface >= 70 % of that time;
                    stop / sit / stand: the command was issued.
  final_distance_m  base -> object surface at the end; time_to_goal_s: sim seconds from the start to
                    `reached` / `found`.
  collisions        times the robot's footprint (a 0.70 x 0.31 m rectangle around the base, the Go2's
                    size) overlapped an object's footprint; min_clearance_m is the smallest gap.
                    Geometric, so it is the same in kinematic and dynamic physics.

    from go2vlm.apps.goal_demo import GoalDemoOptions, run_goal_demo
    result = run_goal_demo(GoalDemoOptions(goal="go to the blue cylinder", mode="kinematic", rtf=2.0))
    print(goal_summary(result))
"""

from __future__ import annotations

import json
import math
import sys
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from go2vlm.apps.follow_demo import (
    shutdown_nodes,
    shutdown_request,
    sim_clock,
    sim_node_params,
    sim_time,
    start_nodes,
)
from go2vlm.behavior.goals import GoalParseError, parse_goal, parse_target
from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node, ShutdownRequested
from go2vlm.geometry.rotations import quat_yaw
from go2vlm.msgs.geometry_msgs import Twist
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.tf2_msgs import TFMessage
from go2vlm.robots.go2 import spec

__all__ = ["GoalDemoOptions", "GoalDemoResult", "goal_summary", "run_goal_demo"]

ROBOT_HALF_LENGTH = spec.FOOTPRINT_LENGTH / 2
ROBOT_HALF_WIDTH = spec.FOOTPRINT_WIDTH / 2
SUCCESS_STATES = {"go_to": "reached", "look_for": "found"}


@dataclass
class GoalDemoOptions:
    goal: str
    world: str | None = None  # None: follow_ball for following a ball, else vision_test
    mode: str = "kinematic"
    rtf: float = 1.0
    fast: bool = False
    timeout_s: float = 60.0  # sim seconds before go to / look for give up
    follow_duration_s: float = 30.0  # sim seconds a follow goal runs
    settle_s: float = 1.0  # sim seconds kept running after the goal is reached (it must stay put)
    spawn: list[float] | None = None
    grounding: str = "color"
    camera_width: int = 640
    camera_height: int = 480
    camera_rate_hz: float = 10.0
    ball_speed: float = 0.3
    success_distance_m: float = 1.0
    follow_success_m: float = 2.5
    params: dict[str, dict[str, Any]] = field(default_factory=dict)  # node kind -> extra parameters
    out: Path | None = None  # write metrics.json here
    interface: str | None = None
    domain_id: int | None = None
    startup_timeout_s: float = 60.0
    progress: bool = False


@dataclass
class GoalDemoResult:
    metrics: dict[str, Any]
    out_dir: Path | None = None


@dataclass(frozen=True)
class _Shape:
    kind: str  # circle | rect
    x: float
    y: float
    yaw: float = 0.0
    r: float = 0.0  # circle radius
    hx: float = 0.0  # rect half sizes
    hy: float = 0.0


class GoalRecorder(Node):
    """Listens like any other node: the commander's status, /cmd_vel, ground truth and the clock."""

    name = "goal_recorder"

    def __init__(self, config: Any = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        self.lock = threading.Lock()
        self.sim_time = -1.0
        self.status: list[tuple[float, dict[str, Any]]] = []  # (sim time, status)
        self.cmds: list[tuple[float, float, float]] = []  # sim time, vx, wz on /cmd_vel
        self.behavior: list[tuple[float, float, float]] = []  # on /behavior/cmd_vel
        self.poses: list[tuple[float, dict[str, tuple[float, float, float]]]] = []  # sim t, name -> x, y, yaw
        self.create_subscription(Clock, "/clock", self._on_clock, QOS_DEFAULT)
        self.create_subscription(String, "/commander/status", self._on_status, QOS_LATCHED)
        self.create_subscription(Twist, "/cmd_vel", lambda m: self._on_twist(self.cmds, m), QOS_DEFAULT)
        self.create_subscription(Twist, "/behavior/cmd_vel", lambda m: self._on_twist(self.behavior, m), QOS_DEFAULT)
        self.create_subscription(TFMessage, "/sim/ground_truth", self._on_gt, QOS_DEFAULT)

    def _on_clock(self, msg: Clock) -> None:
        self.sim_time = msg.clock.to_sec()

    def _on_status(self, msg: String) -> None:
        try:
            st = json.loads(msg.data)
        except ValueError:
            self.count("bad_status")
            return
        with self.lock:
            self.status.append((self.sim_time, st))

    def _on_twist(self, into: list[tuple[float, float, float]], msg: Twist) -> None:
        with self.lock:
            into.append((self.sim_time, msg.linear.x, msg.angular.z))

    def _on_gt(self, msg: TFMessage) -> None:
        poses = {}
        for tf in msg.transforms:
            t = tf.transform.translation
            q = tf.transform.rotation
            poses[tf.child_frame_id.removeprefix("gt/")] = (t.x, t.y, quat_yaw(q.w, q.x, q.y, q.z))
        with self.lock:
            self.poses.append((self.sim_time, poses))

    def latest_state(self) -> str | None:
        with self.lock:
            return self.status[-1][1].get("state") if self.status else None


# -- geometry ----------------------------------------------------------------------------------


def world_shapes(model: Any) -> dict[str, _Shape]:
    """Footprints of the named non-robot bodies of a MuJoCo model (spheres, cylinders, boxes)."""
    import mujoco

    robot_root = model.body("base").id
    out: dict[str, _Shape] = {}
    for g in range(model.ngeom):
        b = int(model.geom_bodyid[g])
        if b == 0 or model.body_rootid[b] == robot_root:
            continue
        name = model.body(b).name
        if not name or name in out:
            continue
        t, size = int(model.geom_type[g]), model.geom_size[g]
        pos = model.body_pos[b]
        q = model.body_quat[b]
        yaw = math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2))
        if t in (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
            out[name] = _Shape("circle", float(pos[0]), float(pos[1]), r=float(size[0]))
        elif t == mujoco.mjtGeom.mjGEOM_BOX:
            out[name] = _Shape("rect", float(pos[0]), float(pos[1]), yaw, hx=float(size[0]), hy=float(size[1]))
    return out


def _to_local(px: float, py: float, x: float, y: float, yaw: float) -> tuple[float, float]:
    dx, dy = px - x, py - y
    c, s = math.cos(yaw), math.sin(yaw)
    return c * dx + s * dy, -s * dx + c * dy


def _rect_dist(px: float, py: float, x: float, y: float, yaw: float, hx: float, hy: float) -> float:
    """Signed distance from a point to an oriented rectangle (negative inside)."""
    lx, ly = _to_local(px, py, x, y, yaw)
    dx, dy = abs(lx) - hx, abs(ly) - hy
    outside = math.hypot(max(dx, 0.0), max(dy, 0.0))
    return outside if outside > 0 else max(dx, dy)


def _rect_points(x: float, y: float, yaw: float, hx: float, hy: float, n: int = 12) -> list[tuple[float, float]]:
    c, s = math.cos(yaw), math.sin(yaw)
    pts = []
    for i in range(n):
        f = -1.0 + 2.0 * i / (n - 1)
        for lx, ly in ((f * hx, hy), (f * hx, -hy), (hx, f * hy), (-hx, f * hy)):
            pts.append((x + c * lx - s * ly, y + s * lx + c * ly))
    return pts


def clearance(robot: tuple[float, float, float], shape: _Shape) -> float:
    """Gap between the robot's footprint and an object's footprint (negative: they overlap)."""
    rx, ry, ryaw = robot
    if shape.kind == "circle":
        return _rect_dist(shape.x, shape.y, rx, ry, ryaw, ROBOT_HALF_LENGTH, ROBOT_HALF_WIDTH) - shape.r
    a = min(_rect_dist(px, py, rx, ry, ryaw, ROBOT_HALF_LENGTH, ROBOT_HALF_WIDTH) for px, py in
            _rect_points(shape.x, shape.y, shape.yaw, shape.hx, shape.hy))  # fmt: skip
    b = min(_rect_dist(px, py, shape.x, shape.y, shape.yaw, shape.hx, shape.hy) for px, py in
            _rect_points(rx, ry, ryaw, ROBOT_HALF_LENGTH, ROBOT_HALF_WIDTH))  # fmt: skip
    return min(a, b)


def surface_distance(robot: tuple[float, float, float], shape: _Shape) -> float:
    """Base centre -> the object's surface: centre distance minus radius, or distance to a box footprint."""
    if shape.kind == "circle":
        return math.hypot(shape.x - robot[0], shape.y - robot[1]) - shape.r
    return _rect_dist(robot[0], robot[1], shape.x, shape.y, shape.yaw, shape.hx, shape.hy)


def target_body(goal_text: str, names: list[str]) -> str | None:
    """The world body the goal's object names (red_sphere for "the red ball", ...)."""
    try:
        goal = parse_goal(goal_text)
    except GoalParseError:
        return None
    if goal.target is None:
        return None
    for name in sorted(names):
        try:
            t = parse_target(name.replace("_", " "))
        except GoalParseError:
            continue
        if (goal.target.color is None or t.color == goal.target.color) and (
            goal.target.shape is None or t.shape == goal.target.shape
        ):
            return name
    return None


# -- orchestration -------------------------------------------------------------------------------


def _pick_world(opts: GoalDemoOptions) -> str:
    if opts.world:
        return opts.world
    try:
        goal = parse_goal(opts.goal)
    except GoalParseError:
        return "vision_test"
    if goal.kind == "follow" and goal.target is not None and goal.target.shape in (None, "ball"):
        return "follow_ball"
    return "vision_test"


def build_nodes(opts: GoalDemoOptions, world: str) -> list[Node]:
    from go2vlm.launch.registry import make_node

    common: dict[str, Any] = {"interface": opts.interface, "domain_id": opts.domain_id}
    sim_params = sim_node_params(opts, world)
    if opts.spawn:
        sim_params["spawn"] = list(opts.spawn)
    sim_params.update(opts.params.get("sim", {}))
    cmd_params: dict[str, Any] = {"goal": opts.goal, **opts.params.get("commander", {})}
    tracker_params: dict[str, Any] = {"grounding": opts.grounding, **opts.params.get("target_tracker", {})}
    nodes = [
        make_node("sim", params=sim_time(sim_params), **common),
        make_node("target_tracker", params=sim_time(tracker_params), **common),
        make_node("commander", params=sim_time(cmd_params), **common),
    ]
    try:
        kind = parse_goal(opts.goal).kind
    except GoalParseError:
        kind = "invalid"
    if kind == "follow" and cmd_params.get("follow_control", "follower") == "follower":
        nodes.append(make_node("follower", params=sim_time(opts.params.get("follower", {})), **common))
    nodes.append(make_node("safety", params=sim_time(opts.params.get("safety", {})), **common))
    return nodes


def run_goal_demo(opts: GoalDemoOptions, shutdown: ShutdownRequested | None = None) -> GoalDemoResult:
    """Run one goal in the sim until it is reached/found (+ settle_s), or the timeout; measure it."""
    stop = shutdown_request(shutdown)
    try:
        kind = parse_goal(opts.goal).kind
    except GoalParseError:
        kind = "invalid"
    world = _pick_world(opts)
    recorder = GoalRecorder(interface=opts.interface, domain_id=opts.domain_id, use_sim_time=True)
    nodes = build_nodes(opts, world)
    sim = nodes[0]
    shapes = world_shapes(sim.sim.model)  # type: ignore[attr-defined]
    wall0 = time.monotonic()  # wall time: the demo's start-up deadline and wall_s
    start_nodes(recorder, nodes)
    interrupted = False
    t0: float | None = None
    t_done: float | None = None
    limit = opts.follow_duration_s if kind == "follow" else opts.timeout_s
    try:
        for t in sim_clock(stop, recorder, wall0, opts.startup_timeout_s, 0.05):
            if t0 is None:
                t0 = t
            state = recorder.latest_state()
            if t_done is None and kind != "follow" and state in ("reached", "found", "not_found", "done",
                                                                 "stopped", "rejected", "sat"):  # fmt: skip
                t_done = t
            if t_done is not None and t - t_done >= opts.settle_s:
                break
            if t - t0 >= limit:
                break
            if opts.progress:
                print(f"\rsim {t - t0:6.1f} s  state {state}   ", end="", file=sys.stderr, flush=True)
        else:
            interrupted = True
    finally:
        wall_s = time.monotonic() - wall0
        shutdown_nodes(recorder, nodes)
        if opts.progress:
            print(file=sys.stderr)
    metrics = compute_metrics(recorder, shapes, opts, world, kind, t0 or 0.0, wall_s)
    metrics["interrupted"] = interrupted
    out = Path(opts.out) if opts.out else None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "metrics.json").write_text(json.dumps(metrics, indent=2, ensure_ascii=False) + "\n")
    return GoalDemoResult(metrics, out)


def compute_metrics(
    rec: GoalRecorder, shapes: dict[str, _Shape], opts: GoalDemoOptions, world: str, kind: str, t0: float, wall_s: float
) -> dict[str, Any]:
    with rec.lock:
        status = list(rec.status)
        cmds = list(rec.cmds)
        behavior = list(rec.behavior)
        poses = list(rec.poses)
    target = target_body(opts.goal, [*shapes, *{n for _, p in poses for n in p if n != "go2"}])
    states = [s.get("state") for _, s in status]
    first = {}
    for t, s in status:
        first.setdefault(s.get("state"), t)
    success_state = SUCCESS_STATES.get(kind)
    t_goal = first.get(success_state) if success_state else None
    # Geometry over time (moving bodies take their pose from ground truth).
    min_clear = math.inf
    collisions = 0
    colliding = False
    dists: list[tuple[float, float]] = []
    for t, p in poses:
        robot = p.get("go2")
        if robot is None:
            continue
        worst = math.inf
        for name, shape in shapes.items():
            if name in p:
                shape = _Shape(shape.kind, p[name][0], p[name][1], p[name][2], shape.r, shape.hx, shape.hy)
            worst = min(worst, clearance(robot, shape))
            if name == target:
                dists.append((t, surface_distance(robot, shape)))
        min_clear = min(min_clear, worst)
        if worst < 0 and not colliding:
            collisions += 1
        colliding = worst < 0
    final_dist = dists[-1][1] if dists else None
    last_state = states[-1] if states else None
    final = status[-1][1] if status else {}
    in_view = None
    if poses and target and "go2" in poses[-1][1] and target in shapes:
        rx, ry, ryaw = poses[-1][1]["go2"]
        tx, ty = poses[-1][1].get(target, (shapes[target].x, shapes[target].y, 0.0))[:2]
        bearing = math.atan2(ty - ry, tx - rx) - ryaw
        bearing = math.atan2(math.sin(bearing), math.cos(bearing))
        hfov = math.radians(spec.head_camera_hfov_deg(opts.camera_width, opts.camera_height))
        in_view = abs(bearing) < hfov / 2
    travelled = 0.0
    track = [p["go2"] for _, p in poses if "go2" in p]
    for a, b in zip(track, track[1:], strict=False):
        travelled += math.hypot(b[0] - a[0], b[1] - a[1])
    m: dict[str, Any] = {
        "goal": opts.goal,
        "kind": kind,
        "world": world,
        "mode": opts.mode,
        "target_body": target,
        "final_state": last_state,
        "final_reason": final.get("reason"),
        "states": _dedupe(states),
        "time_to_goal_s": None if t_goal is None else round(t_goal - t0, 2),
        "final_distance_m": None if final_dist is None else round(final_dist, 3),
        "min_distance_m": round(min(d for _, d in dists), 3) if dists else None,
        "collisions": collisions,
        "min_clearance_m": None if not math.isfinite(min_clear) else round(min_clear, 3),
        "target_in_view_at_end": in_view,
        "robot_distance_travelled_m": round(travelled, 3),
        "max_abs_cmd_vx": round(max((abs(c[1]) for c in cmds), default=0.0), 3),
        "max_abs_cmd_wz": round(max((abs(c[2]) for c in cmds), default=0.0), 3),
        "max_behavior_vx": round(max((c[1] for c in behavior), default=0.0), 3),
        "final_cmd": [round(cmds[-1][1], 3), round(cmds[-1][2], 3)] if cmds else None,
        "sim_s": round((poses[-1][0] - t0) if poses else 0.0, 2),
        "wall_s": round(wall_s, 2),
        "commander_counters": final.get("counters", {}),
    }
    if kind == "go_to":
        m["goal_reached"] = bool(
            t_goal is not None and final_dist is not None and final_dist <= opts.success_distance_m and collisions == 0
        )
    elif kind == "look_for":
        m["goal_reached"] = bool(t_goal is not None and in_view)
    elif kind == "follow":
        seen_t = [t for t, s in status if s.get("seen")]
        start = seen_t[0] if seen_t else None
        after = [(t, s) for t, s in status if start is not None and t >= start]
        tracked = sum(1 for _, s in after if s.get("seen")) / len(after) if after else 0.0
        near = [d for t, d in dists if start is not None and t >= start]
        close = sum(1 for d in near if d <= opts.follow_success_m) / len(near) if near else 0.0
        m["tracked_fraction"] = round(tracked, 3)
        m["within_follow_distance_fraction"] = round(close, 3)
        m["mean_distance_m"] = round(sum(near) / len(near), 3) if near else None
        m["goal_reached"] = bool(tracked >= 0.7 and close >= 0.7 and collisions == 0)
    else:
        m["goal_reached"] = last_state in ("stopped", "done")
    m["options"] = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(opts).items()}
    return m


def _dedupe(states: list[Any]) -> list[Any]:
    out: list[Any] = []
    for s in states:
        if not out or out[-1] != s:
            out.append(s)
    return out


def goal_summary(result: GoalDemoResult) -> str:
    m = result.metrics

    def f(v: Any, unit: str = "") -> str:
        return "n/a" if v is None else (f"{v:.2f}{unit}" if isinstance(v, float) else f"{v}{unit}")

    lines = [
        f"go2vlm demo --goal {m['goal']!r}: {'REACHED' if m['goal_reached'] else 'NOT reached'} "
        f"({m['kind']}, world {m['world']}, {m['mode']} physics, {f(m['sim_s'], ' s')} sim in {f(m['wall_s'], ' s')})",
        f"  final state:     {m['final_state']} ({m['final_reason']})",
        f"  states:          {' -> '.join(map(str, m['states']))}",
        f"  target body:     {m['target_body']}",
        f"  time to goal:    {f(m['time_to_goal_s'], ' s')}",
        f"  final distance:  {f(m['final_distance_m'], ' m')} (base centre -> object surface)",
        f"  collisions:      {m['collisions']} (min clearance {f(m['min_clearance_m'], ' m')})",
    ]
    if m["kind"] == "follow":
        lines.append(
            f"  follow:          tracked {100 * m['tracked_fraction']:.0f} %, "
            f"within {m['options']['follow_success_m']} m {100 * m['within_follow_distance_fraction']:.0f} %, "
            f"mean distance {f(m['mean_distance_m'], ' m')}"
        )
    if result.out_dir is not None:
        lines.append(f"  wrote:           {result.out_dir / 'metrics.json'}")
    return "\n".join(lines)
