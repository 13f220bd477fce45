"""The episode runner's pure parts: suites -> seeded episodes, metrics from a recording, grounding
scores, confidence intervals, atomic files, graph overrides, the second-signal rule. No DDS, no sim
stepping (suites compile the world models to place spawns)."""

from __future__ import annotations

import math
import signal
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")

from go2vlm.apps.episodes.episode import Episode, graph_name, label_matches, node_overrides, target_body  # noqa: E402
from go2vlm.apps.episodes.metrics import Context, compute_metrics, flips, grounding_metrics  # noqa: E402
from go2vlm.apps.episodes.outputs import append_jsonl, atomic, read_jsonl, write_json  # noqa: E402
from go2vlm.apps.episodes.recorder import Recording  # noqa: E402
from go2vlm.apps.episodes.report import bootstrap_ci, wilson  # noqa: E402
from go2vlm.apps.episodes.suites import SuiteError, available_suites, load_suite  # noqa: E402
from go2vlm.behavior.goals import parse_target  # noqa: E402
from go2vlm.behavior.strategies.params import MissionParams  # noqa: E402
from go2vlm.bus import ShutdownRequested  # noqa: E402
from go2vlm.geometry.footprint import Footprint, clearance  # noqa: E402
from go2vlm.launch.launcher import LaunchError, load_launch, with_overrides  # noqa: E402
from go2vlm.robot_profile import go2 as spec  # noqa: E402
from go2vlm.sim.render import segmentation_boxes  # noqa: E402
from go2vlm.sim.worlds import world_footprints, world_model  # noqa: E402

# -- suites --------------------------------------------------------------------------------------


def test_packaged_suites_load_and_expand_reproducibly() -> None:
    assert {"smoke", "goals", "follow", "distractors", "obstacles", "injection"} <= set(available_suites())
    for name in available_suites():
        suite = load_suite(name)
        assert suite.episodes >= 1 and suite.tasks
        eps = [suite.episode(k, "color") for k in range(suite.episodes)]
        # Episode k depends on (seed, k) only: the same again, whatever else was drawn before.
        assert [suite.episode(k, "color") for k in reversed(range(suite.episodes))][::-1] == eps
        assert len({e.id for e in eps}) == len(eps)
        # Another seed moves the random spawns.
        if any(t.get("spawn") for t in suite.tasks):
            assert [suite.episode(k, "color", seed=1).spawn for k in range(suite.episodes)] != [e.spawn for e in eps]
    smoke = load_suite("smoke")
    assert smoke.episodes == 4 and {e.kind for e in (smoke.episode(k, "oracle") for k in range(4))} == {
        "look_for",
        "go_to",
        "follow",
    }


def test_spawns_are_clear_of_objects_and_away_from_the_goal() -> None:
    suite = load_suite("goals")
    shapes = world_footprints(world_model("vision_test")[0])
    for k in range(suite.episodes):
        ep = suite.episode(k, "color")
        x, y, yaw = ep.spawn
        robot = Footprint.rect(x, y, yaw, spec.FOOTPRINT_LENGTH, spec.FOOTPRINT_WIDTH)
        assert min(clearance(robot, s) for s in shapes.values()) >= 0.5 - 1e-6
        target = shapes[target_body(ep.goal, list(shapes))]
        assert math.hypot(target.x - x, target.y - y) - max(target.r, target.hx) >= 1.5 - 0.01
        assert -4 <= x <= 4 and -4 <= y <= 4 and -math.pi <= yaw <= math.pi


def test_the_follow_suite_covers_the_ball_speeds() -> None:
    suite = load_suite("follow")
    assert sorted({suite.episode(k, "oracle").ball_speed for k in range(suite.episodes)}) == [0.2, 0.4, 0.6, 0.8]


@pytest.mark.parametrize(
    ("text", "error"),
    [
        ("tasks: []", "non-empty"),
        ("tasks: [{world: vision_test, goal: go to the blue cylinder, bogus: 1}]", "bogus"),
        ("tasks: [{world: no_such_world, goal: go to the blue cylinder}]", "no_such_world"),
        ("tasks: [{world: vision_test, goal: dance please}]", "cannot understand"),
        ("tasks: [{world: vision_test, goal: go to the red ball, spawn: {z: 1}}]", "spawn takes"),
        ("tasks: [{world: vision_test, goal: go to the red ball, mode: warp}]", "mode"),
        ("nope: 1\ntasks: [{world: vision_test}]", "nope"),
        ("tasks: [", "YAML"),
    ],
)
def test_bad_suite_files_say_why(tmp_path: Path, text: str, error: str) -> None:
    path = tmp_path / "mine.yaml"
    path.write_text(text)
    with pytest.raises(SuiteError, match=error):
        load_suite(str(path))
    with pytest.raises(SuiteError, match="not found"):
        load_suite("no_such_suite")


