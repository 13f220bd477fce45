"""Property tests of the tracked target's strategy (behavior/strategies/approach.py): it answers only
while the tracker confirms the target or a detour hides it; it never reverses nor exceeds its limits;
look for never walks; reached and found only where the law says so; a detour out of view walks only
while the planner says the direct way is blocked, and never for look for or the follower's follow."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from go2vlm.behavior.control import CENTRED_X
from go2vlm.behavior.goals import parse_goal
from go2vlm.behavior.strategies.approach import Approach
from go2vlm.behavior.strategies.base import Command, Context, Pose, Sighting
from go2vlm.behavior.strategies.params import MissionParams

GOALS = ["go to the blue cylinder", "look for the blue cylinder", "follow the blue cylinder"]
pts = st.lists(st.tuples(st.floats(0.5, 2.5), st.floats(-0.8, 0.8)), min_size=1, max_size=25).map(
    lambda p: np.array(p, dtype=float).reshape(-1, 2)
)
seen = st.tuples(
    st.booleans(),
    st.floats(-0.5, 0.5),
    st.one_of(st.none(), st.floats(0.0, 6.0)),
    st.one_of(st.just(math.nan), st.floats(-0.6, 0.6)),
)
step = st.tuples(seen, st.booleans(), st.one_of(st.floats(0.0, 0.3), st.floats(0.0, 3.0)), st.floats(-0.3, 0.3))


@settings(max_examples=200)
@given(
    goal=st.sampled_from(GOALS),
    wall=pts,
    steps=st.lists(step, min_size=1, max_size=40),
)
def test_the_approach_acts_only_on_a_confirmed_or_hidden_target(
    goal: str, wall: np.ndarray, steps: list[tuple[tuple[bool, float, float | None, float],
                                                                       bool, float, float]],
) -> None:  # fmt: skip
    p = MissionParams()
    ctx = Context(p, goal=parse_goal(goal))
    a, now, yaw = Approach(), 0.0, 0.0
    kind = ctx.goal.kind if ctx.goal is not None else ""
    for (tracked, x, dist, bearing), scan, dt, turn in steps:
        now += dt
        yaw += turn
        ctx.pose = Pose(0.0, 0.0, yaw, now)
        ctx.scan = (wall, now) if scan else None
        if tracked:
            s = Sighting(now, "blue cylinder", "tracking", x, dist, "bottom", bearing)
            ctx.sighting = s
            ctx.saw(s)
        cmd = a.step(ctx, now)
        if ctx.confirmed(now):
            assert cmd is not None
        if cmd is None:
            continue
        event(f"{cmd.state} ({'confirmed' if ctx.confirmed(now) else 'hidden'})")
        assert 0.0 <= cmd.vx <= p.max_linear + 1e-9 and abs(cmd.wz) <= p.max_angular + 1e-9
        if kind == "look_for":
            assert ctx.confirmed(now) and ctx.sighting is not None and cmd.vx == 0.0
            x_now, since = ctx.sighting.x, ctx.align_since
            wait = MissionParams().align_found_s
            late = since is not None and now - since > wait and abs(x_now) < 1.0  # the turn held
            assert (cmd.state == "found") == (abs(x_now) < CENTRED_X or late)
        if cmd.state == "reached":
            d = ctx.base_distance(now)
            assert kind == "go_to" and d is not None and d - p.stop_distance_m <= p.distance_tolerance_m
        if cmd.state in ("found", "reached"):
            assert cmd.vx == cmd.wz == 0.0
        if kind == "follow":
            assert cmd.state in ("tracking", "detouring")
        if not ctx.confirmed(now):  # a detour that hides the target
            assert kind != "look_for"
            assert cmd.state == "detouring" and ctx.last_seen is not None
            assert now - ctx.last_seen <= p.detour_memory_s and scan
            assert cmd.vx == 0.0 or ctx.navigator.steering.detour_t == now  # walks only round a blocked way


def test_go_to_a_target_the_tracker_cannot_range_is_ranged_by_the_scan_on_its_bearing() -> None:
    """Near a box, its bottom edge leaves the image and the tracker gives no range: the scan's return
    on the target's bearing ranges it, so the approach stops and ends `reached` (the robot stood 0.70 m
    from the green box, 'target at unknown', until the goal timed out)."""
    import pytest

    from go2vlm.behavior.goals import parse_goal
    from go2vlm.behavior.sighting import Sighting
    from go2vlm.behavior.strategies.approach import Approach
    from go2vlm.behavior.strategies.base import Context
    from go2vlm.behavior.strategies.params import MissionParams

    p = MissionParams()
    ctx = Context(p, goal=parse_goal("go to the green box"), view=math.radians(73))
    ys = np.linspace(-0.25, 0.25, 11)
    for surface, want in ((0.75, "reached"), (1.6, "approaching")):
        box = np.column_stack([np.full_like(ys, surface), ys])  # its face, `surface` m ahead of the base
        ctx.scan = (box, 1.0)
        ctx.sighting = Sighting(1.0, "green box", "tracking", 0.0, None, "none", 0.0, math.radians(73))
        ctx.last_seen = 1.0
        cmd = Approach().step(ctx, 1.0)
        assert cmd is not None and cmd.state == want, (surface, cmd)
        assert ctx.base_distance(1.0) == pytest.approx(surface, abs=0.01)
    ctx.scan = (np.column_stack([np.full_like(ys, 3.0), ys]), 1.0)  # only far returns: not its face
    assert ctx.base_distance(1.0) is None


def test_a_range_by_size_beyond_what_the_scan_shows_on_its_bearing_gives_way_to_the_scan() -> None:
    """A cone ranged by its assumed size at 1.2 m stood 0.65 m away, and the guard held every step
    closer until the goal timed out: a scan return on the target's bearing nearer than the tracker's
    range (within 2 m) is the range; a farther one (what is behind a small object) is not."""
    import pytest

    from go2vlm.behavior.goals import parse_goal
    from go2vlm.behavior.sighting import Sighting
    from go2vlm.behavior.strategies.approach import Approach
    from go2vlm.behavior.strategies.base import Context
    from go2vlm.behavior.strategies.params import MissionParams

    p = MissionParams()
    cf = p.camera_forward_m
    ctx = Context(p, goal=parse_goal("go to the cone"), view=math.radians(73))
    ys = np.linspace(-0.1, 0.1, 5)
    for face, ranged, want, method in ((0.75, 1.2, 0.75, "lidar"), (1.9, 1.2, 1.2 + cf, "size")):
        ctx.scan = (np.column_stack([np.full_like(ys, face), ys]), 1.0)
        ctx.sighting = Sighting(1.0, "cone", "tracking", 0.0, ranged, "size", 0.0, math.radians(73))
        ctx.last_seen = 1.0
        assert ctx.base_distance(1.0) == pytest.approx(want, abs=0.01)
        cmd = Approach().step(ctx, 1.0)
        assert cmd is not None and f"({method})" in cmd.reason, cmd
    assert cmd.state == "approaching"
    for far in (10.0, 2.6):  # rooms 37 and 47: a door jamb, a brick on the bearing, the object far beyond
        ctx.scan = (np.column_stack([np.full_like(ys, 0.75), ys]), 1.0)
        ctx.sighting = Sighting(1.0, "cone", "tracking", 0.0, far, "bottom", 0.0, math.radians(73))
        assert ctx.base_distance(1.0) == pytest.approx(far + cf, abs=0.01)
        cmd = Approach().step(ctx, 1.0)
        assert cmd is not None and cmd.state in ("approaching", "detouring") and "(bottom)" in cmd.reason, cmd
    ctx.scan = (np.column_stack([np.full_like(ys, 0.75), ys]), 1.0)
    ctx.sighting = Sighting(1.0, "cone", "tracking", 0.0, 1.2, "size", 0.0, math.radians(73))
    assert Approach().step(ctx, 1.0).state == "reached"


def test_a_look_for_whose_turn_is_held_is_found_in_view_all_the_same() -> None:
    """In a doorway the gate held every turn to centre the green box, 25 deg off, until the goal timed
    out: confirmed in view but not centred for `align_found_s`, it is found, saying how far off."""
    from go2vlm.behavior.goals import parse_goal
    from go2vlm.behavior.sighting import Sighting
    from go2vlm.behavior.strategies.base import Context
    from go2vlm.behavior.strategies.params import MissionParams

    ctx = Context(MissionParams(), goal=parse_goal("look for the green box"), view=math.radians(73))
    a, states = Approach(), []
    for k in range(int((MissionParams().align_found_s + 1.0) / 0.1)):
        now = 1.0 + 0.1 * k
        ctx.sighting = Sighting(now, "green box", "tracking", -0.7, 2.0, "bottom", math.radians(25), math.radians(73))
        ctx.last_seen = now
        cmd = a.step(ctx, now)
        assert cmd is not None
        states.append(cmd.state)
        if cmd.state == "found":
            break
    assert states[0] == "aligning" and states[-1] == "found", states
    assert 0.1 * (len(states) - 1) == pytest.approx(MissionParams().align_found_s, abs=0.15)
    assert "25 deg to the left" in cmd.reason and "not centred" in cmd.reason


def test_a_thin_thing_on_the_bearing_of_a_wider_target_does_not_range_it() -> None:
    """Rooms 40: a table leg 6 cm wide stood on the bearing of the tray, 2.3 m away and ranged about
    1.7 m; its return ranged the tray at 0.84 m and ended the go to `reached` 1.5 m short. A return
    counts only where what it hits spans at least SCAN_COVER of the box's angular width."""
    import pytest

    from go2vlm.behavior.goals import parse_goal
    from go2vlm.behavior.sighting import Sighting
    from go2vlm.behavior.strategies.base import Context
    from go2vlm.behavior.strategies.params import MissionParams
    from go2vlm.world.ranging import RangingParams

    p = MissionParams()
    cf = p.camera_forward_m
    ctx = Context(p, goal=parse_goal("go to the tray"), view=math.radians(73))
    width = math.radians(10.0)
    ctx.sighting = Sighting(1.0, "tray", "tracking", 0.0, 1.7, "bottom", 0.0, math.radians(73), width)
    ctx.last_seen = 1.0
    leg = np.array([[cf + 0.84, 0.0], [cf + 0.86, 0.01]])
    ctx.scan = (leg, 1.0)
    assert ctx.base_distance(1.0) == pytest.approx(1.7 + cf, abs=0.01)  # the leg: not the tray
    SCAN_COVER = RangingParams().scan_cover
    for cover, want in ((SCAN_COVER + 0.1, 0.84 + cf), (SCAN_COVER - 0.1, 1.7 + cf)):
        a = np.linspace(-cover * width / 2, cover * width / 2, 7)
        ctx.scan = (np.column_stack([cf + 0.84 * np.cos(a), 0.84 * np.sin(a)]), 1.0)
        assert ctx.base_distance(1.0) == pytest.approx(want, abs=0.01), cover


