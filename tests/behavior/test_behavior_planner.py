"""The approach's local planner (behavior/planner/local.py): a free way passes the command unchanged; a box
in the way turns the robot to a free heading; the goal itself is no obstacle; it never speeds anything
up nor drives backwards."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.behavior.planner import PlannerParams, corridor_free, steer
from go2vlm.behavior.planner.local import BACK_SPEED, BACK_TURN, unstick
from go2vlm.geometry.footprint import rect_distance

P = PlannerParams()
W = 0.8  # the approach's turn rate ceiling


def box(cx: float, cy: float, hx: float, hy: float) -> np.ndarray:
    xs, ys = np.linspace(cx - hx, cx + hx, 11), np.linspace(cy - hy, cy + hy, 11)
    return np.array([[x, y] for x in xs for y in (cy - hy, cy + hy)] + [[x, y] for y in ys for x in (cx - hx, cx + hx)])


def test_free_way_passes_unchanged() -> None:
    s = steer(0.4, 0.1, 0.4, 0.0, 3.0, box(0.0, 3.0, 0.3, 0.3), P, max_angular=W)
    assert (s.vx, s.wz, s.blocked, s.note) == (0.4, 0.1, False, "")


def test_box_in_the_way_steers_round_it() -> None:
    pts = box(1.6, 0.05, 0.2, 0.3)
    assert corridor_free(pts, 0.0, P) < P.lookahead
    s = steer(0.0, 0.0, 0.4, 0.0, 3.5, pts, P, max_angular=W)
    assert s.blocked and s.note and s.heading != 0.0
    assert corridor_free(pts, s.heading, P) >= P.lookahead
    assert 0.0 < s.vx < 0.4 and s.wz * s.heading > 0  # slower, turning towards the free heading


def test_the_goal_is_not_its_own_obstacle() -> None:
    # The cylinder itself, 1.2 m ahead, with the robot to stop 0.8 m from it: no detour.
    cyl = np.array([[1.2 + 0.3 - 0.3 * math.cos(a), 0.3 * math.sin(a)] for a in np.linspace(-1.2, 1.2, 13)])
    s = steer(0.2, 0.0, 0.2, 0.0, 1.2, cyl, P, max_angular=W, reach_m=0.4)
    assert not s.blocked and (s.vx, s.wz) == (0.2, 0.0)


def test_goal_closer_than_the_obstacle_is_not_steered() -> None:
    s = steer(0.3, 0.0, 0.3, 0.0, 0.5, box(2.5, 0.0, 0.3, 0.3), P, max_angular=W)
    assert not s.blocked


def test_keeps_to_the_side_it_chose() -> None:
    pts = box(1.5, 0.0, 0.2, 0.3)  # dead ahead: either side is as good
    left = steer(0.0, 0.0, 0.4, 0.0, 3.5, pts, P, max_angular=W, side=1.0)
    right = steer(0.0, 0.0, 0.4, 0.0, 3.5, pts, P, max_angular=W, side=-1.0)
    assert left.heading > 0 > right.heading


def test_boxed_in_turns_in_place() -> None:
    # 0.75 m round: not even a creep's way (0.16 m each side) is min_free long (0.9 m is, at a creep)
    ring = np.array([[0.75 * math.cos(a), 0.75 * math.sin(a)] for a in np.linspace(-math.pi, math.pi, 180)])
    s = steer(0.4, 0.0, 0.4, 0.0, 3.0, ring, P, max_angular=W)
    assert s.blocked and s.vx == 0.0 and "no free way" in s.note and abs(s.wz) >= W / 2


def test_a_short_free_way_is_still_progress() -> None:
    # Nothing free for the 1.2 m it would like, but 0.5 m ahead-left is: creep that way, slower.
    ring = np.array([[1.2 * math.cos(a), 1.2 * math.sin(a)] for a in np.linspace(-math.pi, math.pi, 180)])
    s = steer(0.0, 0.0, 0.4, 0.0, 3.0, ring, P, max_angular=W)
    assert s.blocked and 0.0 < s.vx < 0.4 * 0.5


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3)), max_size=20),
    st.floats(0.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(0.0, 1.0),
    st.floats(-math.pi, math.pi),
    st.one_of(st.none(), st.floats(0.0, 6.0)),
    st.sampled_from([-1.0, 0.0, 1.0]),
)
def test_never_faster_never_backwards(
    pts: list, vx: float, wz: float, speed: float, bearing: float, goal: float | None, side: float
) -> None:
    s = steer(vx, wz, speed, bearing, goal, np.array(pts).reshape(-1, 2), P, max_angular=W, side=side)
    if not s.blocked:  # the approach's own command; slowed where only a slower speed's clearance is free
        assert s.wz == wz and (s.vx == vx or (0.0 <= s.vx < vx and "slowed" in s.note))
    else:
        assert 0.0 <= s.vx <= speed
        assert abs(s.wz) <= W
        assert abs(math.remainder(s.heading - bearing, 2 * math.pi)) <= P.max_offset + 1e-9
        if s.vx > 0 and goal is None:  # it only drives along a corridor that is free
            free = corridor_free(np.array(pts).reshape(-1, 2), s.heading, P)
            assert free > 0.0
    assert math.isfinite(s.vx) and math.isfinite(s.wz)


# -- unstick: a turn in place the footprint cannot sweep --------------------------------------------
# The wedges below were measured with 0.35 m kept at every speed (the clearance before it grew with
# speed): they keep that clearance, so that each stays the tight spot it was (unstick's rules are the
# same at any clearance; a creep's few centimetres would leave most of them room to turn).
P = PlannerParams(margin=0.35, margin_per_speed_s=0.0)


def _edge(x: float, y0: float = -0.6, y1: float = 0.6) -> np.ndarray:
    """A straight edge across the robot's way at `x` (base frame), points every 2 cm."""
    ys = np.arange(y0, y1, 0.02)
    return np.column_stack([np.full_like(ys, x), ys])


