"""The remembered place with the navigator (remembered.py over behavior/navigate/): a remembered object
in the other room is walked to along the route through the doorway; without a map it goes straight
and says why; a place with no route (a misplaced memory beyond a wall, a door shut) is given up and
the search goes on; a look for (or a go to not yet sure of it) walks until the place is in sight."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import ndimage

from go2vlm.behavior.goals import parse_goal
from go2vlm.behavior.navigate import line_of_sight
from go2vlm.behavior.planner.global_path import Costmap, GlobalParams
from go2vlm.behavior.strategies.base import Context, Pose
from go2vlm.behavior.strategies.params import MissionParams
from go2vlm.behavior.strategies.remembered import GoToRemembered
from go2vlm.world.objects_msg import Remembered

RES = 0.05
ORIGIN = (-6.0, -3.5)


def two_rooms(door: bool = True) -> Costmap:
    occ = np.zeros((140, 240), bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    occ[:, 119:121] = True
    if door:
        occ[58:82, 119:121] = False
    d = ndimage.distance_transform_edt(~occ) * RES
    cost = np.clip((0.8 - d) / 0.4 * 98, 0, 98).astype(np.int8)
    cost[d <= 0.43] = 99
    cost[d <= 0.2] = 100
    return Costmap(cost, RES, ORIGIN, 1.0)


def duck(x: float = -4.8, y: float = -2.6) -> Remembered:
    return Remembered("o1", "duck", x, y, 0.1, (0.3, 0.3, 0.2), 0.95, 1.0, (0.01, 0.0, 0.01))


def ctx_at(x: float, y: float, yaw: float, cm: Costmap | None, now: float = 10.0) -> Context:
    ctx = Context(MissionParams(), goal=parse_goal("go to the duck"), memory=[duck()], view=math.radians(73))
    ctx.pose = Pose(x, y, yaw, now)
    ctx.costmap = cm
    return ctx


def test_line_of_sight() -> None:
    cm, p = two_rooms(), GlobalParams()
    assert not line_of_sight(cm, (3.0, -2.0), (-4.8, -2.6), p, 0.6)  # the middle wall
    assert line_of_sight(cm, (3.0, -2.0), (3.0, 2.0), p, 0.6)
    assert line_of_sight(cm, (2.0, 0.0), (-2.0, 0.0), p, 0.6)  # through the door
    assert not line_of_sight(cm, (3.0, -2.0), (30.0, 0.0), p, 0.6)  # off the map
    # rooms 6: the wall 0.55 m from the robot, the object 1.2 m behind it; the robot in the inflation
    assert not line_of_sight(cm, (0.55, -2.0), (-1.2, -2.0), p, 1.05)
    assert line_of_sight(cm, (0.55, -2.0), (3.0, -2.0), p, 1.05)  # away from the wall: its inflation skipped


def test_a_remembered_object_in_the_other_room_is_walked_to_through_the_door() -> None:
    cm = two_rooms()
    s = GoToRemembered()
    ctx = ctx_at(3.0, -2.0, 0.0, cm)
    ctx.target_obj = s.pick(ctx)
    cmd = s.step(ctx, 10.0)
    assert cmd is not None and cmd.state == "approaching" and cmd.navigated and "along the route" in cmd.reason
    assert ctx.route is not None
    w = ctx.route.plan.waypoints
    crossings = [
        a + (b - a) * (0 - a[0]) / (b[0] - a[0]) for a, b in zip(w[:-1], w[1:], strict=True) if a[0] * b[0] < 0
    ]
    assert crossings and all(abs(c[1]) < 0.6 for c in crossings)


def test_no_map_goes_straight_and_says_why() -> None:
    s = GoToRemembered()
    ctx = ctx_at(3.0, -2.0, math.pi, None)
    ctx.target_obj = s.pick(ctx)
    cmd = s.step(ctx, 10.0)
    assert cmd is not None and "no map" in cmd.reason and not cmd.navigated and ctx.route is None


def test_a_place_with_no_route_is_given_up_and_the_search_goes_on() -> None:
    """A memory placed beyond a wall by bad ranges, or a door shut since: the navigator finds no
    route, the object is given up (until it is seen again) and the strategy hands over (None)."""
    s = GoToRemembered()
    shut = ctx_at(3.0, -2.0, math.pi, two_rooms(door=False))
    shut.target_obj = s.pick(shut)
    assert s.step(shut, 10.0) is None
    assert shut.counters["remembered_unreachable"] == 1 and shut.target_obj is None and s.pick(shut) is None
    s2 = GoToRemembered()  # walking, and the door shuts on the next map: given up the same way
    ctx = ctx_at(3.0, -2.0, 0.0, two_rooms())
    ctx.target_obj = s2.pick(ctx)
    assert s2.step(ctx, 10.0) is not None
    ctx.costmap = Costmap(two_rooms(door=False).data, RES, ORIGIN, 2.0)
    ctx.pose = Pose(3.0, -2.0, 0.0, 10.1)
    assert s2.step(ctx, 10.1) is None and ctx.counters["remembered_unreachable"] == 1


def test_look_for_a_remembered_object_in_the_other_room_walks_until_it_is_in_sight() -> None:
    cm = two_rooms()
    s = GoToRemembered()
    ctx = ctx_at(3.0, -2.0, 0.0, cm)
    ctx.goal = parse_goal("look for the duck")
    ctx.target_obj = s.pick(ctx)
    cmd = s.step(ctx, 10.0)
    assert cmd is not None and cmd.state in ("aligning", "detouring") and "can be seen" in cmd.reason
    assert ctx.route is not None
    # In sight (the living room): it turns to face it and looks, as before.
    ctx2 = ctx_at(-2.0, -2.0, 0.0, cm)
    ctx2.goal = parse_goal("look for the duck")
    ctx2.target_obj = s.pick(ctx2)
    cmd2 = s.step(ctx2, 10.0)
    assert cmd2 is not None and cmd2.state == "aligning" and "turning to" in cmd2.reason and cmd2.vx == 0.0


def test_a_go_to_not_yet_sure_of_an_object_behind_a_wall_walks_to_where_it_can_be_seen() -> None:
    """Seen once through the door, the duck is not yet sure enough to walk to: the go to looks at it
    first. From beside the wall, 1.2 m from it, no look can see it: it walks (the navigator, through
    the door) to where the map shows it in sight, rather than looking at the wall until it gives the
    duck up. In sight, it faces it and looks, as before."""
    cm, s = two_rooms(), GoToRemembered()
    unsure = replace(duck(-0.6, -2.6), confidence=0.5)
    assert unsure.confidence < MissionParams().memory_confirm_confidence
    ctx = ctx_at(0.6, -2.6, math.pi, cm)  # facing it, the wall between
    ctx.memory = [unsure]
    ctx.target_obj = s.pick(ctx)
    cmd = s.step(ctx, 10.0)
    assert cmd is not None and cmd.state in ("approaching", "detouring") and "can be seen" in cmd.reason, cmd
    assert cmd.navigated and ctx.route is not None
    seen = ctx_at(-2.0, -2.6, 0.0, cm)  # the same room: in sight
    seen.memory = [unsure]
    seen.target_obj = s.pick(seen)
    cmd2 = s.step(seen, 10.0)
    assert cmd2 is not None and "can be seen" not in cmd2.reason and cmd2.vx == 0.0, cmd2


def test_a_go_to_sure_of_an_object_just_behind_a_wall_does_not_take_the_wall_for_it() -> None:
    """The duck, sure, 0.35 m past the wall; the robot 0.4 m this side of it, facing it. The scan's
    return on its bearing is the wall's, 0.4 m away: taken for the duck's surface, the go to was at its
    place, looked through the wall, and gave the duck up. It walks through the door to where it sees it."""
    cm, s = two_rooms(), GoToRemembered()
    ctx = ctx_at(0.45, -2.0, math.pi, cm)
    ctx.memory = [duck(-0.45, -2.0)]
    ctx.target_obj = s.pick(ctx)
    ctx.scan = (np.array([[0.4, dy] for dy in np.arange(-0.5, 0.5, 0.02)]), 10.0)  # the wall ahead
    cmd = s.step(ctx, 10.0)
    assert cmd is not None and "can be seen" in cmd.reason and cmd.navigated, cmd
    assert ctx.counters["remembered_given_up"] == 0


def test_look_for_does_not_walk_the_route_to_what_the_tracker_just_saw() -> None:
    s = GoToRemembered()
    ctx = ctx_at(3.0, -2.0, 0.0, two_rooms())
    ctx.goal = parse_goal("look for the duck")
    ctx.target_obj = s.pick(ctx)
    ctx.last_seen = 8.0  # 2 s ago: in sight, whatever the map says
    cmd = s.step(ctx, 10.0)
    assert cmd is not None and "can be seen" not in cmd.reason and cmd.vx == 0.0