def test_a_box_that_fills_the_view_is_ranged_by_the_scan_where_it_has_a_return() -> None:
    """Rooms 37: the shelf filled the view 1.01 m away, was "ranged" 0 (fills_view) and the go to ended
    `reached` 1 cm outside success: the scan's return ranges it, so the approach walks on to the stop
    distance; without a return it still counts as near."""
    p = MissionParams()
    cf = p.camera_forward_m
    ctx = Context(p, goal=parse_goal("go to the shelf"), view=math.radians(73))
    ys = np.linspace(-1.0, 1.0, 41)
    for face, want in ((1.0 - cf, "approaching"), (p.stop_distance_m - 0.05 - cf, "reached")):
        ctx.scan = (np.column_stack([np.full_like(ys, cf + face), ys]), 1.0)
        ctx.sighting = Sighting(1.0, "shelf", "tracking", 0.0, 0.0, "fills_view", 0.0, math.radians(73),
                                math.radians(65))  # fmt: skip
        ctx.last_seen = 1.0
        assert ctx.base_distance(1.0) == pytest.approx(face + cf, abs=0.01)
        cmd = Approach().step(ctx, 1.0)
        assert cmd is not None and cmd.state == want and "(lidar)" in cmd.reason, cmd
    ctx.scan = (np.zeros((0, 2)), 1.0)
    assert ctx.base_distance(1.0) == pytest.approx(cf, abs=0.01)
    assert Approach().step(ctx, 1.0).state == "reached"