def _clearance(points: np.ndarray, x: float, y: float, th: float) -> float:
    dx, dy = points[:, 0] - x, points[:, 1] - y
    c, s = math.cos(th), math.sin(th)
    return float(rect_distance(c * dx + s * dy, -s * dx + c * dy, P.half_length, P.half_width).min())


def test_a_turn_in_place_facing_a_table_edge_backs_away_and_a_clear_turn_is_left_alone() -> None:
    table = _edge(P.half_length + 0.25)  # 0.25 m ahead of the footprint: the corners would sweep closer
    back = unstick(0.0, 0.5, table, P)
    assert back is not None and back.vx == -BACK_SPEED and back.wz == BACK_TURN and back.blocked
    assert "backing away, turning" in back.note  # reversing out: the way it wanted to turn
    assert unstick(0.0, 0.5, _edge(P.half_length + 1.0), P) is None  # room to turn
    walking = unstick(0.3, 0.5, table, P)  # walking on turning into it: the guard would hold it too
    assert walking is not None and (walking.vx, walking.wz) == (-BACK_SPEED, BACK_TURN)
    assert unstick(0.3, 0.5, _edge(P.half_length + 1.5), P) is None  # its arc is clear
    post = np.array([[0.15, 0.5], [0.3, 0.5]])  # beside it, on the left: a walking left turn sweeps into it
    turn_first = unstick(0.3, 0.8, post, P)
    assert turn_first is None or (turn_first.vx, turn_first.wz) in (
        (0.0, 0.8),
        (-BACK_SPEED, 0.0),
        (-BACK_SPEED, BACK_TURN),
    )
    assert unstick(0.0, 0.5, np.zeros((0, 2)), P) is None
    assert unstick(0.0, 0.5, None, P) is None
    boxed = np.vstack([table, _edge(-P.half_length - 0.1)])  # a wall just behind too: nothing to do
    assert unstick(0.0, 0.5, boxed, P) is None
    post = np.array([[-0.35, -0.55]])  # behind on the right: reversing on a left turn swings the tail into it
    straight = unstick(0.0, 0.5, np.vstack([table, post]), P)
    assert straight is not None and (straight.vx, straight.wz) == (-BACK_SPEED, 0.0), straight


