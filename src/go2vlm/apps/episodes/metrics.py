"""The one metrics module: a `Recording` (what the recorder heard) + the episode -> numbers.

Everything is judged from the simulator's ground truth (/sim/ground_truth poses, the world's
footprints, /sim/detections boxes), never from what the robot believes.

Per episode (every task):
  success          go to: the commander reported `reached`, the robot ended within
                   `success_distance_m` (1.0 m) of the object's SURFACE (centre distance minus the
                   radius; a box: distance to its footprint), never collided and never fell;
                   look for: `found` and the object inside the camera's field of view at the end;
                   follow: the target was tracked >= 70 % of the time after first contact and the
                   robot stayed within `follow_success_m` (2.5 m) of the ball's surface >= 70 % of
                   that time, without a collision or a fall; stop / sit / stand: the command was
                   carried out.
  spl              go to only: success weighted by path length, S * L / max(P, L), with P the path
                   the base travelled and L the shortest path: the straight-line distance from the
                   start to the object's surface minus the commander's stop distance (0.8 m), at
                   least 0 (a start inside the stop distance counts L/max(P, L) as 1).
  time_to_goal_s   sim seconds from the start to `reached` / `found`.
  path_length_m    the base's path (ground truth at 20 Hz).
  collisions       times the robot's footprint (0.70 x 0.31 m around the base: the Go2's size,
                   its robot profile, robot_profile/go2.py) began to overlap an object's footprint (a mesh's
                   convex hull, as MuJoCo collides it: sim/worlds.py `world_footprints`); min_clearance_m is
                   the smallest gap; collided_with names the bodies. Geometric, so it is the same
                   in kinematic and dynamic physics (and a moving body, such as a world's red
                   ball, that runs into a robot standing still counts too).
  fell             the sim reported a fall.
  estop            the latches of the safety gate's e-stop that held the robot during the run
                   (apps/episodes/latch.py): {latched, latched_s, latched_at_end, latches: [{at_s,
                   for_s, why, released}]}, sim seconds from the start; `stopped` is then true and a
                   goal's result is "stopped", whatever the commander's last state says.
  target_in_view_fraction  ground-truth samples with the target's centre inside the head camera's
                   horizontal field of view (geometric: occlusion is not checked); *_at_end likewise.
Grounding (answers on /vlm/detections, or the oracle's /sim/detections), each answer against the
ground-truth boxes of the frame it describes (same stamp):
  iou              per answer with a box for the goal's object while that object is visible: the
                   best IoU; hit = IoU >= 0.5; wrong_object = a box that misses the target (IoU < 0.5)
                   but covers another object (IoU >= 0.5), or any box for it while it is not visible
                   and another object is; miss = visible but no hit and no wrong object;
                   precision = hits / answers with a box; recall = hits / answers while visible.
  vlm latency      latency_ms (total) of each inference from /vlm/status (wall time: how long the
                   model took); result age: sim seconds from the frame's stamp to the answer.
Tracking (/target/tracked, goal episodes):
  tracking_fraction  frames on which the target_tracker reported the target confirmed (`tracking`);
  carried_fraction   of those, the frames whose box the tracker carried from an answer about an older
                     frame (grounding_age_s > 0) rather than from a fresh answer about this very frame;
  grounding_age_s    p50/p95 of grounding_age_s over the tracking frames;
  forward_unconfirmed  /cmd_vel samples with forward speed > 0.05 m/s although no `tracking` message came
                     in the UNCONFIRMED_GRACE_S before (the commander's lost_timeout_s 1.0 s + the
                     gate's ramp-down) and the object memory did not hold the goal's object confirmed
                     (confidence >= the commander's memory_confirm_confidence on the newest /objects):
                     motion toward a target nothing confirmed (a detour round an obstacle that takes
                     the target out of view counts here too: behavior/mission.py bounds it by
                     detour_memory_s);
  forward_on_memory  of the forward samples, those the memory alone confirmed (the tracker did not).
Memory (/objects, episodes with an object_memory), at the end, against the ground truth:
  objects          every remembered object: label, place, confidence, and the world body of that
                   label nearest to it (apps/episodes/episode.py label_matches) with the error (m): the
                   distance to the body's centre, or for a long body (a wall) to the line its middle
                   runs along (a place anywhere along a wall is on it);
  phantoms         remembered objects with no body of their label within PHANTOM_M (1 m): not there;
  max_error_m      the largest error of the others; `accurate`: how many are within ACCURATE_M (0.3 m).
House (a generated house, `--world house:SEED`; None in other worlds): `house` = the seed asked and
the seed used (a failed seed is replaced by the next), the house's hash, its rooms and their types,
the spawn's room and the target's, and the doors between them on the way through the fewest doors:
how many (`doors`), their clear widths and the narrowest (`narrowest_door_m`; None in the same room).
Map (/map, /map/costmap, /plan; episodes with a map node; None without): `map` = the newest map's
size (resolution_m, width, height cells), free_m2 and occupied_m2, the frontiers left in the newest
costmap, explored_frontiers (those the explorer walked to) and plans (routes heard on /plan). The map
itself goes to series.json (map, frontiers, explored, plans: apps/episodes/navmap.py) and the run
folder (map.npz, map.png).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypedDict

import numpy as np

from go2vlm.apps.episodes.episode import Episode, goal_target, label_matches, target_body
from go2vlm.apps.episodes.latch import estop_metrics
from go2vlm.apps.episodes.navmap import map_summary, nav_series
from go2vlm.apps.episodes.recorder import Recording
from go2vlm.behavior.goals import GoalParseError, parse_target
from go2vlm.behavior.mission import MissionParams
from go2vlm.geometry.footprint import Footprint, clearances, surface_distance
from go2vlm.geometry.rotations import quat_yaw
from go2vlm.msgs.vision_msgs import PixelBox
from go2vlm.robot_profile import profile
from go2vlm.world.labels import label_fits
from go2vlm.world.objects_msg import Remembered

__all__ = ["Context", "box_iou", "compute_metrics", "grounding_metrics", "memory_metrics", "tracker_metrics"]

SUCCESS_STATES = {"go_to": "reached", "look_for": "found"}
END_STATES = ("reached", "found", "not_found", "done", "stopped", "rejected", "sat")
IOU_HIT = 0.5
TRACKED_MIN = 0.7  # follow: tracked at least this fraction of the time after first contact
NEAR_MIN = 0.7  # follow: within follow_success_m at least this fraction of that time
UNCONFIRMED_GRACE_S = 1.5  # commander lost_timeout_s (1.0) + the gate's ramp from 0.4 m/s to 0 (< 0.5 s)
FORWARD_MPS = 0.05  # forward speed that counts as driving toward something
PHANTOM_M = 1.0  # a remembered object farther than this from every body of its label is a phantom
ACCURATE_M = 0.3  # ... and one within this of its body is where it is


@dataclass
class Context:
    """How the episode ran: what the recording alone does not say."""

    episode: Episode
    shapes: dict[str, Footprint]  # the world's footprints at their initial poses
    t0: float  # sim time the run started
    wall_s: float
    rtf: float
    fast: bool
    stop_distance_m: float = MissionParams().stop_distance_m  # the commander's (written once, in its core)


def box_iou(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def _r(v: float | None, n: int = 3) -> float | None:
    return None if v is None or not math.isfinite(v) else round(float(v), n)


def _dedupe(states: list[Any]) -> list[Any]:
    out: list[Any] = []
    for s in states:
        if not out or out[-1] != s:
            out.append(s)
    return out


FLIP_SPEED = 0.05  # m/s: a command slower than this, either way, is neither forward nor back
FLIP_WINDOW_S = 2.0  # a run of forward (or back) shorter than this, between two flips, is rocking


def flips(cmds: Sequence[tuple[float, float]]) -> tuple[int, float]:
    """(how many times /cmd_vel's vx turned from forward to back or back again, the seconds spent in
    runs shorter than FLIP_WINDOW_S between two such turns: rocking) over (t, vx) samples in time
    order; a command under FLIP_SPEED either way keeps the last direction."""
    turns: list[float] = []
    last = 0.0
    for t, vx in cmds:
        d = 1.0 if vx >= FLIP_SPEED else -1.0 if vx <= -FLIP_SPEED else 0.0
        if d and last and d != last:
            turns.append(t)
        last = d or last
    rocking = sum(b - a for a, b in zip(turns[:-1], turns[1:], strict=True) if b - a < FLIP_WINDOW_S)
    return len(turns), round(rocking, 2)


def _reasons(status: Sequence[tuple[float, Mapping[str, object]]]) -> list[list[object]]:
    """[t, state, reason] each time the commander's reason changes (its numbers included: a reason
    that counts down metres is a walk, one that stays is a stall)."""
    out: list[list[object]] = []
    for t, s in status:
        row = [t, s.get("state"), s.get("reason")]
        if not out or out[-1][1:] != row[1:]:
            out.append(row)
    return out


def grounding_metrics(
    answers: list[tuple[float, float, list[PixelBox]]],
    truth: dict[float, list[PixelBox]],
    goal: str | None,
    body: str | None = None,
) -> dict[str, Any] | None:
    """Every answer against the ground truth of its frame (see the module docstring); None without answers.
    `body`: the episode's own target body (a referring goal), the only ground truth of the goal."""
    target = goal_target(goal)
    if not answers or target is None:
        return None

    def is_goal(label: str) -> bool:
        return label == body if body is not None else label_matches(target, label)

    ious: list[float] = []
    hits = misses = wrong = false_pos = answered = visible_n = unscored = 0
    ages: list[float] = []
    for t_recv, stamp, boxes in answers:
        ages.append(t_recv - stamp)
        gt = truth.get(stamp)
        if gt is None:
            unscored += 1  # no ground truth for that frame (scoring off, or the answer's stamp is not a frame's)
            continue
        mine = [b for label, b, _ in boxes if label == body or label_matches(target, label)]
        goal_boxes = [b for label, b, _ in gt if is_goal(label)]
        others = [b for label, b, _ in gt if not is_goal(label)]
        visible = bool(goal_boxes)
        visible_n += visible
        answered += bool(mine)
        best = max((box_iou(p, g) for p in mine for g in goal_boxes), default=0.0)
        on_other = any(box_iou(p, o) >= IOU_HIT for p in mine for o in others)
        if visible and mine:
            ious.append(best)
        if mine and best >= IOU_HIT:
            hits += 1
        elif mine and on_other:
            wrong += 1
        elif mine and not visible:
            false_pos += 1
        elif visible:
            misses += 1
    return {
        "answers": len(answers),
        "scored": len(answers) - unscored,
        "answers_with_box": answered,
        "answers_target_visible": visible_n,
        "hits": hits,
        "misses": misses,
        "wrong_object": wrong,
        "false_positives": false_pos,
        "precision": _r(hits / answered, 4) if answered else None,
        "recall": _r(hits / visible_n, 4) if visible_n else None,
        "iou": [round(v, 4) for v in ious],
        "mean_iou": _r(float(np.mean(ious)), 4) if ious else None,
        "result_age_s_mean": _r(float(np.mean(ages)), 3) if ages else None,
        "result_age_s_p95": _r(float(np.percentile(ages, 95)), 3) if ages else None,
    }


