"""The check a house passes before use, on a floor grid (GRID_M cells):

- every door is wider than the robot plus the planners' clearance at a creep on each side (2 x PASSAGE);
- nothing overlaps: no piece of furniture or object overlaps a wall, another piece or another object;
- every room is reachable by the Go2's footprint as the navigator plans it: the robot turns in place and
  crosses a gap square-on, so its centre may be where the clearance exceeds the half width (0.155 m)
  plus CHECK_GAP_M (0.16 m, at least the gap the planners keep at a creep, geometry/footprint.Clearance,
  0.11 m: the houses are as roomy as when that gap was 0.16 m, and the suite's figures stay comparable):
  0.63 m between two obstacles; every room's spawn is one connected floor with every other's; the spawn itself
  clears the whole footprint at any heading;
- every object is reachable (a reachable cell within REACH_M of its footprint) and visible from
  somewhere (a reachable cell within SIGHT_M with a line of sight to it past walls and solid furniture;
  tables and chairs on legs do not hide what is behind them).

`spawns` picks each room's spawn (the clearest reachable cell, facing the room's middle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from go2vlm.robot_profile.go2 import SIM
from go2vlm.sim.houses.furniture import overlaps
from go2vlm.sim.houses.plan import House, Rect

__all__ = [
    "CHECK_GAP_M", "GRID_M", "MARGIN_M", "Floor", "check_house", "floor_grid", "hidden_items", "spawns",
    "unreachable_rooms",
]  # fmt: skip

GRID_M = 0.05
MARGIN_M = 0.05  # beyond the footprint's circle (spawns)
REACH_M = 0.8  # the commander's stop distance: how close a go-to comes
SIGHT_M = 4.0
INSCRIBED = SIM.footprint_width / 2
CIRCUMSCRIBED = math.hypot(SIM.footprint_length / 2, SIM.footprint_width / 2)
CHECK_GAP_M = 0.16  # kept round the footprint by the check: >= Clearance().creep (a test holds it)
PASSAGE = INSCRIBED + CHECK_GAP_M  # the centre's clearance where the check lets it stand


@dataclass
class Floor:
    """The house on a grid: what blocks the robot, what blocks the view, the clearance of each cell."""

    x0: float
    y0: float
    blocked: np.ndarray  # (ny, nx) bool
    opaque: np.ndarray
    clearance: np.ndarray  # metres to the nearest blocked cell
    reach: np.ndarray  # int labels of connected cells the robot's centre may be on (0: none)

    def cell(self, x: float, y: float) -> tuple[int, int]:
        return int((y - self.y0) / GRID_M), int((x - self.x0) / GRID_M)

    def xy(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.x0 + (j + 0.5) * GRID_M, self.y0 + (i + 0.5) * GRID_M

    def sees(self, ax: float, ay: float, bx: float, by: float, skip_m: float) -> bool:
        """A line of sight from a to b, its last `skip_m` (the object's own footprint) not counted."""
        n = max(2, int(math.hypot(bx - ax, by - ay) / (GRID_M / 2)))
        t = np.linspace(0.0, 1.0, n)
        keep = (1 - t) * math.hypot(bx - ax, by - ay) > skip_m
        i = ((ay + t[keep] * (by - ay) - self.y0) / GRID_M).astype(int)
        j = ((ax + t[keep] * (bx - ax) - self.x0) / GRID_M).astype(int)
        return not bool(self.opaque[i, j].any())


def _fill(mask: np.ndarray, x0: float, y0: float, r: Rect) -> None:
    i0, i1 = int(math.floor((r.y0 - y0) / GRID_M)), int(math.ceil((r.y1 - y0) / GRID_M))
    j0, j1 = int(math.floor((r.x0 - x0) / GRID_M)), int(math.ceil((r.x1 - x0) / GRID_M))
    mask[max(i0, 0) : max(i1, 0), max(j0, 0) : max(j1, 0)] = True


def floor_grid(house: House) -> Floor:
    o = house.outline
    x0, y0 = o.x0 - 0.5, o.y0 - 0.5
    nx, ny = int(math.ceil((o.w + 1.0) / GRID_M)), int(math.ceil((o.h + 1.0) / GRID_M))
    blocked = np.zeros((ny, nx), dtype=bool)
    opaque = np.zeros((ny, nx), dtype=bool)
    outside = np.ones((ny, nx), dtype=bool)
    _fill(outside, x0, y0, o)
    outside = ~outside  # past the outer walls: not floor
    for w in house.walls:
        _fill(blocked, x0, y0, Rect(w.x - w.hx, w.y - w.hy, w.x + w.hx, w.y + w.hy))
    opaque |= blocked
    for p in house.pieces:
        _fill(blocked, x0, y0, p.box())
        if p.opaque:
            _fill(opaque, x0, y0, p.box())
    for it in house.items:
        _fill(blocked, x0, y0, Rect(it.cx - it.radius, it.cy - it.radius, it.cx + it.radius, it.cy + it.radius))
    clearance = ndimage.distance_transform_edt(~(blocked | outside)) * GRID_M
    reach, _ = ndimage.label(clearance > PASSAGE)
    return Floor(x0, y0, blocked, opaque, clearance, reach)


def spawns(house: House, floor: Floor) -> None:
    """Each room's spawn: on the floor most of the house's rooms share, where the whole footprint
    clears everything at any heading, as clear as can be (capped at 1 m), nearest the room's middle;
    facing the middle."""
    labels = []
    for room in house.rooms:
        f = room.floor
        (i0, j0), (i1, j1) = floor.cell(f.x0, f.y0), floor.cell(f.x1, f.y1)
        lab = floor.reach[i0:i1, j0:j1]
        labels.extend(lab[lab > 0].tolist())
    main = int(np.bincount(labels).argmax()) if labels else 0
    for room in house.rooms:
        f = room.floor
        (i0, j0), (i1, j1) = floor.cell(f.x0, f.y0), floor.cell(f.x1, f.y1)
        clear = floor.clearance[i0:i1, j0:j1]
        ok = (floor.reach[i0:i1, j0:j1] == main) & (clear > CIRCUMSCRIBED + MARGIN_M)
        if not ok.any():
            room.spawn = (round(f.cx, 3), round(f.cy, 3), 0.0)  # the check says this room is not reachable
            continue
        ii, jj = np.nonzero(ok)
        x, y = floor.xy(ii + i0, jj + j0)
        score = np.minimum(clear[ii, jj], 1.0) - 0.05 * np.hypot(x - f.cx, y - f.cy)
        k = int(np.argmax(score))
        sx, sy = float(x[k]), float(y[k])
        yaw = math.atan2(f.cy - sy, f.cx - sx) if math.hypot(f.cx - sx, f.cy - sy) > 0.3 else 0.0
        room.spawn = (round(sx, 3), round(sy, 3), round(yaw, 3))


def check_house(house: House, floor: Floor | None = None) -> list[str]:
    """What is wrong with a house (module docstring); empty when it passes."""
    floor = floor or floor_grid(house)
    problems: list[str] = []
    need = 2 * PASSAGE
    for door in house.doors:
        if door.width < need:
            problems.append(f"the door between {door.a} and {door.b} is {door.width:.2f} m wide, under {need:.2f} m")
    walls = [Rect(w.x - w.hx, w.y - w.hy, w.x + w.hx, w.y + w.hy) for w in house.walls]
    boxes = [(p.name, p.box()) for p in house.pieces]
    boxes += [
        (it.name, Rect(it.cx - it.radius, it.cy - it.radius, it.cx + it.radius, it.cy + it.radius))
        for it in house.items
    ]
    for k, (name, b) in enumerate(boxes):
        if any(overlaps(b.shrunk(1e-3), w) for w in walls):
            problems.append(f"{name} overlaps a wall")
        for other, c in boxes[k + 1 :]:
            if overlaps(b.shrunk(1e-3), c.shrunk(1e-3)):
                problems.append(f"{name} overlaps {other}")
    lost, main = unreachable_rooms(house, floor)
    for room in house.rooms:
        i, j = floor.cell(room.spawn[0], room.spawn[1])
        if room.name in lost:
            problems.append(f"room {room.name} is not reachable by the robot")
        elif floor.clearance[i, j] <= CIRCUMSCRIBED:
            problems.append(f"the spawn in {room.name} does not clear the robot")
    if main == 0:
        return problems
    return problems + list(hidden_items(house, floor, main).values())


def unreachable_rooms(house: House, floor: Floor) -> tuple[list[str], int]:
    """The rooms whose spawn is not on the floor most rooms' spawns share, and that floor's label."""
    home = [int(floor.reach[floor.cell(r.spawn[0], r.spawn[1])]) for r in house.rooms]
    main = max(set(home), key=home.count) if home else 0
    return [r.name for r, lab in zip(house.rooms, home, strict=True) if lab == 0 or lab != main], main


def hidden_items(house: House, floor: Floor, main: int | None = None) -> dict[str, str]:
    """Object name -> why the robot cannot reach or see it, from the floor most rooms share."""
    if main is None:
        main = unreachable_rooms(house, floor)[1]
    ii, jj = np.nonzero(floor.reach == main)
    xs, ys = floor.xy(ii, jj)
    out: dict[str, str] = {}
    for it in house.items:
        d = np.hypot(xs - it.cx, ys - it.cy) - it.radius
        if not (d <= REACH_M).any():
            out[it.name] = f"the {it.name} is not reachable"
            continue
        near = np.nonzero(d <= SIGHT_M)[0]
        order = near[np.argsort(d[near])][:: max(1, len(near) // 300)]
        if not any(floor.sees(float(xs[k]), float(ys[k]), it.cx, it.cy, it.radius) for k in order):
            out[it.name] = f"the {it.name} is not visible from anywhere the robot can stand"
    return out