@settings(max_examples=200, deadline=None)
@given(
    pts=st.lists(st.tuples(st.floats(-1.5, 1.5), st.floats(-1.5, 1.5)), min_size=1, max_size=30),
    wz=st.floats(-1.0, 1.0).filter(lambda w: abs(w) > 0.01),
)
def test_unstick_moves_only_instead_of_a_turn_it_cannot_sweep_and_only_where_its_move_is_clear(
    pts: list[tuple[float, float]], wz: float
) -> None:
    points = np.array(pts, dtype=float)
    out = unstick(0.0, wz, points, P)
    if out is None:
        return
    moves = {(-BACK_SPEED, math.copysign(BACK_TURN, wz)), (-BACK_SPEED, 0.0), (0.0, -wz)}  # never on
    assert (out.vx, out.wz) in moves, out
    now = _clearance(points, 0.0, 0.0, 0.0)
    keep = min(P.margin, now) - 1e-9
    turns = [_clearance(points, 0.0, 0.0, math.copysign(a, wz)) for a in np.linspace(0.0, math.radians(30), 7)]
    assert min(turns) < keep, "it moved instead of a turn it could sweep"
    t = np.linspace(0.0, 0.3 / BACK_SPEED, 7)
    if out.vx == 0.0:  # the other way round
        path = [_clearance(points, 0.0, 0.0, -math.copysign(a, wz)) for a in np.linspace(0.0, math.radians(30), 7)]
    elif out.wz == 0.0:  # straight back, or straight on
        path = [_clearance(points, out.vx * tk, 0.0, 0.0) for tk in t]
    else:  # its reversing arc, the whole 0.3 m of it
        w, v = out.wz, out.vx
        path = [_clearance(points, v * math.sin(w * tk) / w, v * (1 - math.cos(w * tk)) / w, w * tk) for tk in t]
    assert min(path) >= keep, "it moved into something"


def test_a_straight_walk_the_guard_would_hold_backs_away_and_one_it_would_not_is_left_alone() -> None:
    """Inside the margin already, the guard allows no step closer: a straight walk into it stood at
    zero until the frontier was given up (rooms 12); it backs straight away instead."""
    near = _edge(P.half_length + P.margin + 0.01)  # 1 cm outside the margin: the first 3 cm break it
    back = unstick(0.3, 0.0, near, P)
    assert back is not None and (back.vx, back.wz) == (-BACK_SPEED, 0.0) and "walk on" in back.note
    assert unstick(0.3, 0.0, _edge(P.half_length + P.margin + 0.2), P) is None  # room to walk: the guard slows it
    assert unstick(0.0, 0.0, near, P) is None  # a stop is a stop
    boxed = np.vstack([near, _edge(-P.half_length - 0.1)])
    assert unstick(0.3, 0.0, boxed, P) is None  # no room behind: the guard holds it, and says so