def vlm_latency(status: list[dict[str, Any]]) -> dict[str, Any] | None:
    """latency_ms.total of each inference (one per new `inferences` count on /vlm/status)."""
    seen: set[int] = set()
    lat: list[float] = []
    for st in status:
        n = st.get("inferences")
        total = (st.get("latency_ms") or {}).get("total")
        if isinstance(n, int) and n not in seen and isinstance(total, (int, float)):
            seen.add(n)
            lat.append(float(total))
    if not status:
        return None
    last = status[-1]
    return {
        "model": last.get("model"),
        "backend": last.get("backend"),
        "inferences": last.get("inferences"),
        "latency_ms_mean": _r(float(np.mean(lat)), 1) if lat else None,
        "latency_ms_p50": _r(float(np.percentile(lat, 50)), 1) if lat else None,
        "latency_ms_p95": _r(float(np.percentile(lat, 95)), 1) if lat else None,
        "errors": last.get("errors"),
    }


def tracker_metrics(
    tracked: list[tuple[float, float, str, float]],
    cmds: list[tuple[float, float, float, float]],
    memory_confirmed: list[tuple[float, bool]] | None = None,
) -> dict[str, Any] | None:
    """How the target_tracker carried the target (see the module docstring); None without /target/tracked.
    `memory_confirmed`: (sim t, the newest /objects held the goal's object confirmed), in time order."""
    if not tracked:
        return None
    tracking = [(t, age) for t, _, state, age in tracked if state == "tracking"]
    ages = [age for _, age in tracking if math.isfinite(age)]
    carried = sum(1 for a in ages if a > 1e-6)
    confirmed_at = [t for t, _ in tracking]
    mem = memory_confirmed or []
    unconfirmed = on_memory = 0
    j = k = 0  # confirmed_at, mem and cmds are all in receive order (sim time)
    for t, vx, _, _ in cmds:
        while j < len(confirmed_at) and confirmed_at[j] <= t:
            j += 1
        while k < len(mem) and mem[k][0] <= t:
            k += 1
        if vx <= FORWARD_MPS:
            continue
        tracker_ok = j > 0 and t - confirmed_at[j - 1] <= UNCONFIRMED_GRACE_S
        memory_ok = k > 0 and mem[k - 1][1]
        unconfirmed += not (tracker_ok or memory_ok)
        on_memory += memory_ok and not tracker_ok
    return {
        "frames": len(tracked),
        "tracking_frames": len(tracking),
        "tracking_fraction": _r(len(tracking) / len(tracked), 4),
        "carried_fraction": _r(carried / len(ages), 4) if ages else None,
        "grounding_age_s_p50": _r(float(np.percentile(ages, 50)), 3) if ages else None,
        "grounding_age_s_p95": _r(float(np.percentile(ages, 95)), 3) if ages else None,
        "forward_cmds": sum(1 for c in cmds if c[1] > FORWARD_MPS),
        "forward_unconfirmed": unconfirmed,
        "forward_on_memory": on_memory,
    }


