"""What an episode is: a world and a spawn pose, a task, a perception variant, and the node graph
that runs it (a launch YAML read through the launcher, with the episode's values as overrides).

Tasks: a language goal for the `commander` ("go to the blue cylinder", "look for the green box",
"follow the red ball", ...), or `goal=None`: the follow article's loop (colour detector + follower),
which is `go2vlm demo`.

Perception variants (goal episodes): which grounding feeds the tracker, and nothing else changes:
  oracle  the sim's ground-truth boxes of each head frame (/sim/detections, from a segmentation
          render): the upper bound of any detector
  color   the classical colour-shape grounder (perception/grounding.py), no weights
  vlm     the `vlm` node (mode=detect; a local model or an OpenAI-compatible server)

An episode may name its `target`, the body its goal refers to ("the ball under the table" is
red_ball): the metrics judge against that body, and the oracle answers with that body's box alone,
labelled as the commander asked, as a perfect model would. `answer_latency_s` (0 too) delivers the
answers late (oracle: the ground truth; vlm: the model's own, held back) through the `answer_delay`
node: the latency axis of `go2vlm eval --latency` (every point of it, 0 too, runs that graph). A
goal's timeout grows by TIMEOUT_PER_LATENCY_S per second of latency (`latency_timeout`): a search that
holds still for each answer needs time in proportion to it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from go2vlm.behavior.goals import GoalParseError, Target, parse_goal, parse_target

__all__ = [
    "FOLLOW_BALL_GOAL",
    "PERCEPTIONS",
    "TIMEOUT_PER_LATENCY_S",
    "latency_timeout",
    "Episode",
    "graph_name",
    "label_matches",
    "node_overrides",
    "target_body",
    "task_kind",
    "vlm_node_params",
]

FOLLOW_BALL_GOAL = "follow the red ball"  # the ball follow demo through the tracker (perception oracle/vlm)

PERCEPTIONS = ("oracle", "color", "vlm")
TIMEOUT_PER_LATENCY_S = 20.0  # sim seconds of a goal's timeout per second of answer latency


def latency_timeout(duration_s: float, latency_s: float, kind: str) -> float:
    """A goal's timeout with answers `latency_s` late (a follow runs its duration whatever the latency)."""
    return duration_s if kind == "follow" else duration_s + TIMEOUT_PER_LATENCY_S * latency_s


@dataclass(frozen=True)
class Episode:
    """One run of the robot in the sim. Everything that decides its outcome is here, so that the same
    Episode runs the same scenario again (up to how late the nodes answer in sim time)."""

    world: str
    goal: str | None = None  # None: the follow article's loop (colour detector + follower)
    perception: str = "color"  # oracle | color | vlm (goal episodes)
    spawn: tuple[float, float, float] | None = None  # x, y, yaw; None: the world's own
    seed: int = 0  # the sim's seed (initial joint noise, when the sim's init_noise > 0)
    mode: str = "kinematic"  # sim physics: kinematic | dynamic
    ball_speed: float = 0.3  # m/s, worlds with a moving ball
    duration_s: float = 60.0  # sim seconds: how long a follow runs; the timeout of other goals
    settle_s: float = 1.0  # sim seconds kept running after a goal ends (it must stay put)
    robot: str = "sim"  # sim | go2 (the follow loop through the Unitree protocol and the go2 driver)
    transport: str = "dds"  # robot go2: dds (Unitree DDS) | webrtc (the Unitree app's route)
    camera_width: int = 640
    camera_height: int = 480
    camera_rate_hz: float = 10.0
    success_distance_m: float = 1.0  # go to: within this of the object's surface
    follow_success_m: float = 2.5  # follow: within this of the ball's surface
    params: dict[str, dict[str, Any]] = field(default_factory=dict)  # node name -> more parameters
    id: str = ""  # a name in a suite (e.g. goals/007)
    graph: str | None = None  # a launch file (name or path) instead of the perception's packaged graph
    target: str | None = None  # the body the goal refers to; None: the one body whose name fits the goal's object
    answer_latency_s: float | None = None  # sim seconds the answers are held back (oracle, vlm); None: no latency axis

    def __post_init__(self) -> None:
        if self.perception not in PERCEPTIONS:
            raise ValueError(f"perception {self.perception!r} is not one of {', '.join(PERCEPTIONS)}")
        if self.goal is None and self.perception != "color":
            raise ValueError("the follow article's loop has its own colour detector: perception must be color")
        if self.mode not in ("kinematic", "dynamic"):
            raise ValueError(f"mode {self.mode!r} is not kinematic or dynamic")
        if self.robot not in ("sim", "go2"):
            raise ValueError(f"robot {self.robot!r} is not sim or go2")
        if self.transport not in ("dds", "webrtc"):
            raise ValueError(f"transport {self.transport!r} is not dds or webrtc")
        if self.transport != "dds" and self.robot != "go2":
            raise ValueError("--transport is how the go2 driver reaches the robot: it needs --robot go2")
        if self.robot == "go2" and self.goal is not None:
            raise ValueError("--robot go2 runs the follow article's loop only (no goal)")
        if self.duration_s <= 0:
            raise ValueError(f"duration must be positive, got {self.duration_s:g}")
        if self.answer_latency_s is not None and not self.answer_latency_s >= 0:
            raise ValueError(f"answer latency must be >= 0 s, got {self.answer_latency_s:g}")
        if self.answer_latency_s is not None and self.perception == "color":
            raise ValueError(
                "an answer latency is for the oracle and vlm variants (the colour grounder runs in the tracker)"
            )

    @property
    def kind(self) -> str:
        """follow | go_to | look_for | stop | sit | stand | invalid."""
        return "follow" if self.goal is None else task_kind(self.goal)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["spawn"] = list(self.spawn) if self.spawn is not None else None
        return d

    @staticmethod
    def from_dict(d: dict[str, Any]) -> Episode:
        d = dict(d)
        if d.get("spawn") is not None:
            d["spawn"] = tuple(float(v) for v in d["spawn"])
        return Episode(**d)


