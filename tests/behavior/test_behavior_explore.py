"""Exploration (behavior/strategies/explore.py) in a toy house: a robot that sees 4 m round it (walls block
its rays) and walks exactly where it is told. Spawned in the kitchen, it walks through the doorway
into the living room, never through a wall, and ends `done` with no frontier left once the house is
known."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from scipy import ndimage

from go2vlm.behavior.navigate import Navigator
from go2vlm.behavior.planner.global_path import Costmap
from go2vlm.behavior.strategies.explore import ExploreParams, Explorer, ExploreStep

RES = 0.05
ORIGIN = (-6.0, -3.5)


def house() -> np.ndarray:
    """True occupancy (1 = wall) of two 6 x 7 m rooms joined by a 1.2 m door at x = 0, |y| < 0.6."""
    g = np.zeros((140, 240), np.int8)
    g[:2, :] = g[-2:, :] = 1
    g[:, :2] = g[:, -2:] = 1
    g[:, 119:121] = 1
    g[58:82, 119:121] = 0
    return g


def cell(x: float, y: float) -> tuple[int, int]:
    return int((y - ORIGIN[1]) / RES), int((x - ORIGIN[0]) / RES)


def sense(truth: np.ndarray, known: np.ndarray, x: float, y: float, reach: float = 4.0) -> None:
    """Ray-cast from (x, y): cells up to the first wall become known (0 free, 100 wall)."""
    for a in np.linspace(-math.pi, math.pi, 360, endpoint=False):
        for d in np.arange(0.0, reach, RES / 2):
            r, c = cell(x + d * math.cos(a), y + d * math.sin(a))
            if not (0 <= r < truth.shape[0] and 0 <= c < truth.shape[1]):
                break
            if truth[r, c]:
                known[r, c] = 100
                break
            known[r, c] = 0


def costmap(known: np.ndarray, stamp: float) -> Costmap:
    d = ndimage.distance_transform_edt(known != 100) * RES
    cost = np.clip((0.6 - d) / 0.4 * 98, 0, 98).astype(np.int8)
    cost[d <= 0.2] = 99
    cost[known == 100] = 100
    cost[known == -1] = -1
    return Costmap(cost, RES, ORIGIN, stamp)


DT = 0.25  # s a toy step lasts


def walk(ex: Explorer, nav: Navigator, step: ExploreStep, pose: tuple[float, float, float], now: float,
         truth: np.ndarray) -> tuple[float, float, float]:  # fmt: skip
    """The navigator's command towards the explorer's frontier, moved exactly (as the Explore strategy does)."""
    cm = ex.costmap
    assert cm is not None
    nav.planner = ex.route_params()  # as the Explore strategy hands it over
    tol = nav.planner.goal_tolerance_m
    out = nav.step(step.goal, tol, cm, pose, None, now, max_linear=0.8, max_angular=1.0)
    if out.status == "arrived":
        ex.arrived()
    elif out.status == "failed":
        ex.give_up(out.reason)
        nav.reset()
    x, y, yaw = pose
    yaw += out.wz * DT
    x, y = x + out.vx * DT * math.cos(yaw), y + out.vx * DT * math.sin(yaw)
    assert truth[cell(x, y)] == 0, f"walked into a wall at ({x:.2f}, {y:.2f})"
    return x, y, yaw


STANDS: list[float] = []  # run(): how far from its frontier's goal each look was taken (m)


def run(x: float, y: float, steps: int = 3000) -> tuple[Explorer, list[tuple[float, float]], list[str]]:
    truth = house()
    known = np.full(truth.shape, -1, np.int8)
    nav = Navigator()
    ex = Explorer(ExploreParams(), nav)
    ex.reset(0.0)
    yaw, path, actions = 0.0, [(x, y)], []
    for k in range(steps):
        now = k * DT
        if k % 4 == 0:
            sense(truth, known, x, y)
            ex.set_map(costmap(known, now))
        step = ex.step(x, y, yaw, now)
        actions.append(step.action)
        if step.action == "done":
            break
        if step.action == "look":
            assert ex.frontier is not None
            STANDS.append(math.dist(ex.frontier.goal, (x, y)))
            ex.looked(now, (x, y))
        elif step.action == "walk":
            x, y, yaw = walk(ex, nav, step, (x, y, yaw), now, truth)
            path.append((x, y))
    return ex, path, actions


def test_from_the_kitchen_through_the_door_until_nothing_is_left() -> None:
    STANDS.clear()
    ex, path, actions = run(3.0, -2.0)
    # Each look is taken within arrive_m of its frontier's goal, where the navigator called it there:
    # a map frontier counts as looked at only from there (a look 0.8 m short of a door's frontier
    # left the room past it unknown, and the frontier skipped as visited).
    assert STANDS and max(STANDS) <= ex.params.arrive_m + 0.05, STANDS
    assert actions[-1] == "done", actions[-5:]
    assert "no frontier left" in ex.reason
    assert min(px for px, _ in path) < -3.0  # deep into the living room
    doors = [(a, b) for a, b in zip(path[:-1], path[1:], strict=False) if a[0] * b[0] <= 0]
    assert doors and all(abs(a[1]) < 0.6 for a, _ in doors)  # through the door, and only there
    assert "look" in actions and ex.status()["visited"] >= 1
    st = ex.status()
    assert st["exploring"] is False and st["frontiers_left"] == 0


def test_status_while_exploring() -> None:
    truth = house()
    known = np.full(truth.shape, -1, np.int8)
    sense(truth, known, 3.0, -2.0)
    ex = Explorer()
    ex.reset(0.0)
    ex.set_map(costmap(known, 1.0))
    step = ex.step(3.0, -2.0, 0.0, 0.1)
    assert step.action == "walk" and "frontier" in step.reason
    st = ex.status()
    assert st["exploring"] is True and st["frontier"] is not None and st["frontiers_left"] >= 1


def test_no_map_waits_then_gives_up() -> None:
    ex = Explorer(ExploreParams(map_timeout_s=5.0))
    ex.reset(0.0)
    assert ex.step(0.0, 0.0, 0.0, 1.0).action == "wait"
    done = ex.step(0.0, 0.0, 0.0, 6.0)
    assert done.action == "done" and "no map" in done.reason


def test_a_known_closed_room_has_nothing_to_explore() -> None:
    truth = house()
    truth[58:82, 119:121] = 1  # door shut
    known = np.full(truth.shape, -1, np.int8)
    for x in (1.5, 3.0, 4.5):
        for y in (-2.0, 0.0, 2.0):
            sense(truth, known, x, y)
    ex = Explorer()
    ex.reset(0.0)
    ex.set_map(costmap(known, 1.0))
    step = ex.step(3.0, 0.0, 0.0, 0.1)
    assert step.action == "done" and "no frontier" in step.reason


def test_exploring_gives_up_after_its_timeout() -> None:
    truth = house()
    known = np.full(truth.shape, -1, np.int8)
    sense(truth, known, 3.0, -2.0)
    ex = Explorer(ExploreParams(timeout_s=60.0))
    ex.reset(0.0)
    ex.set_map(costmap(known, 1.0))
    assert ex.step(3.0, -2.0, 0.0, 30.0).action == "walk"
    done = ex.step(3.0, -2.0, 0.0, 61.0)
    assert done.action == "done" and "explored for 60 s" in done.reason


def _explore_from_the_room() -> tuple[Any, Any]:
    """The Explore strategy and its context, the robot at (3, -2) in the toy house, its room sensed."""
    from go2vlm.behavior.goals import parse_goal
    from go2vlm.behavior.strategies.base import Context
    from go2vlm.behavior.strategies.explore_search import Explore
    from go2vlm.behavior.strategies.params import MissionParams

    truth = house()
    known = np.full(truth.shape, -1, np.int8)
    sense(truth, known, 3.0, -2.0)
    s = Explore()
    ctx = Context(MissionParams(), goal=parse_goal("look for the duck"), view=math.radians(73))
    ctx.costmap = costmap(known, 1.0)
    s.reset(0.0)
    return s, ctx


def test_the_strategy_walks_then_looks_all_round_then_walks_on() -> None:
    from go2vlm.behavior.strategies.base import Pose

    s, ctx = _explore_from_the_room()
    x, y, yaw, now = 3.0, -2.0, 0.0, 0.0
    states: list[str] = []
    turned = 0.0
    for _ in range(4000):
        now += 0.05
        ctx.pose = Pose(x, y, yaw, now)
        cmd = s.step(ctx, now)
        assert cmd is not None
        states.append(cmd.state)
        top = ctx.params.nav.max_speed if cmd.navigated else ctx.params.max_linear  # the navigator's: faster
        assert 0.0 <= cmd.vx <= top and abs(cmd.wz) <= ctx.params.max_angular
        if s.looking:
            turned += abs(cmd.wz) * 0.05
        yaw += cmd.wz * 0.05
        x, y = x + cmd.vx * 0.05 * math.cos(yaw), y + cmd.vx * 0.05 * math.sin(yaw)
        if s.explorer.status()["visited"] >= 1 and not s.looking and s.explorer.phase == "walk":
            break
    assert set(states) <= {"exploring", "detouring"}
    assert s.explorer.status()["visited"] >= 1  # it arrived, looked all round, and walks on
    assert turned >= 2 * math.pi - math.radians(73) - 0.1
    assert ctx.route is ctx.navigator.route is not None


def test_a_look_the_gate_holds_ends_and_the_search_walks_on() -> None:
    """The robot at a frontier beside a wall: the safety gate holds its turn (the pose never turns).
    The look ends once it has gained nothing for look_stall_s, the place counts as visited, and the
    search goes on to the next frontier instead of waiting there until the goal times out."""
    from go2vlm.behavior.strategies.base import Pose

    s, ctx = _explore_from_the_room()
    stall_s = s.params.look_stall_s
    x, y, yaw, now = 3.0, -2.0, 0.0, 0.0
    look_began: float | None = None
    reasons: list[str] = []
    for _ in range(8000):
        now += 0.05
        ctx.pose = Pose(x, y, yaw, now)
        cmd = s.step(ctx, now)
        assert cmd is not None
        reasons.append(cmd.reason)
        if s.looking:
            look_began = now if look_began is None else look_began
            continue  # held: it does not turn
        if look_began is not None:
            break
        yaw += cmd.wz * 0.05
        x, y = x + cmd.vx * 0.05 * math.cos(yaw), y + cmd.vx * 0.05 * math.sin(yaw)
    assert look_began is not None, "it never looked"
    assert s.explorer.status()["visited"] == 1 and not s.looking
    assert stall_s - 0.1 <= now - look_began <= 2 * stall_s + 0.1
    assert "could not turn all round" in reasons[-1]


def test_a_look_rocking_in_place_turns_nothing_and_ends_held() -> None:
    """The gate holds the look's turn and the robot rocks: its yaw jitters +-0.1 rad. The jitter is no
    turn (it once added up to "looked all round"): the look ends held, having turned about nothing."""
    from go2vlm.behavior.strategies.base import Pose

    s, ctx = _explore_from_the_room()
    stall_s = s.params.look_stall_s
    x, y, yaw, now = 3.0, -2.0, 0.0, 0.0
    look_began: float | None = None
    reasons: list[str] = []
    k = 0
    for _ in range(8000):
        now += 0.05
        ctx.pose = Pose(x, y, yaw + (0.1 if s.looking and k % 2 else 0.0), now)
        cmd = s.step(ctx, now)
        assert cmd is not None
        reasons.append(cmd.reason)
        if s.looking:
            look_began, k = (now if look_began is None else look_began), k + 1
            continue
        if look_began is not None:
            break
        yaw += cmd.wz * 0.05
        x, y = x + cmd.vx * 0.05 * math.cos(yaw), y + cmd.vx * 0.05 * math.sin(yaw)
    assert look_began is not None, "it never looked"
    assert now - look_began <= 2 * stall_s + 0.1
    assert "could not turn all round (turned 0 deg)" in reasons[-1], reasons[-1]


def test_a_look_where_the_camera_has_seen_everything_near_ends_at_once() -> None:
    """Coverage (world/coverage.py): arrived where the camera has already looked all round, the look
    ends without a turn; where it has not, the look turns."""
    from go2vlm.behavior.strategies.base import Pose
    from go2vlm.world.frontiers import Frontier

    s, ctx = _explore_from_the_room()
    cm = ctx.costmap
    assert cm is not None
    for k in range(12):  # answered frames all round from here
        ctx.coverage.observe(cm.data, cm.resolution, cm.origin, 3.0, -2.0, k * math.pi / 6, math.radians(73))
    s.explorer.set_map(cm)
    s.explorer.phase = "look"
    s.explorer.frontier = Frontier(1, (3.0, -2.0), (3.0, -2.0), cell(3.0, -2.0), 10, 0.5)
    ctx.pose = Pose(3.0, -2.0, 0.0, 1.0)
    cmd = s.step(ctx, 1.0)
    assert cmd is not None and (cmd.vx, cmd.wz) == (0.0, 0.0) and "nothing in sight left unseen" in cmd.reason
    assert s.explorer.phase == "choose" and s.explorer.status()["visited"] == 1
    s2, ctx2 = _explore_from_the_room()  # nothing looked at yet: the look turns
    s2.explorer.set_map(ctx2.costmap)
    s2.explorer.phase = "look"
    s2.explorer.frontier = Frontier(1, (3.0, -2.0), (3.0, -2.0), cell(3.0, -2.0), 10, 0.5)
    ctx2.pose = Pose(3.0, -2.0, 0.0, 1.0)
    cmd2 = s2.step(ctx2, 1.0)
    assert cmd2 is not None and cmd2.wz != 0.0


def test_a_refresh_turns_all_round_where_the_camera_has_seen_everything() -> None:
    """No frontier reachable: the turn where it stands is for the map (the lidar's view round it), so
    it turns all round although the camera has looked all round from there; then it plans again."""
    from go2vlm.behavior.strategies.base import Pose

    s, ctx = _explore_from_the_room()
    cm = ctx.costmap
    assert cm is not None
    for k in range(12):
        ctx.coverage.observe(cm.data, cm.resolution, cm.origin, 3.0, -2.0, k * math.pi / 6, math.radians(73))
    s.explorer.set_map(cm)
    s.explorer.phase, s.explorer.reason = "refresh", "no reachable frontier now: turning round where it stands"
    yaw, now, turned = 0.0, 1.0, 0.0
    for _ in range(2000):
        ctx.pose = Pose(3.0, -2.0, yaw, now)
        cmd = s.step(ctx, now)
        assert cmd is not None and cmd.vx == 0.0
        if s.explorer.phase != "refresh":
            break
        yaw, turned, now = yaw + cmd.wz * 0.05, turned + abs(cmd.wz) * 0.05, now + 0.05
    assert s.explorer.phase != "refresh" and "looked all round" in cmd.reason, cmd.reason
    assert turned >= 2 * math.pi - math.radians(73) - 0.1
    assert s.explorer.status()["visited"] == 0  # a turn for the map: no place marked as looked from


def test_with_coverage_it_walks_to_what_the_camera_has_not_seen_and_ends_with_the_house_seen() -> None:
    """The toy robot's lidar sees 8 m round it, its camera (73 degrees, 4 m) where it faces; the
    explorer walks to the map's frontiers and to free space the camera has not seen, and ends with
    little of the house unseen."""
    from go2vlm.world.coverage import Coverage

    truth = house()
    known = np.full(truth.shape, -1, np.int8)
    ex, nav = Explorer(ExploreParams(timeout_s=1e4)), Navigator()
    ex.coverage = cov = Coverage()
    ex.reset(0.0)
    x, y, yaw = 3.0, -2.0, 0.0
    kinds: set[str] = set()
    unseen_first = None  # the share of the house unseen when the first pass (4 m) ended
    share = 1.0
    for k in range(12000):
        now = k * DT
        if k % 4 == 0:
            sense(truth, known, x, y, reach=8.0)  # the lidar reaches twice as far as the camera's answers
            ex.set_map(costmap(known, now))
        cm = ex.costmap
        assert cm is not None
        cov.observe(cm.data, RES, ORIGIN, x, y, yaw, math.radians(73))
        free = (cm.data >= 0) & (cm.data < 99)
        share = cov.unlooked(cm.data, RES, ORIGIN, 99).sum() / max(1, free.sum())
        step = ex.step(x, y, yaw, now)
        if unseen_first is None and "second pass" in ex.reason:
            unseen_first = share
        if ex.frontier is not None:
            kinds.add(ex.frontier.kind)
        if step.action == "done":
            break
        if step.action == "look":
            for a in range(12):
                cov.observe(cm.data, RES, ORIGIN, x, y, yaw + a * math.pi / 6, math.radians(73))
            ex.looked(now, (x, y))
        elif step.action == "walk":
            x, y, yaw = walk(ex, nav, step, (x, y, yaw), now, truth)
    assert step.action == "done" and "no frontier left" in ex.reason, (step, k)
    assert "view" in kinds  # it walked to free space the camera had not seen
    assert unseen_first is not None and unseen_first < 0.1  # the first pass saw nine tenths of the house
    assert cov.params.range_m == 2.0 and share < 0.25  # and the second, from within 2 m, most of it again


@pytest.mark.parametrize("looked_left", [True, False])
def test_a_look_turns_the_short_way_to_what_is_left_unseen(looked_left: bool) -> None:
    """Half the view round the place looked at already (frames on the way): the look turns towards
    the other half, not always left, and not all round."""
    from go2vlm.behavior.strategies.base import Pose
    from go2vlm.world.frontiers import Frontier

    s, ctx = _explore_from_the_room()
    cm = ctx.costmap
    assert cm is not None
    sign = 1.0 if looked_left else -1.0
    for k in range(7):  # facing +x (yaw 0) and round to one side
        ctx.coverage.observe(cm.data, cm.resolution, cm.origin, 3.0, -2.0, sign * k * math.pi / 6, math.radians(73))
    s.explorer.set_map(cm)
    s.explorer.phase = "look"
    s.explorer.frontier = Frontier(1, (3.0, -2.0), (3.0, -2.0), cell(3.0, -2.0), 10, 0.5)
    ctx.pose = Pose(3.0, -2.0, 0.0, 1.0)
    cmd = s.step(ctx, 1.0)
    assert cmd is not None and cmd.vx == 0.0 and cmd.wz != 0.0, cmd
    assert math.copysign(1.0, cmd.wz) == -sign, (looked_left, cmd)


def test_a_frontier_the_navigator_gives_up_comes_back_once_the_map_round_it_changes() -> None:
    """Given up (a person in the doorway, say), a frontier is skipped while the map round it stays as it
    was, and chosen again once more of it is known."""
    truth = house()
    known = np.full(truth.shape, -1, np.int8)
    sense(truth, known, 3.0, -2.0)
    ex = Explorer(ExploreParams())
    ex.reset(0.0)
    ex.set_map(costmap(known, 0.0))
    first = ex.step(3.0, -2.0, 0.0, 0.0)
    assert first.action == "walk"
    goal = first.goal
    ex.give_up("no progress after every recovery")
    ex.set_map(costmap(known, 1.0))
    again = ex.step(3.0, -2.0, 0.0, 1.0)
    assert again.action != "walk" or math.dist(again.goal, goal) >= ex.params.visited_radius_m
    sense(truth, known, goal[0], goal[1])  # the map round it fills in
    ex.set_map(costmap(known, 2.0))
    ex.step(3.0, -2.0, 0.0, 2.0)
    assert all(math.dist(g, goal) > 1e-9 for g, _ in ex.dropped)


def right_room_known() -> np.ndarray:
    """The toy house's map with the right room known and its door open onto the unknown left room."""
    known = np.full((140, 240), -1, np.int8)
    known[2:-2, 121:-2] = 0
    known[:2, 119:] = known[-2:, 119:] = 100
    known[:, -2:] = 100
    known[:, 119:121] = 100
    known[58:82, 119:121] = 0  # the door, and the unknown room beyond it
    return known


def test_gain_takes_the_room_through_the_door_over_a_nearer_corner() -> None:
    """Known: the right room, but for a 1 m corner at its far end the scan has not reached, and the
    doorway to the unknown left room. The corner is nearer; the door reveals a room. `gain` walks to
    the door, `nearest` to the corner."""
    known = right_room_known()
    known[2:22, 218:238] = -1  # the corner at (5, -3) the scan has not reached
    cm = costmap(known, 1.0)
    goals = {}
    for choice in ("gain", "nearest"):
        ex = Explorer(ExploreParams(frontier_choice=choice))
        ex.set_map(cm)
        step = ex.step(3.5, -1.5, 0.0, 0.0)
        assert step.action == "walk", step
        goals[choice] = step.goal
    assert goals["gain"][0] < 0.5 and abs(goals["gain"][1]) < 1.0, goals  # the doorway (x = 0)
    assert goals["nearest"][0] > 3.0 and goals["nearest"][1] < -1.8, goals  # the corner


def test_a_door_seen_from_beside_it_is_still_walked_through() -> None:
    """The robot looked around 1 m from a doorway, beside its jamb, and the room past it stayed unknown:
    the door's frontier is not 'looked at' (its goal is not where the robot stood), so the search walks
    through the door rather than ending with a room it never saw."""
    known = right_room_known()
    ex = Explorer(ExploreParams())
    ex.set_map(costmap(known, 1.0))
    first = ex.step(3.5, -1.5, 0.0, 0.0)
    assert first.action == "walk" and abs(first.goal[0]) < 0.5, first
    door = first.goal
    ex.reset(0.0)
    ex.visited.append((door[0] + 0.5, door[1] + 0.8))  # looked from beside the jamb, 0.94 m from its goal
    step = ex.step(3.5, -1.5, 0.0, 0.0)
    assert step.action == "walk" and math.dist(step.goal, door) < 0.2, step
    ex.visited.append(step.goal)  # looked from the door itself, and the room stayed unknown: done with it
    ex.phase, ex.frontier = "choose", None
    ex._frontier_stamp = None
    end = ex.step(3.5, -1.5, 0.0, 1.0)
    assert end.action != "walk" or math.dist(end.goal, door) >= ex.params.arrive_m, end


def test_no_reachable_frontier_ends_the_search_only_once_it_has_held() -> None:
    """One failed plan is not the last word (a plan from a doorway at an angle, a scan that shut a gap):
    with the door shut on the map the explorer first turns all round where it stands (standing still,
    the map the plan failed on does not change), then holds still and plans again on each new map; the
    door open again within explore_unreachable_wait_s, it walks through; shut all along, it ends
    not_found with how long it held."""
    known = right_room_known()
    shut = known.copy()
    shut[58:82, 119:121] = 100  # the door shut on the map, with what the lidar saw past it before
    shut[50:90, 100:119] = known[50:90, 100:119] = 0
    wait = ExploreParams().unreachable_wait_s
    for opens in (True, False):
        ex = Explorer(ExploreParams())
        ex.reset(0.0)
        ex.set_map(costmap(shut, 0.0))
        turn = ex.step(3.5, -1.5, 0.0, 0.0)
        assert turn.action == "refresh" and "turning round" in turn.reason, turn
        assert ex.step(3.5, -1.5, 0.0, 0.0).action == "refresh"  # until the host has turned all round
        ex.looked(0.0)
        assert ex.status()["refreshes"] == 1
        first = ex.step(3.5, -1.5, 0.0, 0.0)
        assert first.action == "wait" and "planning again" in first.reason, first
        assert ex.step(3.5, -1.5, 0.0, 0.5).action == "wait"  # no new map: no new plan
        ex.set_map(costmap(known if opens else shut, wait / 2))
        mid = ex.step(3.5, -1.5, 0.0, wait / 2)
        if opens:
            assert mid.action == "walk" and mid.goal[0] < 0.0, mid  # past the door
            continue
        assert mid.action == "wait", mid
        ex.set_map(costmap(shut, wait + 1.0))
        end = ex.step(3.5, -1.5, 0.0, wait + 1.0)
        assert (
            end.action == "done" and "no reachable frontier" in end.reason and f"for {wait + 1.0:.0f} s" in end.reason
        )


def test_the_last_frontier_given_up_is_tried_again_rather_than_ending_the_search() -> None:
    """The door is the only frontier and the navigator gave it up (a person stood in it, say): the search
    does not end "no frontier left" with a reachable room unseen; it brings the door back and walks to it."""
    ex = Explorer(ExploreParams())
    ex.reset(0.0)
    ex.set_map(costmap(right_room_known(), 1.0))
    first = ex.step(3.5, -1.5, 0.0, 0.0)
    assert first.action == "walk" and abs(first.goal[0]) < 0.5, first
    ex.give_up("no progress after every recovery")
    ex.set_map(costmap(right_room_known(), 2.0))
    steps = [ex.step(3.5, -1.5, 0.0, 2.0 + k) for k in range(3)]
    assert all(s.action != "done" for s in steps), steps
    assert "trying the given-up again" in steps[0].reason, steps[0]
    assert steps[-1].action == "walk" and math.dist(steps[-1].goal, first.goal) < 0.2, steps
    assert ex.status()["retried_given_up"] == 1