def test_a_turn_with_no_room_behind_walks_on_straight_or_turns_the_other_way_round() -> None:
    """Boxed in behind (rooms 12: a left turn the guard held in the corridor for 80 s, with no room
    to back away): straight on where that is clear, to turn later; else the other way round."""
    behind = _edge(-P.half_length - 0.1)  # inside the margin: neither backing nor turning in place
    on = unstick(0.1, 0.8, behind, P)  # walking on turning sharply: straight on, no faster
    assert on is not None and (on.vx, on.wz) == (0.1, 0.0) and "walking on straight" in on.note
    assert unstick(0.0, 0.5, behind, P) is None  # a search's turn in place never becomes a walk: held
    route = unstick(0.0, 0.5, behind, P, walk=BACK_SPEED)  # a route's turn (the explorer walks on anyway)
    assert route is not None and (route.vx, route.wz) == (BACK_SPEED, 0.0), route
    tail = np.array([[-0.3, -0.465]])  # right of the rear-right corner: a left turn swings the tail into it
    posts = np.array([[-P.half_length - 0.5, 0.0], [P.half_length + 0.5, 0.0]])  # no 0.3 m ahead nor behind
    other = unstick(0.0, 0.5, np.vstack([tail, posts]), P)
    assert other is not None and (other.vx, other.wz) == (0.0, -0.5) and "the other way round" in other.note
    assert unstick(0.0, -0.5, np.vstack([tail, posts]), P) is None  # the right turn itself is clear


def _corridor(half_width: float = 0.75, length: float = 8.0) -> np.ndarray:
    xs = np.arange(-length, length, 0.02)
    return np.vstack([np.c_[xs, np.full_like(xs, half_width)], np.c_[xs, np.full_like(xs, -half_width)]])


def _clearance(walls: np.ndarray, x: float, y: float, yaw: float) -> float:
    dx, dy = walls[:, 0] - x, walls[:, 1] - y
    c, s = math.cos(yaw), math.sin(yaw)
    return float(rect_distance(c * dx + s * dy, -s * dx + c * dy, P.half_length, P.half_width).min())


def test_askew_in_a_corridor_it_backs_towards_a_way_on_behind_it() -> None:
    """Rooms 14: askew and off the middle of a 1.5 m corridor, the way on behind. The turn towards it
    does not keep the margin; `reverse` backs towards the way on, turning the rear onto it."""
    from go2vlm.behavior.planner.local import REVERSE_SPEED, reverse

    walls, x, y, yaw = _corridor(), 0.0, -0.2, math.radians(15)
    base = _to_base(walls, x, y, yaw)
    toward = math.radians(170)  # the way on: along the corridor, behind on the left
    plain = unstick(0.0, W, base, P)
    assert plain is not None and plain.vx >= -BACK_SPEED and "way on" not in plain.note  # held: without a way on
    st = unstick(0.0, W, base, P, toward=toward)
    assert st is not None and st.vx == -REVERSE_SPEED and st.wz < 0.0 and "backing towards the way on" in st.note
    assert reverse(base, math.radians(10), P) is not None  # (behind or not is unstick's call)
    end = np.c_[np.full(40, -0.7), np.linspace(-0.75, 0.75, 40)]  # a wall across, 0.35 m behind the tail
    assert reverse(_to_base(np.vstack([walls, end]), 0.0, 0.0, 0.0), math.pi, P) is None