def _body_fits(label: str, body: str) -> bool:
    try:
        return label_matches(parse_target(label), body)
    except GoalParseError:  # free text: the body's own name ("crate_1" is "crate 1")
        return " ".join(body.replace("_", " ").lower().split()) == label


def _on_axis(x: float, y: float, f: Footprint) -> tuple[float, float]:
    """The point of body `f`'s long axis nearest (x, y): its centre for a round or square body; along a
    long one (a wall, a counter) the segment its middle runs on, so that a place anywhere along a wall
    is as right as its distance from the wall."""
    half = max(0.0, abs(f.hx - f.hy)) if f.kind == "rect" else 0.0
    ux, uy = (math.cos(f.yaw), math.sin(f.yaw)) if f.hx >= f.hy else (-math.sin(f.yaw), math.cos(f.yaw))
    t = max(-half, min(half, (x - f.x) * ux + (y - f.y) * uy))
    return f.x + t * ux, f.y + t * uy


def memory_metrics(objects: list[Remembered], bodies: dict[str, Footprint]) -> dict[str, Any]:
    """The memory at the end against the ground truth (see the module docstring)."""
    out: list[dict[str, Any]] = []
    phantoms = 0
    errors: list[float] = []
    for o in objects:
        fits = [
            (math.hypot(o.x - x, o.y - y), name, x, y)
            for name, f in bodies.items()
            if _body_fits(o.label, name)
            for x, y in [_on_axis(o.x, o.y, f)]
        ]
        err, name, tx, ty = min(fits) if fits else (None, None, None, None)
        phantom = err is None or err > PHANTOM_M
        phantoms += phantom
        if err is not None and not phantom:
            errors.append(err)
        out.append({
            "id": o.id, "label": o.label, "x": _r(o.x), "y": _r(o.y), "confidence": _r(o.confidence),
            "body": name, "true_x": _r(tx), "true_y": _r(ty), "error_m": _r(err), "phantom": phantom,
        })  # fmt: skip
    return {
        "objects": out,
        "phantoms": phantoms,
        "accurate": sum(1 for e in errors if e <= ACCURATE_M),
        "max_error_m": _r(max(errors)) if errors else None,
        "mean_error_m": _r(float(np.mean(errors))) if errors else None,
    }