def task_kind(goal: str) -> str:
    try:
        return parse_goal(goal).kind
    except GoalParseError:
        return "invalid"


def graph_name(ep: Episode) -> str:
    """The launch graph that runs this episode: its own `graph`, else the packaged one for its task and perception."""
    if ep.graph is not None:
        return ep.graph
    if ep.goal is None:
        if ep.robot == "go2":
            return "follow_go2_sim_webrtc" if ep.transport == "webrtc" else "follow_go2_sim"
        return "follow_sim"
    if ep.perception == "oracle" and (ep.target is not None or ep.answer_latency_s is not None):
        return "episode_oracle_delay"
    if ep.perception == "vlm" and ep.answer_latency_s is not None:
        return "episode_vlm_delay"
    return f"episode_{ep.perception}"


def goal_target(goal: str | None) -> Target | None:
    if goal is None:
        return parse_target("red ball")  # the follow article's loop follows the red ball
    try:
        return parse_goal(goal).target
    except GoalParseError:
        return None


def label_matches(target: Target, label: str) -> bool:
    """True when a detection or body label names the target: colour and shape agree where the target
    names them ("red_sphere" and "red ball" are the same thing), and a category or phrase beyond them
    ("soccer ball", "red mug", "teddy bear") is the same words."""
    try:
        t = parse_target(label.replace("_", " "))
    except GoalParseError:
        return False
    if t.label != _canonical(t) or target.label != _canonical(target):
        return t.label == target.label
    return (target.color is None or t.color == target.color) and (target.shape is None or t.shape == target.shape)


def _canonical(t: Target) -> str:
    return " ".join(x for x in (t.color, t.shape) if x)


def target_body(goal: str | None, names: list[str], target: str | None = None) -> str | None:
    """The world body the goal refers to: `target` (an episode's own), else the body the goal's object
    names (red_sphere for "the red ball", ...); the first by name when several fit."""
    if target is not None:
        return target if target in names else None
    wanted = goal_target(goal)
    if wanted is None:
        return None
    fits = sorted(n for n in names if label_matches(wanted, n))
    return fits[0] if fits else None


def vlm_node_params(
    perception: str, model: str | None, base_url: str | None, params: dict[str, dict[str, Any]] | None = None
) -> dict[str, dict[str, Any]]:
    """`params` (node name -> parameters) with the vlm node's model and backend from --model / --base-url:
    transformers for a local checkpoint or hub id, openai when a server URL is given. The user's own
    `vlm.*` parameters win. ValueError for a vlm variant without a model, or a model for another variant."""
    out = {name: dict(p) for name, p in (params or {}).items()}
    if perception == "vlm":
        if not model:
            raise ValueError("--perception vlm needs --model (a checkpoint dir, a hub id, or the served model's name)")
        vlm: dict[str, Any] = {"model": model, "backend": "openai" if base_url else "transformers"}
        if base_url:
            vlm["base_url"] = base_url
        out["vlm"] = {**vlm, **out.get("vlm", {})}
    elif model or base_url:
        raise ValueError(f"--model and --base-url are for --perception vlm, not {perception}")
    return out


def free_tcp_port(host: str) -> int:
    import socket

    with socket.socket() as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


def node_overrides(ep: Episode, rtf: float, fast: bool) -> dict[str, dict[str, Any]]:
    """Parameters per node name that make the graph run this episode (the user's own `params` last)."""
    sim: dict[str, Any] = {
        "world": ep.world,
        "mode": ep.mode,
        "rtf": rtf,
        "fast": fast,
        "ball_speed": ep.ball_speed,
        "camera_width": ep.camera_width,
        "camera_height": ep.camera_height,
        "camera_rate_hz": ep.camera_rate_hz,
        "seed": ep.seed,
        "world_camera": False,  # nobody looks at it here: save the render time
    }
    if ep.spawn is not None:
        sim["spawn"] = list(ep.spawn)
    out: dict[str, dict[str, Any]] = {"sim": sim}
    if ep.robot == "go2":
        from go2vlm.robot_profile.go2 import GO2

        hfov = GO2.head_camera.hfov_deg(ep.camera_width, ep.camera_height)
        out["go2"] = {"camera_rate_hz": ep.camera_rate_hz, "camera_hfov_deg": round(hfov, 3)}
        if ep.transport == "webrtc":  # a free port on loopback, so that runs side by side do not meet
            port = free_tcp_port("127.0.0.1")
            sim.update(webrtc_host="127.0.0.1", webrtc_port=port)
            out["go2"].update(ip="127.0.0.1", signal_port=port)
    if ep.goal is not None:
        out["commander"] = {"goal": ep.goal}
    if graph_name(ep) in ("episode_oracle_delay", "episode_vlm_delay"):
        target = goal_target(ep.goal)
        out["answer_delay"] = {
            "latency_s": ep.answer_latency_s or 0.0,
            "target_body": (ep.target or "") if ep.perception == "oracle" else "",
            "target_label": target.label if target is not None and ep.perception == "oracle" else "",
        }
        if ep.perception == "oracle":  # the commander's frontier_choice vlm asks it which way (perception/way.py)
            from go2vlm.robot_profile.go2 import GO2

            half = GO2.head_camera.hfov_deg(ep.camera_width, ep.camera_height) / 2  # the episode camera's view
            out["way_oracle"] = {"target_body": ep.target or "", "half_view_deg": round(half, 3)}
    for name, values in ep.params.items():
        out.setdefault(name, {}).update(values)
    return out