# -- episodes and graphs ---------------------------------------------------------------------------


def test_episode_graphs_and_overrides() -> None:
    assert graph_name(Episode(world="follow_ball")) == "follow_sim"
    assert graph_name(Episode(world="follow_ball", robot="go2")) == "follow_go2_sim"
    for p in ("oracle", "color", "vlm"):
        ep = Episode(world="vision_test", goal="go to the blue cylinder", perception=p, spawn=(1, 2, 0.5))
        _, entries = load_launch(graph_name(ep))
        entries = with_overrides(entries, node_overrides(ep, 2.0, False), every={"use_sim_time": True})
        by = {e.name: e for e in entries}
        assert all(e.params["use_sim_time"] is True for e in entries)
        assert by["sim"].params["spawn"] == [1, 2, 0.5] and by["sim"].params["rtf"] == 2.0
        assert by["commander"].params["goal"] == "go to the blue cylinder"
        assert by["sim"].params.get("detections", False) is (p != "color")
        # The variant is the grounding that feeds the tracker; the commander's /target/query says what.
        assert by["target_tracker"].params["grounding"] == ("color" if p == "color" else "vlm")
        if p == "oracle":  # the oracle's boxes come from the sim, through the tracker's vlm input
            assert by["target_tracker"].remap == {"/vlm/detections": "/sim/detections"}
        if p == "vlm":
            assert by["vlm"].params["mode"] == "detect" and "labels" not in by["vlm"].params
    with pytest.raises(LaunchError, match="no node named 'vlm'"):
        with_overrides(load_launch("episode_color")[1], {"vlm": {"model": "x"}})
    for bad in (
        {"perception": "lidar", "goal": "go to the red ball"},
        {"perception": "oracle"},  # the follow article's loop has its own detector
        {"robot": "go2", "goal": "go to the red ball"},
        {"duration_s": 0},
    ):
        with pytest.raises(ValueError):
            Episode(world="vision_test", **bad)
    ep = Episode(world="vision_test", goal="look for the green box", spawn=(0.0, 1.0, 2.0), params={"sim": {"x": 1}})
    assert Episode.from_dict(ep.to_dict()) == ep


def test_labels_name_the_right_body() -> None:
    names = ["red_sphere", "red_box", "blue_cylinder", "blue_box", "wall_east"]
    assert target_body("go to the red box", names) == "red_box"
    assert target_body("走到蓝色圆柱", names) == "blue_cylinder"
    assert target_body("follow the red ball", names) == "red_sphere"
    assert target_body("go to the yellow ball", names) is None
    red_ball = parse_target("red ball")
    assert label_matches(red_ball, "red_sphere") and label_matches(red_ball, "red ball")
    assert not label_matches(red_ball, "red_box") and not label_matches(red_ball, "wall_east")


# -- metrics ----------------------------------------------------------------------------------------


def _quat(yaw: float) -> tuple[float, float, float, float]:
    return math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)


def _go_to_recording(stop_at: float) -> Recording:
    """The robot walks +x from (0, 0) towards a cylinder at (3, 0), r 0.3, and stops at x = stop_at."""
    rec = Recording(sim_time=12.0)
    xs = np.linspace(0.0, stop_at, 101)
    for i, x in enumerate(xs):
        rec.poses.append((0.1 * i, {"go2": (float(x), 0.0, 0.3, *_quat(0.0))}))
    rec.commander = [(0.0, {"state": "searching"}), (1.0, {"state": "approaching", "seen": True})]
    rec.commander.append((9.0, {"state": "reached", "seen": True, "reason": "there"}))
    rec.cmds = [(9.0, 0.0, 0.0, 0.0)]
    return rec


def _ctx(ep: Episode, shapes: dict[str, Footprint]) -> Context:
    return Context(ep, shapes, t0=0.0, wall_s=5.0, rtf=1.0, fast=False, stop_distance_m=0.8)