def test_a_range_far_short_of_the_remembered_object_on_its_bearing_gives_way_to_the_memory() -> None:
    """Rooms 37: the tracker's box spread onto a door leaf of the shelf's wood, ranged 1.0 m (bottom),
    and the go to ended `reached` 7.4 m short, while the memory held the shelf, seen 0.5 s before,
    8 m away on that bearing. A confident, fresh remembered object of the goal's label on the bearing,
    far beyond the range, is the range; an old, unsure, off-bearing or near one is not."""
    from go2vlm.world.objects_msg import Remembered
    from go2vlm.world.ranging import RangingParams

    p = MissionParams()
    cf = p.camera_forward_m
    ctx = Context(p, goal=parse_goal("go to the shelf"), view=math.radians(73))
    ctx.pose = Pose(0.0, 0.0, 0.0, 10.0)
    ctx.scan = (np.zeros((0, 2)), 10.0)
    ctx.sighting = Sighting(10.0, "shelf", "tracking", 0.0, 1.0, "bottom", 0.0, math.radians(73), math.radians(8))
    ctx.last_seen = 10.0

    def shelf(x: float, y: float = 0.0, conf: float = 0.9, seen: float = 9.5, label: str = "shelf") -> Remembered:
        return Remembered("s1", label, x, y, 0.5, (1.0, 1.0, 1.0), conf, seen, (0.01, 0.0, 0.01))

    ctx.memory = [shelf(8.5)]
    assert ctx.base_distance(10.0) == pytest.approx(8.0, abs=0.01) and ctx.ranged_by == "memory"
    cmd = Approach().step(ctx, 10.0)
    assert cmd is not None and cmd.state != "reached" and "(memory)" in cmd.reason
    # The leaf the blob spread onto, 1.0 m ahead and 0.8 m wide: in the way, not the goal (the guard
    # held the walk into it at zero for 8 s, and the go to ended `reached` on it, rooms 37 at 3e9e72c)
    ys = np.linspace(-0.4, 0.4, 17)
    ctx.scan = (np.column_stack([np.full_like(ys, 1.0 + cf), ys]), 10.0)
    cmd = Approach().step(ctx, 10.0)
    assert cmd is not None and cmd.state == "detouring" and "(memory)" in cmd.reason, cmd
    ctx.scan = (np.zeros((0, 2)), 10.0)
    MEMORY_FRESH_S = RangingParams().memory_fresh_s
    for other in (shelf(8.5, conf=0.3), shelf(8.5, seen=10.0 - MEMORY_FRESH_S - 0.5), shelf(8.5, y=4.0),
                  shelf(2.2), shelf(8.5, label="duck")):  # fmt: skip
        ctx.memory, ctx.overruled = [other], None  # (not held from the overrule above: MEMORY_HOLD_S)
        assert ctx.base_distance(10.0) == pytest.approx(1.0 + cf, abs=0.01) and ctx.ranged_by == "bottom", other


