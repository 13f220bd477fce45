"""Suites: YAML files of tasks that expand into seeded episodes.

A suite is a packaged name (apps/episodes/suites/NAME.yaml: smoke, goals, follow, distractors,
obstacles, household, household_cross, referring, rooms, rooms_narrow, houses) or a path to a file of
your own (copy a packaged one and edit it):

    name: goals
    description: go to and look for each object of the VLM article's world from seeded random spawns
    episodes: 24            # default of --episodes
    seed: 0                 # default of --seed
    defaults:               # any field of Episode (episode.py) for every task
      mode: kinematic
      duration_s: 40        # follow: how long; other goals: the timeout (sim seconds)
    tasks:                  # episode k runs tasks[k % len(tasks)]
      - world: vision_test
        goals: [go to the red ball, look for the green box]   # one task per goal
        spawn:              # the world's own spawn when left out
          x: [-4, 4]        # a range: uniform; a number: fixed
          y: [-4, 4]
          yaw: [-3.14159, 3.14159]
          min_clearance_m: 0.5       # robot footprint <-> every object (default 0.4)
          min_goal_distance_m: 1.5   # base centre <-> the goal object's surface (default 1.3)
        ball_speed: {choice: [0.2, 0.4]}   # any numeric field: a number, [lo, hi] or {choice: [...]}
        params: {commander: {search_timeout_s: 20}}   # node name -> parameters
        target: red_ball    # the body the goal refers to (needed when its words do not name one body:
                            # "the ball under the table"); left out, the body whose name fits the goal

A task may be a generated house each episode instead of a world (the `houses` suite):

      - house: {first_seed: 1000, goal: go to}    # episode k: house first_seed + k (sim/houses),
                                                  # an object of it drawn, the robot in another room
                                                  # (that room's spawn); goal: go to | look for

A task naming one house (`world: house:17`) needs that house itself to pass its check: a house whose
seed would be replaced stops the suite before any episode runs.

Top-level keys starting with `x-` are left alone: a place for YAML anchors the tasks refer to
(`x-rooms: {kitchen: &kitchen {x: ..., y: ...}}`, then `spawn: *kitchen`).

A suite is checked before any episode runs: every world must load (its meshes too), and every goal's
object must be a body of its world (`target`, or the one its words name).

Reproducible: episode k draws from numpy's generator seeded with (seed, k) and nothing else, so an
episode is the same whatever --episodes, --workers or the order they run in.
"""

from __future__ import annotations

import functools
import hashlib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from go2vlm.apps.episodes.episode import Episode, task_kind
from go2vlm.errors import ConfigError

__all__ = ["SUITES_DIR", "Suite", "SuiteError", "available_suites", "load_suite"]

SUITES_DIR = Path(__file__).resolve().parent / "suites"
_SUITE_KEYS = {"name", "description", "episodes", "seed", "defaults", "tasks"}
_TASK_ONLY = {"goals", "spawn", "house"}
_HOUSE_KEYS = {"first_seed", "goal", "rooms"}
_HOUSE_GOALS = ("go to", "look for")
_SPAWN_KEYS = {"x", "y", "yaw", "min_clearance_m", "min_goal_distance_m"}
_EPISODE_FIELDS = {f.name for f in fields(Episode)} - {"id", "perception", "spawn", "seed"}
_MAX_TRIES = 2000


class SuiteError(ConfigError):
    """A suite file that cannot be found or read, or a task in it that is wrong."""


@dataclass
class Suite:
    name: str
    path: Path
    text: str  # the file as it was read: stored with every result
    description: str
    episodes: int
    seed: int
    tasks: list[dict[str, Any]] = field(default_factory=list)

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()

    def episode(self, k: int, perception: str, seed: int | None = None) -> Episode:
        """Episode k (0-based) of this suite for a perception variant, drawn from (seed, k)."""
        s = self.seed if seed is None else seed
        task = self.tasks[k % len(self.tasks)]
        rng = np.random.default_rng([s, k])
        values: dict[str, Any] = {}
        for key, v in task.items():
            if key in _TASK_ONLY or key == "params":
                continue
            values[key] = _draw(v, rng, key)
        spawn = _spawn(task, rng, k) if task.get("spawn") is not None else None
        if task.get("house") is not None:
            h = task["house"]
            world, goal, target, spawn = _house_episode(int(h["first_seed"]), str(h["goal"]), h.get("rooms"), rng, k)
            values.update(world=world, goal=goal, target=target)
        return Episode(
            **values,
            spawn=spawn,
            perception=perception,
            seed=(s * 1_000_003 + k) % 2**31,
            params={n: dict(p) for n, p in (task.get("params") or {}).items()},
            id=f"{self.name}/{k:03d}",
        )