def _to_base(pts: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = pts[:, 0] - x, pts[:, 1] - y
    return np.c_[c * dx + s * dy, -s * dx + c * dy]


def _walk_under_guard(
    world: np.ndarray, start: tuple[float, float, float], goal: tuple[float, float], align: float,
    with_toward: bool = True,
) -> tuple[float, float, float, int]:  # fmt: skip
    """The mission's escape (planner/escape.py) over a turn-then-walk law towards `goal` (turning in
    place beyond `align` rad off), for 60 s at 20 Hz, each step applied only as the guard would (never
    closer than the margin, or than it is, if inside it): the pose it ends at, and how many times it
    changed between walking forward and back."""
    from go2vlm.behavior.planner.escape import Escape

    esc, (x, y, yaw), dt, flips, last = Escape(), start, 0.05, 0, 0.0
    for k in range(1200):
        if math.hypot(goal[0] - x, goal[1] - y) < 0.4:
            break
        bearing = math.atan2(goal[1] - y, goal[0] - x) - yaw
        bearing = (bearing + math.pi) % (2 * math.pi) - math.pi
        vx, wz = (0.0, math.copysign(W, bearing)) if abs(bearing) > align else (0.4, 1.5 * bearing)
        out = esc.step(vx, wz, k * dt, _to_base(world, x, y, yaw), P, max_angular=W, walk=BACK_SPEED,
                       toward=bearing if with_toward else None)  # fmt: skip
        if out is not None:
            vx, wz = out[0], out[1]
        flips += vx * last < 0
        last = vx or last
        nyaw = yaw + wz * dt
        nx, ny = x + vx * dt * math.cos(nyaw), y + vx * dt * math.sin(nyaw)
        keep = P.clearance.at(abs(vx) + abs(wz) * math.hypot(P.half_length, P.half_width))  # the guard's rule
        if _clearance(world, nx, ny, nyaw) >= min(keep, _clearance(world, x, y, yaw)) - 1e-9:
            x, y, yaw = nx, ny, nyaw
    assert _clearance(world, x, y, yaw) > 0.0
    return x, y, yaw, flips


def test_a_route_behind_in_a_corridor_is_walked_backwards_under_the_guards_rule() -> None:
    """The mission's escape over a route 3 m behind, the robot askew and off the middle of a 1.5 m
    corridor, each step applied only as the guard would: it gets there. Without `toward`, it rocks
    where it stands."""
    walls, goal, start = _corridor(), (-3.0, 0.0), (0.0, -0.2, math.radians(45))
    x, y, _, _ = _walk_under_guard(walls, start, goal, 0.3)
    assert math.hypot(goal[0] - x, goal[1] - y) < 0.4
    x, y, _, _ = _walk_under_guard(walls, start, goal, 0.3, with_toward=False)
    assert math.hypot(goal[0] - x, goal[1] - y) > 2.0


def test_a_route_turn_wedged_in_edges_out_and_gets_away() -> None:
    """Rooms 37: backed up to within 0.28 m of a wall, with furniture at the front-left corner. No turn
    keeps the margin (the tail swings into the wall), nor 0.3 m straight on or back; the guard held the
    route's left turn at zero for 65 s. It edges out along a short forward arc and then walks the
    route's way, each step applied only as the guard would. Without the edge-out it stands for ever."""
    ys = np.linspace(-1.0, 1.0, 101)
    wall = np.c_[np.full_like(ys, -P.half_length - 0.283), ys]  # behind, inside the guard's margin
    front = np.array([[0.51, 0.43], [0.54, 0.42], [0.57, 0.416], [0.61, 0.41], [0.64, 0.40], [0.73, 0.39],
                      [0.79, 0.384], [0.507, 0.457], [0.527, 0.509], [0.536, 0.595], [0.551, 0.706]])  # fmt: skip
    world = np.vstack([wall, front])
    assert unstick(0.0, W, world, P) is None  # a search's turn in place: held, as before
    out = unstick(0.0, W, world, P, walk=BACK_SPEED)
    assert out is not None and out.vx == BACK_SPEED and out.wz == -BACK_TURN and "edging out" in out.note
    goal = (0.0, 2.5)  # the way on: left, past the furniture
    x, y, yaw, _ = _walk_under_guard(world, (0.0, 0.0, 0.0), goal, 0.3)
    assert math.hypot(goal[0] - x, goal[1] - y) < 0.4, (x, y, yaw)


def test_a_narrow_doorway_is_walked_through_slowly_and_a_gap_too_narrow_is_not() -> None:
    """A pocket whose way out, 0.6 m ahead, is a doorway, the robot a few centimetres off its middle.
    With the clearance rule (a creep keeps 0.16 m, 0.4 m/s 0.26 m) a 0.8 m doorway straight ahead is
    walked through slower, not steered away from; with the goal off to one side the doorway is the way
    taken, at a creep; a 0.45 m gap is no way (it turns away in place)."""
    rule = PlannerParams()
    off = 0.04  # the robot stands this far right of the gap's middle

    def pocket(gap: float) -> np.ndarray:
        half = gap / 2
        xs, back = np.arange(0.6, 1.2, 0.01), np.arange(-1.0, 0.6, 0.01)
        side = np.linspace(half, 0.9, 30)
        walls = np.vstack([np.c_[xs, np.full_like(xs, half)], np.c_[xs, np.full_like(xs, -half)],
                           np.c_[np.full(30, 0.6), side], np.c_[np.full(30, 0.6), -side],
                           np.c_[back, np.full_like(back, 0.9)], np.c_[back, np.full_like(back, -0.9)]])  # fmt: skip
        return walls + (0.0, off)

    door = pocket(0.8)
    ahead = steer(0.4, 0.0, 0.4, 0.0, 3.0, door, rule, max_angular=W)
    assert not ahead.blocked and 0.0 < ahead.vx < 0.4 and "slowed" in ahead.note, ahead
    assert corridor_free(door, 0.0, rule, rule.clearance.at(ahead.vx)) >= rule.lookahead
    aside = steer(0.4, 0.0, 0.4, math.radians(25), 3.0, door, rule, max_angular=W)
    assert aside.blocked and 0.0 < aside.vx <= rule.creep_mps and abs(aside.heading) < math.radians(10), aside
    narrow = steer(0.4, 0.0, 0.4, 0.0, 3.0, pocket(0.45), rule, max_angular=W)
    assert narrow.blocked and narrow.vx == 0.0 and abs(narrow.heading) > math.radians(45), narrow  # not into it


def test_keeps_near_the_way_it_chose_while_that_stays_free() -> None:
    """Rooms 28: a way just right of the goal and one 95 deg left were free in turn as it turned, and
    it swung between them on the spot for two minutes. Near the way chosen last (KEEP_WINDOW) wins
    while it is free; with that way blocked the nearest free way is taken as before."""
    from go2vlm.behavior.planner.local import KEEP_WINDOW

    wall = np.array([[1.5, y] for y in np.linspace(-0.2, 3.0, 65)])  # ahead and to the left; open right
    first = steer(0.0, 0.0, 0.4, 0.0, 3.5, wall, P, max_angular=W)
    assert first.blocked and first.heading < 0  # the nearest free way: round the wall's right end
    kept = steer(0.0, 0.0, 0.4, 0.0, 3.5, wall, P, max_angular=W, keep=math.radians(95))
    assert kept.blocked and abs(kept.heading - math.radians(95)) <= KEEP_WINDOW + 1e-9
    left_shut = np.vstack([wall, [[x, 0.8] for x in np.linspace(-1.5, 1.5, 61)]])
    again = steer(0.0, 0.0, 0.4, 0.0, 3.5, left_shut, P, max_angular=W, keep=math.radians(95))
    assert again.blocked and again.heading < 0


def test_wedged_between_a_wall_and_a_table_it_backs_out_along_the_gap() -> None:
    """Rooms 1 at 1871f77 rocked forward and back for 25 s between the living room's wall and the
    coffee table, its route's way on behind it. Here the two are 1.2 m apart, the robot askew between
    them: backing with the rear turned fully onto the way on does not keep the margin, and it rocked
    (about 1200 changes of direction a minute). A gentler turn, or none, while backing is tried too:
    it backs out along the gap and walks on, each step applied only as the guard would."""
    xs = np.arange(-4.0, 4.0, 0.02)
    table = np.arange(-2.0, 0.8, 0.02)
    world = np.vstack([np.c_[xs, np.full_like(xs, -0.6)], np.c_[table, np.full_like(table, 0.6)]])
    goal = (3.0, 0.8)
    x, y, yaw, flips = _walk_under_guard(world, (0.0, 0.0, 2.3), goal, 0.77)
    assert math.hypot(goal[0] - x, goal[1] - y) < 0.4, (x, y, yaw, flips)
    assert flips < 10