def _rtf(status: list[dict[str, Any]]) -> tuple[float, float]:
    """Achieved real-time factor after the first 2 s of sim time (start-up excluded), and overall."""
    sims = [float(s["sim_time"]) for s in status if "sim_time" in s and "wall_time" in s]
    walls = [float(s["wall_time"]) for s in status if "sim_time" in s and "wall_time" in s]

    def rate(i0: int) -> float:
        dw = walls[-1] - walls[i0] if len(walls) > i0 + 1 else 0.0
        return (sims[-1] - sims[i0]) / dw if dw > 0 else 0.0

    if not sims:
        return 0.0, 0.0
    warm = next((i for i, t in enumerate(sims) if t >= 2.0), 0)
    return (rate(warm) or rate(0)), rate(0)


def _memory_confirmed(rec: Recording, ep: Episode) -> list[tuple[float, bool]]:
    """(sim t, the goal's object confirmed in the memory) for every /objects the recorder heard."""
    target = goal_target(ep.goal)
    if target is None or not rec.memory:
        return []
    commander = ep.params.get("commander", {})
    conf = float(commander.get("memory_confirm_confidence", MissionParams.memory_confirm_confidence))
    return [
        (t, any(o.confidence >= conf and label_fits(target.label, o.label) for o in objs)) for t, objs in rec.memory
    ]