def available_suites() -> list[str]:
    return sorted(p.stem for p in SUITES_DIR.glob("*.yaml"))


def _draw(v: Any, rng: np.random.Generator, key: str) -> Any:
    if isinstance(v, dict):
        if set(v) != {"choice"} or not isinstance(v["choice"], list) or not v["choice"]:
            raise SuiteError(f"{key}: expected a value, [lo, hi] or {{choice: [...]}}, got {v!r}")
        return v["choice"][int(rng.integers(len(v["choice"])))]
    if isinstance(v, list) and key not in ("goals",):
        if len(v) != 2 or not all(isinstance(x, (int, float)) for x in v):
            raise SuiteError(f"{key}: a range is [lo, hi], got {v!r}")
        return float(rng.uniform(v[0], v[1]))
    return v


def _spawn(task: dict[str, Any], rng: np.random.Generator, k: int) -> tuple[float, float, float]:
    """A spawn pose in the task's region, clear of every object and not already at the goal."""
    from go2vlm.apps.episodes.episode import target_body
    from go2vlm.geometry.footprint import Footprint, clearance, surface_distance
    from go2vlm.robot_profile.go2 import SIM

    sp = task["spawn"]
    shapes = _shapes(task["world"])
    goal = task.get("goal")
    body = target_body(goal, list(shapes), task.get("target"))
    target = shapes.get(body or "") if goal and task_kind(goal) != "follow" else None
    min_clear = float(sp.get("min_clearance_m", 0.4))
    min_goal = float(sp.get("min_goal_distance_m", 1.3))
    for _ in range(_MAX_TRIES):
        x, y, yaw = (float(_draw(sp.get(a, 0.0), rng, f"spawn.{a}")) for a in ("x", "y", "yaw"))
        robot = Footprint.rect(x, y, yaw, SIM.footprint_length, SIM.footprint_width)
        if any(clearance(robot, s) < min_clear for s in shapes.values()):
            continue
        if target is not None and surface_distance(x, y, target) < min_goal:
            continue
        return round(x, 3), round(y, 3), round(math.atan2(math.sin(yaw), math.cos(yaw)), 3)
    raise SuiteError(
        f"task {k % 1000}: no spawn in its region clears the objects by {min_clear} m ({_MAX_TRIES} tries)"
    )


def _house_episode(
    first_seed: int, verb: str, rooms: int | None, rng: np.random.Generator, k: int
) -> tuple[str, str, str, tuple[float, float, float]]:
    """Episode k of a house task: house first_seed + k, one of its objects drawn, the robot at the
    spawn of another room drawn. (world, goal, target body, spawn)."""
    from go2vlm.sim.houses import generate

    seed = first_seed + k
    house = generate(seed, rooms).house
    item = house.items[int(rng.integers(len(house.items)))]
    others = [r for r in house.rooms if r.name != item.room]
    start = others[int(rng.integers(len(others)))]
    world = f"house:{seed}" + ("" if rooms is None else f":rooms={rooms}")
    return world, f"{verb} the {item.name.replace('_', ' ')}", item.name, start.spawn


@functools.lru_cache(maxsize=16)
def _shapes(world: str) -> dict[str, Any]:
    from go2vlm.sim.worlds import world_footprints

    return world_footprints(_model(world))


@functools.lru_cache(maxsize=16)
def _model(world: str) -> Any:
    from go2vlm.sim.worlds import world_model

    return world_model(world)[0]


@functools.lru_cache(maxsize=16)
def world_bodies(world: str) -> tuple[str, ...]:
    """The labelled bodies of a world (the objects a goal may name); SuiteError when it does not load."""
    from go2vlm.sim.render import labelled_bodies

    try:
        model = _model(world)
    except Exception as exc:  # MuJoCo's XML, mesh and texture errors are ValueErrors; a bad file may be others
        first = str(exc).strip().splitlines()
        raise SuiteError(f"world {world!r} does not load: {first[0] if first else type(exc).__name__}") from None
    return tuple(sorted(labelled_bodies(model).values()))