def test_the_memory_s_range_is_held_a_moment_after_it_overruled() -> None:
    """Rooms 37 at 405ed76: for one step the shelf fell out of the memory's cone, and the blob on the
    door leaf, 0.81 m away and ranged by the lidar, was `reached` 7.4 m short. The memory's range
    stands MEMORY_HOLD_S after it last overruled, while the tracker's is still as far short of it."""
    from go2vlm.world.objects_msg import Remembered

    p = MissionParams()
    cf, MEMORY_HOLD_S = p.camera_forward_m, p.ranging.memory_hold_s
    ctx = Context(p, goal=parse_goal("go to the shelf"), view=math.radians(73))
    ctx.scan = (np.zeros((0, 2)), 10.0)
    ctx.memory = [Remembered("s1", "shelf", 8.5, 0.0, 0.5, (1.0, 1.0, 1.0), 0.9, 9.5, (0.01, 0.0, 0.01))]

    def seen(now: float, dist: float, bearing: float = 0.0) -> float | None:
        ctx.pose = Pose(0.0, 0.0, 0.0, now)
        ctx.sighting = Sighting(now, "shelf", "tracking", 0.0, dist, "bottom", bearing, math.radians(73),
                                math.radians(8))  # fmt: skip
        ctx.last_seen = now
        return ctx.base_distance(now)

    assert seen(10.0, 1.0) == pytest.approx(8.0, abs=0.01) and ctx.ranged_by == "memory"
    off = math.radians(30)  # the box has slid off the shelf's bearing: the memory has nothing on it
    assert seen(11.0, p.stop_distance_m - cf - 0.1, off) == pytest.approx(8.0, abs=0.01)
    cmd = Approach().step(ctx, 11.0)
    assert cmd is not None and cmd.state != "reached" and "(memory)" in cmd.reason
    assert seen(11.5, 6.0, off) == pytest.approx(6.0 + cf, abs=0.01)  # not far short of it: the tracker's
    assert seen(10.0 + MEMORY_HOLD_S + 0.1, p.stop_distance_m - cf - 0.1, off) == pytest.approx(p.stop_distance_m - 0.1)
    assert Approach().step(ctx, 10.0 + MEMORY_HOLD_S + 0.1).state == "reached"
    ctx.new_goal(parse_goal("go to the shelf"))
    assert ctx.overruled is None