def test_go_to_metrics_success_spl_and_collisions() -> None:
    shapes = {"blue_cylinder": Footprint("circle", 3.0, 0.0, r=0.3), "red_sphere": Footprint("circle", 0.0, 3.0, r=0.5)}
    ep = Episode(world="vision_test", goal="go to the blue cylinder", spawn=(0.0, 0.0, 0.0))
    m, series = compute_metrics(_go_to_recording(1.9), _ctx(ep, shapes))
    assert m["success"] and m["goal_reached"] and m["target_body"] == "blue_cylinder"
    assert m["final_distance_m"] == pytest.approx(0.8, abs=1e-3)  # 3 - 0.3 - 1.9
    assert m["shortest_path_m"] == pytest.approx(2.7 - 0.8) and m["path_length_m"] == pytest.approx(1.9)
    assert m["spl"] == pytest.approx(1.0)  # it stopped exactly at the stop distance: the shortest path
    assert m["time_to_goal_s"] == 9.0 and m["collisions"] == 0 and m["target_in_view_at_end"] is True
    assert m["states"] == ["searching", "approaching", "reached"] and len(series["robot_xy"]) == 101
    # Walking into the cylinder: a collision, so not a success, whatever the commander says.
    m, _ = compute_metrics(_go_to_recording(2.6), _ctx(ep, shapes))
    assert m["collisions"] == 1 and m["min_clearance_m"] < 0 and not m["success"] and m["spl"] == 0.0
    # Stopping 1.6 m short: reached in its own eyes, too far in the ground truth's.
    m, _ = compute_metrics(_go_to_recording(0.5), _ctx(ep, shapes))
    assert not m["success"] and m["final_distance_m"] > 1.0
    # A detour: SPL = L / P.
    rec = _go_to_recording(1.9)
    rec.poses.insert(50, (4.95, {"go2": (1.0, 1.0, 0.3, *_quat(0.0))}))
    m, _ = compute_metrics(rec, _ctx(ep, shapes))
    assert m["spl"] == pytest.approx(1.9 / m["path_length_m"], abs=1e-4) and m["spl"] < 0.9


def test_the_commanders_farthest_reach_is_the_evals_success_distance() -> None:
    """One definition of reached: where nearer cannot be walked the commander calls a go to reached
    out to stop + tolerance + reach_slack_m from the surface; past the eval's success distance that
    was a reached episode judged a miss (houses 006: 1.08 m by its own range, truly 1.002 m)."""
    m = MissionParams()
    assert m.stop_distance_m + m.distance_tolerance_m + m.reach_slack_m == pytest.approx(Episode.success_distance_m)


def test_grounding_scores_every_answer_against_its_frame() -> None:
    target = (100.0, 100.0, 200.0, 300.0)
    other = (400.0, 100.0, 500.0, 200.0)
    truth = {
        1.0: [("blue_cylinder", target, 1.0), ("red_sphere", other, 1.0)],
        2.0: [("red_sphere", other, 1.0)],  # the cylinder out of view
    }
    answers = [
        (1.5, 1.0, [("blue cylinder", (105.0, 100.0, 205.0, 300.0), 1.0)]),  # hit
        (2.5, 1.0, [("blue cylinder", other, 1.0)]),  # the red sphere's box: wrong object
        (3.5, 1.0, []),  # miss
        (4.5, 2.0, [("blue cylinder", (0.0, 0.0, 10.0, 10.0), 1.0)]),  # nothing there: false positive
        (5.5, 2.0, []),  # correctly nothing
        (6.5, 9.0, []),  # no ground truth for that stamp: not scored
    ]
    g = grounding_metrics(answers, truth, "go to the blue cylinder")
    assert (g["hits"], g["wrong_object"], g["misses"], g["false_positives"]) == (1, 1, 1, 1)
    assert g["answers"] == 6 and g["scored"] == 5 and g["answers_with_box"] == 3 and g["answers_target_visible"] == 3
    assert g["precision"] == pytest.approx(1 / 3, abs=1e-4) and g["recall"] == pytest.approx(1 / 3, abs=1e-4)
    assert g["iou"][0] == pytest.approx(95 * 200 / (105 * 200), abs=1e-3) and g["iou"][1] == 0.0
    assert g["result_age_s_mean"] == pytest.approx(np.mean([0.5, 1.5, 2.5, 2.5, 3.5, -2.5]), abs=1e-3)
    assert grounding_metrics([], truth, "go to the blue cylinder") is None


def test_segmentation_boxes_are_the_visible_extent_of_each_body() -> None:
    ids = np.full((6, 8), -1, dtype=np.int32)
    ids[1:3, 2:5] = 0  # geom 0 of body 1
    ids[4, 6] = 1  # geom 1 of body 1, elsewhere: the box covers both parts
    ids[5, 0] = 2  # a speck of body 2
    geom_body = np.array([1, 1, 2])
    assert segmentation_boxes(ids, geom_body, {1: "box", 2: "ball"}, min_pixels=2) == {"box": (2, 1, 7, 5)}
    assert segmentation_boxes(ids, geom_body, {1: "box", 2: "ball"}, min_pixels=1, min_side=1)["ball"] == (0, 5, 1, 6)
    ids[:, 0] = 2  # a sliver one pixel wide at the border: enough pixels, still not a detection
    assert "ball" not in segmentation_boxes(ids, geom_body, {1: "box", 2: "ball"}, min_pixels=2)