class HouseFacts(TypedDict):
    """An episode's house (module docstring)."""

    asked_seed: int
    seed: int
    hash: str | None
    rooms: list[str]
    room_types: list[str]
    spawn_room: str | None
    target_room: str | None
    doors: int | None
    door_widths_m: list[float]
    narrowest_door_m: float | None


def house_metrics(ep: Episode, target: Footprint | None) -> HouseFacts | None:
    """The house facts of an episode in a generated house (module docstring); None in other worlds."""
    from go2vlm.sim.houses import is_house, parse_house
    from go2vlm.sim.houses.plan import door_path
    from go2vlm.sim.worlds import world_info

    if not is_house(ep.world):
        return None
    info = world_info(ep.world)
    words = info.house.split()
    meta = dict(zip(words[::2], words[1::2], strict=False))
    x, y, _ = ep.spawn if ep.spawn is not None else info.spawn
    start = info.room_of(x, y)
    goal = info.room_of(target.x, target.y) if target is not None else None
    path = door_path(info.doors, start, goal) if start and goal else []
    widths = [d.width for d in path]
    return {
        "asked_seed": parse_house(ep.world)[0],
        "seed": int(meta.get("seed", -1)),
        "hash": meta.get("hash"),
        "rooms": [r.name for r in info.rooms],
        "room_types": sorted({r.name.rstrip("_0123456789") for r in info.rooms}),
        "spawn_room": start,
        "target_room": goal,
        "doors": len(path) if start and goal else None,
        "door_widths_m": widths,
        "narrowest_door_m": min(widths) if widths else None,
    }