def load_suite(name: str) -> Suite:
    """A packaged suite by name, or a suite file by path; SuiteError with the reason otherwise."""
    p = Path(name).expanduser()
    if not p.is_file():
        p = SUITES_DIR / f"{name}.yaml"
        if "/" in name or not p.is_file():
            raise SuiteError(f"suite {name!r} not found (no such file; packaged: {', '.join(available_suites())})")
    text = p.read_text(encoding="utf-8")
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise SuiteError(f"{p}: not valid YAML: {exc}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("tasks"), list) or not doc["tasks"]:
        raise SuiteError(f"{p}: expected a mapping with a non-empty `tasks:` list")
    unknown = {k for k in doc if not str(k).startswith("x-")} - _SUITE_KEYS  # x-...: anchors the tasks name
    if unknown:
        raise SuiteError(f"{p}: unknown key(s) {sorted(unknown)}; allowed: {', '.join(sorted(_SUITE_KEYS))}")
    defaults = doc.get("defaults") or {}
    if not isinstance(defaults, dict):
        raise SuiteError(f"{p}: defaults must be a mapping")
    tasks: list[dict[str, Any]] = []
    for i, raw in enumerate(doc["tasks"]):
        where = f"{p}: task #{i}"
        if not isinstance(raw, dict):
            raise SuiteError(f"{where}: expected a mapping, got {raw!r}")
        task = {**defaults, **raw}
        bad = set(task) - _EPISODE_FIELDS - _TASK_ONLY
        if bad:
            raise SuiteError(f"{where}: unknown key(s) {sorted(bad)}")
        if "house" in task:
            _check_house_task(task, where)
            tasks.append(task)
            continue
        if "world" not in task:
            raise SuiteError(f"{where}: needs a world (or a house)")
        if not isinstance(task.get("spawn", {}) or {}, dict) or set(task.get("spawn") or {}) - _SPAWN_KEYS:
            raise SuiteError(f"{where}: spawn takes {', '.join(sorted(_SPAWN_KEYS))}")
        goals = task.pop("goals", None)
        for goal in goals if goals is not None else [task.get("goal")]:
            t = {**task, "goal": goal}
            _check_task(t, where)
            tasks.append(t)
    suite = Suite(
        name=str(doc.get("name") or p.stem),
        path=p,
        text=text,
        description=str(doc.get("description") or ""),
        episodes=int(doc.get("episodes") or len(tasks)),
        seed=int(doc.get("seed") or 0),
        tasks=tasks,
    )
    return suite


def _check_house_task(task: Mapping[str, object], where: str) -> None:
    from go2vlm.sim.houses import HouseError, generate

    spec = task["house"]
    if not isinstance(spec, dict) or set(spec) - _HOUSE_KEYS or "first_seed" not in spec or "goal" not in spec:
        raise SuiteError(f"{where}: house takes first_seed, goal ({' | '.join(_HOUSE_GOALS)}) and rooms")
    if spec["goal"] not in _HOUSE_GOALS:
        raise SuiteError(f"{where}: a house task's goal is {' or '.join(_HOUSE_GOALS)}, not {spec['goal']!r}")
    if {"world", "goal", "goals", "spawn", "target"} & set(task):
        raise SuiteError(f"{where}: a house task draws its world, goal, target and spawn itself")
    try:
        generate(int(spec["first_seed"]), spec.get("rooms"))
    except (HouseError, TypeError, ValueError) as exc:
        raise SuiteError(f"{where}: {exc}") from None


def _check_task(task: dict[str, Any], where: str) -> None:
    from go2vlm.sim.houses import generate, is_house, parse_house
    from go2vlm.sim.worlds import world_path

    try:
        if is_house(task["world"]):  # a house the suite names: that very house must pass its check
            generate(*parse_house(task["world"]), strict=True)
        world_path(task["world"])
    except ValueError as exc:
        raise SuiteError(f"{where}: {exc}") from None
    goal = task.get("goal")
    if goal is not None and task_kind(goal) == "invalid":
        raise SuiteError(f"{where}: cannot understand the goal {goal!r}")
    if goal is not None and task_kind(goal) in ("follow", "go_to", "look_for"):
        from go2vlm.apps.episodes.episode import target_body

        bodies = list(world_bodies(task["world"]))
        named = task.get("target")
        if named is not None and named not in bodies:
            raise SuiteError(f"{where}: target {named!r} is not an object of world {task['world']!r}")
        if target_body(goal, bodies, named) is None:
            raise SuiteError(f"{where}: no object of world {task['world']!r} is what {goal!r} names")
    try:  # every drawn value must make a valid Episode: try the first draw
        rng = np.random.default_rng(0)
        vals = {k: _draw(v, rng, k) for k, v in task.items() if k not in _TASK_ONLY and k != "params"}
        Episode(**vals)
    except (TypeError, ValueError) as exc:
        raise SuiteError(f"{where}: {exc}") from None