def test_a_range_by_size_beyond_the_go_to_cap_counts_only_once_it_has_held() -> None:
    """Rooms 14: one frame ranged a sliver of the teddy bear, beside a door jamb 8 m away, at 72.5 m by
    its size, and the go to was refused. A range by size beyond the cap counts only after FAR_HOLD_S of
    such ranges; a range by the bottom edge counts at once; a range within the cap starts the hold again."""
    from go2vlm.behavior.goals import parse_goal
    from go2vlm.behavior.sighting import Sighting
    from go2vlm.behavior.strategies.base import Context
    from go2vlm.behavior.strategies.params import MissionParams

    p = MissionParams()
    cf, cap, FAR_HOLD_S = p.camera_forward_m, 25.0, p.ranging.far_hold_s
    ctx = Context(p, goal=parse_goal("go to the teddy bear"), view=math.radians(73))

    def seen(t: float, d: float, method: str) -> float | None:
        ctx.sighting, ctx.last_seen = Sighting(t, "teddy bear", "tracking", 0.0, d, method, 0.0, 1.27), t
        return ctx.capped_distance(t, cap)

    assert seen(1.0, 72.5, "size") is None
    assert seen(1.0 + FAR_HOLD_S / 2, 40.0, "default_size") is None
    assert seen(1.0 + FAR_HOLD_S / 2 + 0.1, 8.0, "size") == 8.0 + cf  # within the cap: no hold
    assert seen(2.0, 72.5, "size") is None  # the hold starts again
    assert seen(2.0 + FAR_HOLD_S, 72.5, "size") == 72.5 + cf  # it held: the cap refuses it
    assert seen(4.0, 30.0, "bottom") == 30.0 + cf  # by the bottom edge: at once


def test_a_go_to_is_not_reached_on_the_moment_it_first_sees_the_target() -> None:
    """Rooms 37 at d201535: the shelf, first seen through a doorway, was ranged 1.1 m on the blob's
    door leaf and `reached` 0.4 s later, 7.5 m short; the memory placed it right 0.3 s after. Within
    reach_settle_s of the first confirmation it holds still; the memory's place, arriving then,
    overrules the range and it walks on; with nothing against the range, it is reached after."""
    from go2vlm.world.objects_msg import Remembered

    p = MissionParams()
    cf = p.camera_forward_m
    near = p.stop_distance_m - cf - 0.05

    def run(memory_at: float | None) -> list[str]:
        ctx = Context(p, goal=parse_goal("go to the shelf"), view=math.radians(73))
        ctx.scan = None
        states, a, t = [], Approach(), 30.0
        while t < 30.0 + MissionParams().reach_settle_s + 0.5:
            ctx.pose = Pose(0.0, 0.0, 0.0, t)
            s = Sighting(t, "shelf", "tracking", 0.0, near, "bottom", 0.0, math.radians(73), math.radians(8))
            ctx.sighting = s
            ctx.saw(s)
            if memory_at is not None and t >= memory_at:
                ctx.memory = [Remembered("s1", "shelf", 8.0, 0.0, 0.5, (1.0, 1.0, 1.0), 0.9, t, (0.01, 0.0, 0.01))]
            cmd = a.step(ctx, t)
            assert cmd is not None
            if t - 30.0 < MissionParams().reach_settle_s - 1e-9:
                assert cmd.state != "reached"
            states.append(cmd.state)
            if cmd.state == "reached":
                break
            t += 0.1
        return states

    alone = run(None)
    assert alone[0] == "approaching" and alone[-1] == "reached"
    with_memory = run(30.3)
    assert "reached" not in with_memory and with_memory[-1] in ("approaching", "detouring")
    ctx = Context(p, goal=parse_goal("go to the shelf"))
    ctx.saw(Sighting(1.0, "shelf", "tracking", 0.0, 1.0, "bottom"))
    ctx.saw(Sighting(1.0 + p.lost_timeout_s + 0.1, "shelf", "tracking", 0.0, 1.0, "bottom"))
    assert ctx.seen_since == 1.0 + p.lost_timeout_s + 0.1  # a gap: the confirmation starts afresh