def compute_metrics(rec: Recording, ctx: Context) -> tuple[dict[str, Any], dict[str, Any]]:
    """(metrics, series): the episode's numbers and the time series behind its plot."""
    ep = ctx.episode
    kind = ep.kind
    names = sorted({*ctx.shapes, *(n for _, p in rec.poses for n in p if n != "go2")})
    target = target_body(ep.goal, names, ep.target)
    robot_facts = profile(ep.robot)
    hfov = math.radians(robot_facts.head_camera.hfov_deg(ep.camera_width, ep.camera_height))

    # -- geometry over time, from ground truth --------------------------------------------------
    track: list[tuple[float, float, float, float]] = []  # t, x, y, yaw
    target_xy: list[tuple[float, float]] = []
    dists: list[tuple[float, float]] = []  # t, base centre -> target surface
    centre: list[float] = []  # base centre -> target centre
    in_view: list[bool] = []
    min_clear, collisions, colliding = math.inf, 0, False
    collided_with: set[str] = set()
    shape_names = list(ctx.shapes)
    for t, p in rec.poses:
        if "go2" not in p:
            continue
        x, y, _, qw, qx, qy, qz = p["go2"]
        yaw = quat_yaw(qw, qx, qy, qz)
        track.append((t, x, y, yaw))
        robot = Footprint.rect(x, y, yaw, robot_facts.footprint_length, robot_facts.footprint_width)
        worst, worst_name = math.inf, ""
        placed: list[Footprint] = []
        for name, shape in ctx.shapes.items():
            if name in p:
                b = p[name]
                shape = shape.moved(b[0], b[1], quat_yaw(b[3], b[4], b[5], b[6]))
            placed.append(shape)
            if name == target:
                dists.append((t, surface_distance(x, y, shape)))
                centre.append(math.hypot(shape.x - x, shape.y - y))
                target_xy.append((shape.x, shape.y))
                bearing = math.atan2(shape.y - y, shape.x - x) - yaw
                in_view.append(abs(math.atan2(math.sin(bearing), math.cos(bearing))) < hfov / 2)
        if placed:
            gaps = clearances(robot, placed)
            k = int(np.argmin(gaps))
            worst, worst_name = float(gaps[k]), shape_names[k]
        if math.isfinite(worst):
            min_clear = min(min_clear, worst)
        if worst < 0 and not colliding:
            collisions += 1
            collided_with.add(worst_name)
        colliding = worst < 0
    path = sum(math.hypot(b[1] - a[1], b[2] - a[2]) for a, b in zip(track, track[1:], strict=False))

    # -- the commander's story -------------------------------------------------------------------
    status = rec.commander
    states = [s.get("state") for _, s in status]
    first: dict[Any, float] = {}
    for t, s in status:
        first.setdefault(s.get("state"), t)
    success_state = SUCCESS_STATES.get(kind)
    t_goal = first.get(success_state) if success_state else None
    final = status[-1][1] if status else {}
    final_dist = dists[-1][1] if dists else None

    # -- tracking (follow) -------------------------------------------------------------------------
    frames = sorted(set(rec.frames))
    seen_stamps = {t for t, *_ in rec.targets}
    frames_with_target = sum(1 for t in frames if t in seen_stamps)
    if ep.goal is None:  # the article's loop: a frame is tracked when the detector answered for it
        first_seen = min(seen_stamps) if seen_stamps else None
        after = [t for t in frames if first_seen is not None and t >= first_seen]
        tracked = sum(1 for t in after if t in seen_stamps) / len(after) if after else 0.0
    else:  # the commander says whether it sees the target
        seen_t = [t for t, s in status if s.get("seen")]
        first_seen = seen_t[0] if seen_t else None
        after_s = [s for t, s in status if first_seen is not None and t >= first_seen]
        tracked = sum(1 for s in after_s if s.get("seen")) / len(after_s) if after_s else 0.0
    near = [d for t, d in dists if first_seen is not None and t >= first_seen]
    close = sum(1 for d in near if d <= ep.follow_success_m) / len(near) if near else 0.0

    # -- success and SPL -------------------------------------------------------------------------
    fell = bool(rec.fell)
    if kind == "go_to":
        success = bool(
            t_goal is not None
            and final_dist is not None
            and final_dist <= ep.success_distance_m
            and collisions == 0
            and not fell
        )
    elif kind == "look_for":
        success = bool(t_goal is not None and in_view and in_view[-1] and not fell)
    elif kind == "follow":
        success = bool(tracked >= TRACKED_MIN and close >= NEAR_MIN and collisions == 0 and not fell)
    elif kind == "invalid":
        success = False
    else:
        success = states[-1] in ("stopped", "done") if states else False
    spl = shortest = None
    if kind == "go_to" and dists:
        shortest = max(0.0, dists[0][1] - ctx.stop_distance_m)
        spl = float(success) * (shortest / max(path, shortest) if max(path, shortest) > 0 else 1.0)

    rtf, rtf_all = _rtf(rec.status)
    duration = max([rec.sim_time, *(float(s["sim_time"]) for s in rec.status if "sim_time" in s)])
    estop = estop_metrics(rec.estop, ctx.t0, max(rec.sim_time, ctx.t0))
    m: dict[str, Any] = {
        "episode": ep.id or None,
        "kind": kind,
        "world": ep.world,
        "goal": ep.goal,
        "perception": ep.perception if ep.goal is not None else "color_detector",
        "mode": ep.mode,
        "spawn": list(ep.spawn) if ep.spawn is not None else None,
        "seed": ep.seed,
        "target_body": target,
        "success": success,
        "spl": _r(spl, 4),
        "shortest_path_m": _r(shortest),
        "time_to_goal_s": None if t_goal is None else round(t_goal - ctx.t0, 2),
        "path_length_m": round(path, 3),
        "collisions": collisions,
        "collided_with": sorted(collided_with),
        "min_clearance_m": _r(min_clear),
        "fell": fell,
        "estop": estop,
        "stopped": estop["latched"],
        "target_in_view_fraction": _r(sum(in_view) / len(in_view), 4) if in_view else None,
        "target_in_view_at_end": bool(in_view[-1]) if in_view else None,
        "final_distance_m": _r(final_dist),
        "sim_s": round((track[-1][0] - ctx.t0) if track else 0.0, 2),
        "wall_s": round(ctx.wall_s, 2),
        "real_time_factor": round(rtf, 3),
        # The oracle's answers are the ground truth itself (what its commander takes): scored the same way.
        "grounding": grounding_metrics(
            [(t, t, b) for t, b in sorted(rec.truth.items())] if ep.perception == "oracle" else rec.answers,
            rec.truth,
            ep.goal,
            ep.target,
        ),
        "vlm": vlm_latency(rec.vlm_status),
        "tracker": tracker_metrics(rec.tracked, rec.cmds, _memory_confirmed(rec, ep)),
        "memory": None,
    }
    if rec.memory:
        last = rec.poses[-1][1] if rec.poses else {}
        bodies = {n: f.moved(last[n][0], last[n][1]) if n in last else f for n, f in ctx.shapes.items()}
        m["memory"] = memory_metrics(rec.memory[-1][1], bodies)
    m["house"] = house_metrics(ep, ctx.shapes.get(target or ""))
    cmds = rec.cmds
    if ep.goal is None:  # the follow article's loop: `go2vlm demo`'s figures
        ball = np.array(centre)
        span = cmds[-1][0] - cmds[0][0] if len(cmds) >= 2 else 0.0
        x_err = [abs(x) for _, x, _, _ in rec.targets]
        m.update(
            {
                "duration_s": round(duration, 3),
                "real_time_factor_with_startup": round(rtf_all, 3),
                "target_visible_fraction": round(frames_with_target / len(frames), 4) if frames else 0.0,
                "frames": len(frames),
                "frames_with_target": frames_with_target,
                "mean_abs_x_error": round(float(np.mean(x_err)), 4) if x_err else None,
                "min_distance_to_ball_m": _r(ball.min()) if len(ball) else None,
                "mean_distance_to_ball_m": _r(ball.mean()) if len(ball) else None,
                "max_distance_to_ball_m": _r(ball.max()) if len(ball) else None,
                "final_distance_to_ball_m": _r(ball[-1]) if len(ball) else None,
                "robot_distance_travelled_m": round(path, 3),
                "tracked_fraction": round(tracked, 3),
                "within_follow_distance_fraction": round(close, 3),
                "cmd_rate_hz": round((len(cmds) - 1) / span, 2) if span > 0 else 0.0,
                "mean_cmd_vx": round(float(np.mean([c[1] for c in cmds])), 4) if cmds else None,
                "frames_dropped_by_renderer": rec.status[-1].get("frames_dropped") if rec.status else None,
                "robot": ep.robot if ep.transport == "dds" else f"{ep.robot} ({ep.transport})",
                "rtf_target": None if ctx.fast else ctx.rtf,
                "fast": ctx.fast,
                "camera": f"{ep.camera_width}x{ep.camera_height}@{ep.camera_rate_hz:g}Hz",
                "ball_speed_mps": ep.ball_speed,
            }
        )
    else:  # a language goal: `go2vlm demo --goal`'s figures
        m.update(
            {
                "result": "stopped" if estop["latched"] else (states[-1] if states else None),
                "final_state": states[-1] if states else None,
                "final_reason": final.get("reason"),
                "states": _dedupe(states),
                "min_distance_m": _r(min(d for _, d in dists)) if dists else None,
                "robot_distance_travelled_m": round(path, 3),
                "max_abs_cmd_vx": round(max((abs(c[1]) for c in cmds), default=0.0), 3),
                "max_abs_cmd_wz": round(max((abs(c[3]) for c in cmds), default=0.0), 3),
                "max_behavior_vx": round(max((c[1] for c in rec.behavior), default=0.0), 3),
                "final_cmd": [round(cmds[-1][1], 3), round(cmds[-1][3], 3)] if cmds else None,
                "flips": (fl := flips([(c[0], c[1]) for c in cmds]))[0],
                "flip_s": fl[1],
                "commander_counters": final.get("counters", {}),
                "goal_reached": success,
            }
        )
        if kind == "follow":
            m["tracked_fraction"] = round(tracked, 3)
            m["within_follow_distance_fraction"] = round(close, 3)
            m["mean_distance_m"] = _r(sum(near) / len(near)) if near else None
    series = {
        "gt_sim_t": [t for t, *_ in track],
        "robot_xy": [[x, y] for _, x, y, _ in track],
        "robot_yaw": [yaw for *_, yaw in track],
        "target_xy": [list(p) for p in target_xy],
        "distance": [d for _, d in dists] if ep.goal is not None else centre,
        "target_sim_t": [t for t, *_ in rec.targets],
        "target_x": [x for _, x, _, _ in rec.targets],
        "states": [[t, s.get("state")] for t, s in status],
        "reasons": _reasons(status),  # what the commander said, on each change: why a miss ended as it did
        "cmd": [[t, vx, wz] for t, vx, _, wz in cmds],
    }
    if ep.goal is None:
        series["ball_xy"] = series["target_xy"]
    nav = nav_series(rec)  # the map, its frontiers and the routes: the plot's top view
    series.update(nav)
    m["map"] = map_summary(rec, nav)
    return m, series