def test_confidence_intervals() -> None:
    lo, hi = wilson(5, 10)
    assert (lo, hi) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    assert wilson(4, 4) == pytest.approx((0.5101, 1.0), abs=1e-4)
    assert wilson(0, 10)[0] == 0.0 and wilson(0, 0) is None
    vals = [0.2, 0.9, 0.5, 0.7, 1.0, 0.0]
    ci = bootstrap_ci(vals)
    assert ci == bootstrap_ci(vals) and ci[0] < np.mean(vals) < ci[1]
    assert bootstrap_ci([0.4]) == (0.4, 0.4) and bootstrap_ci([]) is None


# -- files and signals --------------------------------------------------------------------------------


def test_atomic_files_are_whole_or_absent(tmp_path: Path) -> None:
    path = tmp_path / "metrics.json"
    write_json(path, {"a": 1})
    with pytest.raises(RuntimeError), atomic(path) as tmp:
        tmp.write_text('{"a": 2, "torn')
        raise RuntimeError("interrupted mid-write")
    assert path.read_text() == '{\n  "a": 1\n}\n' and list(tmp_path.iterdir()) == [path]
    lines = tmp_path / "results.jsonl"
    append_jsonl(lines, {"i": 0})
    append_jsonl(lines, {"i": 1})
    with open(lines, "a") as f:
        f.write('{"i": 2, "tor')  # a torn last line (power cut): skipped
    assert read_jsonl(lines) == [{"i": 0}, {"i": 1}]


def test_a_second_signal_waits_for_the_results() -> None:
    stop = ShutdownRequested()
    with stop.hold("the metrics"):
        stop._on_signal(signal.SIGINT)  # the first: stop
        assert stop.event.is_set() and stop.exit_code == 130
        stop._on_signal(signal.SIGINT)  # the second: noted, the block goes on
        stop._on_signal(signal.SIGTERM)
        assert not stop.abort.is_set()
    assert stop.abort.is_set() and stop.exit_code == 130  # after the block: skip what is left
    term = ShutdownRequested()
    term._on_signal(signal.SIGTERM)
    assert term.exit_code == 143


def test_the_memory_is_scored_against_its_bodies_and_summed_in_the_report() -> None:
    """A remembered object is measured from its body's centre, or for a long body (a wall) from the
    line its middle runs on: a place anywhere along a wall is on it. A remembered object of no body's
    label, or farther than PHANTOM_M, is a phantom. The report sums them per group."""
    from go2vlm.apps.episodes.metrics import PHANTOM_M, memory_metrics
    from go2vlm.apps.episodes.report import summarize
    from go2vlm.world.objects_msg import Remembered

    def rem(oid: str, label: str, x: float, y: float) -> Remembered:
        return Remembered(oid, label, x, y, 0.2, (0.3, 0.3, 0.3), 0.9, 1.0, (0.01, 0.0, 0.01))

    bodies = {"wall_north": Footprint.rect(0.0, 3.5, 0.0, 12.0, 0.1), "duck": Footprint("circle", -4.8, -2.6, r=0.1)}
    far = -2.6 - PHANTOM_M - 0.1
    objs = [rem("w", "wall_north", 4.5, 3.45), rem("d", "duck", -4.7, -2.6), rem("p", "duck", -4.8, far),
            rem("x", "blue mug", 0.0, 0.0)]  # fmt: skip
    m = memory_metrics(objs, bodies)
    got = {o["id"]: o for o in m["objects"]}
    assert got["w"]["error_m"] == pytest.approx(0.05) and not got["w"]["phantom"]
    assert got["d"]["error_m"] == pytest.approx(0.1) and not got["d"]["phantom"]
    assert got["p"]["phantom"] and got["x"]["phantom"] and m["phantoms"] == 2
    assert m["mean_error_m"] == pytest.approx(0.075)
    line = {"metrics": {"success": True, "kind": "go_to", "collisions": 0, "fell": False, "wall_s": 1.0, "memory": m},
            "config": {"suite": "s", "perception": "oracle", "run_id": "r"}, "suite": "s"}  # fmt: skip
    [row] = summarize([line])
    assert (row["memory_objects"], row["memory_phantoms"], row["memory_mean_error_m"]) == (4, 2, 0.075)


def test_flips_count_forward_back_turns_and_the_rocking_between_them() -> None:
    """Forward, back 1 s later, forward 1 s later (rocking: 1 s between the two turns), then 5 s on, back
    again (a turn, but no rocking); commands slower than a creep keep the last direction."""
    cmds = [(0.0, 0.3), (0.5, 0.01), (1.0, -0.2), (1.5, -0.01), (2.0, 0.2), (7.0, 0.2), (7.1, -0.2)]
    assert flips(cmds) == (3, 1.0)
    assert flips([(0.0, 0.3), (1.0, 0.0), (2.0, 0.3)]) == (0, 0.0) and flips([]) == (0, 0.0)