def _tracked_walk(x: float, y: float, yaw: float, obj: tuple[float, float], sure: float = 0.95) -> tuple[list, Context]:
    """A tracked go to in test_strategy_route's two rooms, closed round a kinematic robot: the duck is
    confirmed whenever it is within the camera's view and in plain sight on the map."""
    from test_strategy_route import ctx_at, duck, two_rooms

    from go2vlm.behavior.navigate import line_of_sight

    cm, a, dt = two_rooms(), Approach(), 0.1
    d = replace(duck(*obj), confidence=sure)
    ctx = ctx_at(x, y, yaw, cm, now=0.0)
    ctx.target_obj = d
    hfov = math.radians(73)
    cmds = []
    for k in range(int(120 / dt)):
        t = k * dt
        ctx.pose = Pose(x, y, yaw, t)
        cf = ctx.params.camera_forward_m
        cx, cy = x + cf * math.cos(yaw), y + cf * math.sin(yaw)
        bearing = math.atan2(d.y - cy, d.x - cx) - yaw
        bearing = (bearing + math.pi) % (2 * math.pi) - math.pi
        if abs(bearing) < hfov / 2 and line_of_sight(cm, (x, y), (d.x, d.y), ctx.place_planner, d.radius + 0.3):
            s = Sighting(t, "duck", "tracking", -bearing / (hfov / 2), math.hypot(d.x - cx, d.y - cy) - d.radius,
                         "bottom", bearing, hfov)  # fmt: skip
            ctx.sighting = s
            ctx.saw(s)
        cmd = a.step(ctx, t)
        if cmd is None:
            break
        cmds.append(cmd)
        if cmd.state == "reached":
            break
        x, y, yaw = x + cmd.vx * dt * math.cos(yaw), y + cmd.vx * dt * math.sin(yaw), yaw + cmd.wz * dt
    return cmds, ctx


@pytest.mark.parametrize("sure", [0.95, 0.5])
def test_a_tracked_go_to_walks_with_the_navigator_the_whole_way_then_closes_in(sure: float) -> None:
    """The duck in plain view straight through the door: the navigator walks the go to all the way
    (not the approach law with the local planner beside the jamb), through the door, and never backs
    or rocks. Once it is there, in sight, the approach law closes the last of the distance (ranged
    by the frame's range) and stops at the stop distance."""
    cmds, ctx = _tracked_walk(2.5, 0.3, math.pi, (-2.5, -0.3), sure)
    assert cmds[-1].state == "reached", cmds[-1]
    if sure < MissionParams().memory_confirm_confidence:
        assert "the memory's place" not in cmds[-1].reason, cmds[-1]
    p, o = ctx.params, ctx.target_obj
    assert o is not None and ctx.pose is not None
    surface = math.hypot(o.x - ctx.pose.x, o.y - ctx.pose.y) - o.radius
    # stopped where the go to stops, not where the navigator's tolerance left it
    assert abs(surface - p.stop_distance_m) <= p.distance_tolerance_m + 0.02, surface
    walked = [c for c in cmds if c.vx > 0.0]
    assert walked and walked[0].navigated and "with the navigator" in walked[0].reason
    assert all(c.vx >= 0.0 for c in cmds)  # never backs
    first_law = next((i for i, c in enumerate(cmds) if c.vx > 0 and not c.navigated), len(cmds))
    assert all(not c.navigated for c in cmds[first_law:] if c.vx > 0)  # no handover back and forth
    assert ctx.pose is not None and ctx.pose.x < -1.0


