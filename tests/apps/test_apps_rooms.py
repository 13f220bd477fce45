"""The apartment world and the suites whose object is in another room (rooms, household_cross): the
world's rooms, doorways and objects, and every episode's spawn (clear of everything, in another room
than its object). Pure: the world models are compiled, nothing is stepped."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from go2vlm.apps.episodes.episode import target_body
from go2vlm.apps.episodes.suites import SuiteError, load_suite, world_bodies
from go2vlm.behavior.goals import parse_goal
from go2vlm.geometry.footprint import Footprint, clearance
from go2vlm.robot_profile.go2 import SIM
from go2vlm.sim.lidar import Lidar
from go2vlm.sim.worlds import world_footprints, world_info, world_model

CELL = 0.05  # m, the grid the doorways are checked on


def _free(world: str, margin: float) -> tuple[np.ndarray, float, float]:
    """Floor cells at least `margin` from every object and wall (the room boxes' outer bounds)."""
    shapes = world_footprints(world_model(world)[0])
    rooms = world_info(world).rooms
    x0, y0 = min(r.x0 for r in rooms) - 0.5, min(r.y0 for r in rooms) - 0.5
    x1, y1 = max(r.x1 for r in rooms) + 0.5, max(r.y1 for r in rooms) + 0.5
    xs, ys = np.meshgrid(np.arange(x0, x1, CELL), np.arange(y0, y1, CELL), indexing="ij")
    free = np.ones(xs.shape, dtype=bool)
    for s in shapes.values():
        c, sn = math.cos(s.yaw), math.sin(s.yaw)
        lx, ly = c * (xs - s.x) + sn * (ys - s.y), -sn * (xs - s.x) + c * (ys - s.y)
        if s.kind == "circle":
            d = np.hypot(lx, ly) - s.r
        else:
            d = np.hypot(np.maximum(np.abs(lx) - s.hx, 0), np.maximum(np.abs(ly) - s.hy, 0))
        free &= d > margin
    return free, x0, y0


def _cell(x: float, y: float, x0: float, y0: float) -> tuple[int, int]:
    return int(round((x - x0) / CELL)), int(round((y - y0) / CELL))


def test_the_apartment_has_rooms_off_a_corridor_with_wide_doorways() -> None:
    info, house = world_info("apartment"), world_info("household")
    names = [r.name for r in info.rooms]
    assert "corridor" in names and len(names) >= 4, "at least three rooms and the corridor"
    area = sum((r.x1 - r.x0) * (r.y1 - r.y0) for r in info.rooms)
    assert area > 1.3 * sum((r.x1 - r.x0) * (r.y1 - r.y0) for r in house.rooms), "larger than household"
    # Every room is reached from the corridor by a robot kept 0.5 m from everything: each doorway is
    # wider than 1.0 m, and no furniture blocks the way in.
    free, x0, y0 = _free("apartment", 0.5)
    labels, _ = ndimage.label(free)
    spawns = dict(info.room_spawns)
    corridor = labels[_cell(*spawns["corridor"][:2], x0, y0)]
    assert corridor > 0
    for room in names:
        assert labels[_cell(*spawns[room][:2], x0, y0)] == corridor, f"{room} is not reached from the corridor"
    # ... and only through the doorways: with 0.65 m kept (a 1.3 m gap) every room is closed off.
    closed, _, _ = _free("apartment", 0.65)
    labels, _ = ndimage.label(closed)
    assert len({labels[_cell(*spawns[r][:2], x0, y0)] for r in names}) == len(names)


def test_the_apartment_has_household_objects_and_one_of_each_colour() -> None:
    bodies = set(world_bodies("apartment"))
    assert {"teddy_bear", "duck", "soccer_ball", "toy_chest", "tray", "mug", "cone", "yellow_lego_brick"} <= bodies
    assert {"red_ball", "green_box", "blue_cylinder", "sofa", "bed", "desk", "dining_table"} <= bodies
    for colour in ("red", "green", "blue"):  # the colour grounder's answer names one object
        assert len([b for b in bodies if b.startswith(f"{colour}_")]) == 1, colour
    info = world_info("apartment")
    shapes = world_footprints(world_model("apartment")[0])
    for name, s in shapes.items():
        if not name.startswith("wall"):
            assert info.room_of(s.x, s.y) not in (None, "corridor"), f"{name} stands in a room"


@pytest.mark.parametrize("world", ["apartment", "household"])
def test_every_room_has_a_clear_spawn_in_it(world: str) -> None:
    info = world_info(world)
    shapes = world_footprints(world_model(world)[0])
    assert {r.name for r in info.rooms} == {room for room, _ in info.room_spawns}
    for room, (x, y, yaw) in info.room_spawns:
        assert info.room_of(x, y) == room
        robot = Footprint.rect(x, y, yaw, SIM.footprint_length, SIM.footprint_width)
        assert min(clearance(robot, s) for s in shapes.values()) >= 0.5, room
    with pytest.raises(ValueError, match="no spawn in a room 'garage'.*kitchen"):
        info.room_spawn("garage")


def test_the_lidar_sees_the_corridor_walls() -> None:
    import mujoco

    model, _ = world_model("apartment")

    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    points = Lidar(model, model.body("base").id).scan(data)  # the robot in the corridor, facing along it
    level = points[np.abs(points[:, 2]) < 0.02]  # the horizon row
    side = level[np.abs(np.abs(np.arctan2(level[:, 1], level[:, 0])) - math.pi / 2) < 0.05]
    assert len(side) >= 2 and np.allclose(np.abs(side[:, 1]), 0.75, atol=0.1), side  # the walls either side


def _check_cross_room(name: str) -> dict[str, int]:
    """Every episode: its object is a body of its world, its spawn is clear of everything by the
    task's margin and in another room than its object. Returns episodes per (world, kind)."""
    suite = load_suite(name)
    counts: dict[str, int] = {}
    for k in range(suite.episodes):
        ep = suite.episode(k, "oracle")
        info, shapes = world_info(ep.world), world_footprints(world_model(ep.world)[0])
        body = target_body(ep.goal, sorted(shapes), ep.target)
        assert body in shapes, ep
        assert ep.spawn is not None
        x, y, yaw = ep.spawn
        robot = Footprint.rect(x, y, yaw, SIM.footprint_length, SIM.footprint_width)
        assert min(clearance(robot, s) for s in shapes.values()) >= 0.5 - 1e-6, ep
        here, there = info.room_of(x, y), info.room_of(shapes[body].x, shapes[body].y)
        assert here is not None and there is not None and here != there, (ep.id, here, there)
        key = f"{ep.world} {ep.kind} {here}->{there}"
        counts[key] = counts.get(key, 0) + 1
        assert ep.duration_s >= 150, "time to walk through a doorway and look round"
    return counts


def test_the_rooms_suite_crosses_rooms_both_ways_in_both_worlds() -> None:
    suite = load_suite("rooms")
    assert suite.episodes >= 40 and suite.episodes == len(suite.tasks), "one episode per task"
    counts = _check_cross_room("rooms")
    for world in ("apartment", "household"):
        for kind in ("go_to", "look_for"):
            assert sum(n for key, n in counts.items() if key.startswith(f"{world} {kind}")) >= 4, (world, kind)
    assert sum(n for key, n in counts.items() if key.startswith("household") and "kitchen->living" in key) >= 8
    assert sum(n for key, n in counts.items() if key.startswith("household") and "living->kitchen" in key) >= 8
    # The colour block comes first: `--episodes 12 --perception color` runs the colour targets alone.
    colours = [suite.episode(k, "color") for k in range(12)]
    assert all(parse_goal(e.goal or "").target.color is not None for e in colours)
    assert {e.target for e in colours} == {"red_ball", "green_box", "blue_cylinder"}
    assert all(parse_goal(suite.episode(k, "color").goal or "").target.color is None for k in range(12, 28))


@pytest.mark.parametrize(("world", "door"), [("apartment_door080", 0.8), ("apartment_door090", 0.9)])
def test_the_narrow_door_apartments_differ_only_in_their_doorways(world: str, door: float) -> None:
    """scripts/narrow_doorways.py's variants: the apartment's rooms, spawns and objects, every doorway
    `door` m clear: a robot kept door/2 - 0.05 m from everything still reaches every room from the
    corridor, one kept door/2 + 0.05 m reaches none."""
    info, base = world_info(world), world_info("apartment")
    assert info.rooms == base.rooms and info.room_spawns == base.room_spawns
    shapes, plain = world_footprints(world_model(world)[0]), world_footprints(world_model("apartment")[0])
    assert {n for n in shapes if not n.startswith("wall")} == {n for n in plain if not n.startswith("wall")}
    names = [r.name for r in info.rooms]
    spawns = dict(info.room_spawns)
    free, x0, y0 = _free(world, door / 2 - 0.05)
    labels, _ = ndimage.label(free)
    assert len({labels[_cell(*spawns[r][:2], x0, y0)] for r in names}) == 1, "a doorway is narrower"
    closed, _, _ = _free(world, door / 2 + 0.05)
    labels, _ = ndimage.label(closed)
    assert len({labels[_cell(*spawns[r][:2], x0, y0)] for r in names}) == len(names), "a doorway is wider"


def test_rooms_narrow_crosses_rooms_through_both_widths() -> None:
    suite = load_suite("rooms_narrow")
    assert suite.episodes == len(suite.tasks), "one episode per task"
    counts = _check_cross_room("rooms_narrow")
    for world in ("apartment_door080", "apartment_door090"):
        assert sum(n for key, n in counts.items() if key.startswith(world)) >= 6, world
    # the widths alternate: any first few episodes take both
    assert {suite.episode(k, "oracle").world for k in range(2)} == {"apartment_door080", "apartment_door090"}


def test_household_cross_is_household_across_the_doorway() -> None:
    cross, home = load_suite("household_cross"), load_suite("household")
    assert cross.episodes == home.episodes
    assert [(t["goal"], t["target"]) for t in cross.tasks] == [(t["goal"], t["target"]) for t in home.tasks]
    counts = _check_cross_room("household_cross")
    assert {key.split()[-1] for key in counts} == {"kitchen->living", "living->kitchen"}


def test_suite_anchors_live_under_x_keys(tmp_path: object) -> None:
    from pathlib import Path

    path = Path(str(tmp_path)) / "mine.yaml"
    path.write_text(
        "x-spots:\n  here: &here {x: [-1, 1], y: [-1, 1]}\n"
        "tasks:\n  - {world: vision_test, goal: go to the red ball, spawn: *here}\n"
    )
    assert load_suite(str(path)).tasks[0]["spawn"] == {"x": [-1, 1], "y": [-1, 1]}
    path.write_text("spots: 1\ntasks:\n  - {world: vision_test, goal: go to the red ball}\n")
    with pytest.raises(SuiteError, match="spots"):
        load_suite(str(path))


# -- the demo's spawn -------------------------------------------------------------------------------


def test_the_demo_spawn_is_a_room_or_a_pose() -> None:
    from go2vlm.apps.episodes.demo import demo_spawn

    assert demo_spawn("household", "kitchen") == world_info("household").room_spawn("kitchen")
    assert world_info("household").room_of(*demo_spawn("household", "kitchen")[:2]) == "kitchen"
    assert demo_spawn("apartment", "study") == world_info("apartment").room_spawn("study")
    assert demo_spawn("household", "1.5, -2, 0.5") == (1.5, -2.0, 0.5)
    with pytest.raises(ValueError, match="no spawn in a room 'attic'.*living, kitchen"):
        demo_spawn("household", "attic")
    with pytest.raises(ValueError, match="finite"):
        demo_spawn("household", "nan,0,0")


def test_a_goal_in_a_generated_house_has_the_houses_suite_s_time() -> None:
    """`go2vlm demo --world house:3 --goal "look for the teddy bear"` searches several rooms: 60 s ended
    it while it was still exploring; it runs as long as a houses episode does."""
    from go2vlm.apps.episodes.demo import DEMO_S, demo_duration
    from go2vlm.apps.episodes.suites import load_suite

    houses = {t["duration_s"] for t in load_suite("houses").tasks}
    assert demo_duration("house:3", "look for the teddy bear") == max(houses) > DEMO_S
    assert demo_duration("household", "go to the duck") == demo_duration("house:3", None) == DEMO_S


def test_a_bad_demo_spawn_is_refused_before_anything_starts(tmp_path: object) -> None:
    import subprocess

    from busutil import GO2VLM, env

    proc = subprocess.run(
        [*GO2VLM, "demo", "--world", "vision_test", "--spawn", "kitchen", "--goal", "go to the red ball",
         "--out", str(tmp_path), "--no-progress"],
        capture_output=True, text=True, timeout=120, env=env(),
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "'vision_test' has no spawn in a room 'kitchen'" in proc.stderr.strip().splitlines()[-1]


@pytest.mark.slow
def test_the_demo_spawns_the_dog_in_the_kitchen(tmp_path: object) -> None:
    """`go2vlm demo --world household --spawn kitchen --goal "go to the duck"`, a few sim seconds: the
    robot's first recorded pose is in the kitchen, the duck in the living room; the map node's map is
    kept and saved (map.npz, map.png)."""
    import json
    import subprocess
    from pathlib import Path

    from busutil import GO2VLM, env

    out = Path(str(tmp_path)) / "demo"
    proc = subprocess.run(
        [*GO2VLM, "demo", "--world", "household", "--spawn", "kitchen", "--goal", "go to the duck",
         "--duration", "3", "--fast", "--mode", "kinematic", "--no-video", "--no-progress", "--out", str(out)],
        capture_output=True, text=True, timeout=300, env=env(),
    )  # fmt: skip
    assert proc.returncode in (0, 1), proc.stderr[-3000:]  # 1: not reached in 3 s, as expected
    metrics = json.loads((out / "metrics.json").read_text())
    series = json.loads((out / "series.json").read_text())
    info = world_info("household")
    assert metrics["spawn"] == list(info.room_spawn("kitchen"))
    x, y = series["robot_xy"][0]
    assert info.room_of(x, y) == "kitchen"
    assert (out / "plot.png").is_file()
    # The graph has a map node: its newest map is in the series (the plot's), the metrics and the run folder.
    assert series["map"]["width"] * series["map"]["height"] == len(series["map"]["data"])
    assert metrics["map"]["free_m2"] > 1.0 and (out / "map.npz").is_file() and (out / "map.png").is_file()


def test_the_plot_draws_a_map_where_the_metrics_carry_one() -> None:
    """The hook the map fills in the demo's and eval's top view (apps/episodes/plot.py)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from go2vlm.apps.episodes.plot import draw_occupancy

    fig, ax = plt.subplots()
    draw_occupancy(ax, None)
    assert not ax.images
    grid = {"origin": [-1.0, -2.0], "resolution": 0.5, "width": 4, "height": 2, "data": [-1, 0, 100, 0] * 2}
    draw_occupancy(ax, grid)
    assert len(ax.images) == 1 and tuple(ax.images[0].get_extent()) == (-1.0, 1.0, -2.0, -1.0)
    rgb = ax.images[0].to_rgba(ax.images[0].get_array())[0, :3, :3]
    assert 0.5 < rgb[0].mean() < 0.9 and rgb[1].min() == 1.0 and rgb[2].max() == 0.0, (
        "unknown grey, free white, occupied black"
    )
    plt.close(fig)


def _nav_recording() -> object:
    """A Recording as the episode recorder keeps it in a graph with a map node: the newest /map and
    /map/costmap (a room 4 x 3 m, its east side unknown, a doorway in its north wall), two routes on
    /plan and the explorer's chosen frontier in /commander/status."""
    import numpy as np

    from go2vlm.apps.episodes.recorder import Recording
    from go2vlm.world.map_msg import Grid

    cells = np.full((80, 120), -1, dtype=np.int8)  # 0.05 m cells: 6 x 4 m
    cells[10:70, 10:90] = 0  # the known free room
    cells[10, 10:90] = cells[69, 10:90] = cells[10:70, 10] = 100
    cells[69, 40:56] = 0  # a doorway north, to the unknown
    grid = Grid(cells, (-1.0, -1.0), 0.05, "odom", 12.0)
    rec = Recording()
    rec.grid = rec.costmap = grid
    rec.plans = [(3.0, [(0.0, 0.0), (1.0, 1.0)]), (6.0, [(0.5, 0.5), (1.4, 2.0), (1.4, 2.6)])]
    explore = {"exploring": True, "frontier": {"id": 1, "centroid": [1.4, 2.5], "goal": [1.4, 2.4], "size_m": 0.8}}
    rec.commander = [
        (4.0, {"state": "exploring", "explore": explore}),
        (5.0, {"state": "exploring", "explore": explore}),
    ]
    return rec


def test_an_episode_with_a_map_keeps_it_coarse_with_frontiers_routes_and_files(tmp_path: object) -> None:
    """apps/episodes/navmap.py: the plot's map (cropped to the known cells, coarsened past
    MAX_PLOT_CELLS a side), the frontiers of the newest costmap, the frontiers walked to, the routes;
    map.npz / map.png in the run folder; nothing without a map."""
    from pathlib import Path

    import numpy as np

    from go2vlm.apps.episodes.navmap import coarse_grid, map_summary, nav_series, write_map_files
    from go2vlm.apps.episodes.recorder import Recording

    assert nav_series(Recording()) == {} and map_summary(Recording(), {}) is None
    rec = _nav_recording()
    nav = nav_series(rec)  # type: ignore[arg-type]
    g = nav["map"]
    assert g["width"] * g["height"] == len(g["data"]) and g["width"] <= 90, "cropped to the known cells"
    assert set(g["data"]) == {-1, 0, 100}
    assert nav["explored"] == [[1.4, 2.4]] and [t for t, _ in nav["plans"]] == [3.0, 6.0]
    north = [f for f in nav["frontiers"] if f[1] > 2.0]
    assert north and abs(north[0][0] - 1.375) < 0.3, "the doorway's frontier"
    summary = map_summary(rec, nav)  # type: ignore[arg-type]
    assert summary is not None and summary["plans"] == 2 and summary["frontiers_left"] == len(nav["frontiers"])
    big = coarse_grid(rec.grid.__class__(np.zeros((1000, 900), np.int8), (0.0, 0.0), 0.05, "odom", 0.0), 400)  # type: ignore[attr-defined]
    assert big is not None and max(big["width"], big["height"]) <= 400 and big["resolution"] == 0.15
    out = Path(str(tmp_path))
    files = write_map_files(rec.grid, out)  # type: ignore[attr-defined]
    assert sorted(files) == ["map_npz", "map_png"]
    with np.load(out / "map.npz") as z:
        assert np.array_equal(z["cells"], rec.grid.cells) and float(z["resolution"]) == 0.05  # type: ignore[attr-defined]
    import matplotlib.image

    assert matplotlib.image.imread(out / "map.png").shape[:2] == (80, 120)


def test_the_plot_draws_the_map_its_frontiers_and_routes(tmp_path: object) -> None:
    """write_plot with series from an episode whose graph had a map node: the top view draws the map
    image, the routes, the frontiers and the path taken, with a legend; plot.png is written."""
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from go2vlm.apps.episodes import plot
    from go2vlm.apps.episodes.navmap import nav_series

    series = {"gt_sim_t": [0.0, 1.0], "robot_xy": [[0.0, 0.0], [1.0, 1.0]], "target_xy": [[2.0, 2.0]] * 2,
              "distance": [2.0, 1.0], "states": [[0.0, "searching"]], "cmd": [[0.0, 0.3, 0.0]],
              **nav_series(_nav_recording())}  # type: ignore[arg-type]  # fmt: skip
    metrics = {"goal": "go to the duck", "success": True, "perception": "oracle", "final_state": "arrived",
               "target_body": "duck", "world": "household", "mode": "kinematic", "sim_s": 9.0,
               "path_length_m": 1.4, "collisions": 0}  # fmt: skip
    path = Path(str(tmp_path)) / "plot.png"
    plot.write_plot(metrics, series, {}, path)
    assert path.stat().st_size > 10_000
    fig = plot.draw_plot(metrics, series, {})
    top = fig.axes[-1]
    labels = top.get_legend_handles_labels()[1]
    assert len(top.images) == 1, "the map under the top view"
    for want in ("planned route (last)", "frontiers left", "frontiers walked to", "Go2 (ground truth)"):
        assert any(lab.startswith(want) for lab in labels), (want, labels)
    assert [t.get_text() for t in top.get_legend().get_texts()][-3:] == ["unknown", "free", "occupied"]
    plt.close(fig)


# -- the drift variant of an eval -------------------------------------------------------------------


def test_a_drift_run_sets_the_sims_odometry_and_is_a_row_of_its_own(tmp_path: object) -> None:
    from pathlib import Path

    from go2vlm.apps.episodes.evaluate import EvalError, EvalOptions, prepare
    from go2vlm.apps.episodes.outputs import append_jsonl
    from go2vlm.apps.episodes.report import write_report

    out = Path(str(tmp_path))
    plain = prepare(EvalOptions(suite="rooms", perception="oracle", out=out, episodes=2, fast=True))
    drift = prepare(EvalOptions(suite="rooms", perception="oracle", out=out, episodes=2, fast=True, odom_drift=1.0))
    assert all("odom_drift" not in ep.params.get("sim", {}) for ep in plain.episodes)
    assert all(ep.params["sim"]["odom_drift"] == 1.0 for ep in drift.episodes)
    assert drift.config["odom_drift"] == 1.0 and "odom_drift" not in plain.config
    assert drift.config["run_id"] != plain.config["run_id"]
    for bad in (0.0, -1.0, 11.0, math.nan):
        with pytest.raises(EvalError, match="--drift"):
            prepare(EvalOptions(suite="rooms", perception="oracle", out=out, episodes=1, odom_drift=bad))
    for prep, wins in ((plain, 2), (drift, 1)):
        config = {**{k: v for k, v in prep.config.items() if k != "suite_text"}, "git": {}, "machine": {}}
        for k in range(2):
            m = {"success": k < wins, "spl": 0.5, "kind": "go_to", "time_to_goal_s": 50.0, "collisions": 0,
                 "fell": False, "wall_s": 5.0, "grounding": None, "vlm": None}  # fmt: skip
            append_jsonl(out / "results.jsonl", {"config": config, "index": k, "metrics": m})
    rows = {r["suite"]: r for r in write_report(out)["groups"]}
    assert rows["rooms"]["success"] == 2 and rows["rooms"]["odom_drift"] is None
    assert rows["rooms (odometry drift 1)"]["success"] == 1 and rows["rooms (odometry drift 1)"]["odom_drift"] == 1.0
    assert "| rooms (odometry drift 1) | oracle |" in (out / "report.md").read_text()