def test_a_target_seen_past_a_jamb_is_walked_to_through_the_door() -> None:
    """The duck in view through the door from beside its jamb: the navigator walks the go to, through
    the door, and on to where it was seen when the jamb hides it; the track too old: lost."""
    from test_strategy_route import ctx_at, two_rooms

    a, cm = Approach(), two_rooms()
    ctx = ctx_at(0.5, -1.0, 2.6, cm, now=0.0)
    s = Sighting(0.0, "duck", "tracking", 0.1, 1.2, "bottom", -0.1)
    ctx.sighting = s
    ctx.saw(s)
    cmd = a.step(ctx, 0.0)
    assert cmd is not None and cmd.navigated and "with the navigator" in cmd.reason, cmd
    assert ctx.route is not None
    w = ctx.route.plan.waypoints
    crossings = [a[1] + (b[1] - a[1]) * (0 - a[0]) / (b[0] - a[0]) for a, b in zip(w[:-1], w[1:], strict=True)
                 if a[0] * b[0] < 0]  # fmt: skip
    end = w[-1]  # in the doorway or past it: where the duck is in sight
    assert all(abs(y) < 0.6 for y in crossings) and end[0] < 0.3 and abs(end[1]) < 0.6, w
    ctx.pose = ctx_at(0.5, -1.0, 2.6, cm, now=1.0).pose
    hidden = a.step(ctx, 1.0)  # no fresh sighting: out of view
    assert hidden is not None and hidden.navigated and "out of view" in hidden.reason, hidden
    late = 2.0 + MissionParams().detour_memory_s
    ctx.pose = ctx_at(0.5, -1.0, 2.6, cm, now=late).pose
    assert a.step(ctx, late) is None  # the track is too old: lost, then the search


def test_a_go_to_whose_last_bit_is_blocked_is_reached_as_near_as_the_way_lets_it() -> None:
    """The duck against a box the map does not hold, the memory's place for it 0.2 m short (the
    navigator is there), the frame's range 0.15 m more than the stop distance: the approach law's
    last bit is blocked on the scan. Within reach_slack_m of the stop distance the go to is reached,
    saying so; where the navigator is not there yet, or without a map, it goes round."""
    from test_strategy_route import ctx_at, duck, two_rooms

    p = MissionParams()
    d = duck(-3.0, -2.0)
    cf = p.camera_forward_m

    box = np.column_stack([np.full(13, 0.4), np.linspace(-0.3, 0.3, 13)])  # a box face 0.4 m ahead, across the way

    def at(gap: float, cm: object, scan: np.ndarray = box) -> Command | None:
        x = d.x + d.radius + p.stop_distance_m + gap  # east of the duck, facing it
        ctx = ctx_at(x, d.y, math.pi, cm, now=10.0)  # type: ignore[arg-type]
        ctx.target_obj = replace(d, x=d.x + 0.2)  # the memory's place, 0.2 m short
        rng = x - cf - d.x - d.radius  # the frame's range, from the camera
        s = Sighting(10.0, "duck", "tracking", 0.0, rng, "bottom", 0.0, math.radians(73))
        ctx.sighting = s
        ctx.saw(s)
        ctx.last_seen = ctx.seen_since = 0.0  # seen a while: not "just seen"
        ctx.scan = (scan, 10.0)
        a = Approach()
        return a.step(ctx, 10.0)

    near = at(0.15, two_rooms())
    assert near is not None and near.state == "reached" and "as near as the way lets it" in near.reason, near
    far = at(0.6, two_rooms())
    assert far is not None and far.state != "reached", far
    no_map = at(0.15, None)
    assert no_map is not None and no_map.state == "detouring", no_map
    # a door's jamb on the left of the way, the duck past it: a way a little right keeps it in view
    jamb = np.column_stack([np.full(8, 0.3), np.linspace(0.12, 0.5, 8)])
    past = at(0.15, two_rooms(), jamb)
    assert past is not None and past.state == "detouring" and past.vx > 0.0, past
