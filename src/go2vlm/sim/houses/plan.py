"""A house's floor plan: rooms cut from one rectangle, walls, doors between them, room types.

The rectangle (its area drawn from the number of rooms) is cut in two, again and again (a binary
space partition), until it holds the asked number of rooms, each 2.5 to 6 m a side inside its walls.
Every cut is a wall 0.1 m thick on the cut line. Two rooms that share enough of a wall may get a door;
the doors are a spanning tree of the rooms (every room reachable), sometimes with one door more, so
that some pair of rooms joins only through a third. Clear widths are drawn from what homes have
(0.75 to 1.0 m). Room types follow size and place: the most connected room of a big house is the hall,
the largest the living room, the smallest the bathroom (a dead end where one is).

Pure: numbers in, dataclasses out. Units: metres, radians; the house's south-west corner at (0, 0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from go2vlm.errors import ConfigError

__all__ = [
    "DOOR_WIDTHS",
    "MAX_ROOMS",
    "MAX_SIDE",
    "MIN_ROOMS",
    "MIN_SIDE",
    "WALL",
    "Door",
    "door_path",
    "House",
    "HouseError",
    "Item",
    "Part",
    "Piece",
    "Rect",
    "Room",
    "Wall",
    "make_plan",
]

MIN_ROOMS, MAX_ROOMS = 3, 7
MIN_SIDE, MAX_SIDE = 2.5, 6.0  # a room's side inside its walls
WALL = 0.1  # wall thickness
WALL_HEIGHT = 1.2  # as the hand-made worlds: high enough for the head camera, low enough to see a plan
DOOR_WIDTHS = (0.75, 0.8, 0.85, 0.9, 1.0)  # clear widths of interior doors in homes
DOOR_WEIGHTS = (0.15, 0.3, 0.25, 0.2, 0.1)
DOOR_END_GAP = 0.3  # a door's frame to the nearest corner or T-junction
EXTRA_DOOR_P = 0.3  # a door more than the spanning tree needs (a loop), houses of 4 rooms or more


class HouseError(ConfigError):
    """A house that cannot be made as asked (too many rooms, an object no room holds, a seed out of range,
    no seed that passes the check): a ValueError, and exit 2 on the command line."""


@dataclass(frozen=True)
class Rect:
    x0: float
    y0: float
    x1: float
    y1: float

    @property
    def w(self) -> float:
        return self.x1 - self.x0

    @property
    def h(self) -> float:
        return self.y1 - self.y0

    @property
    def cx(self) -> float:
        return (self.x0 + self.x1) / 2

    @property
    def cy(self) -> float:
        return (self.y0 + self.y1) / 2

    def shrunk(self, d: float) -> Rect:
        return Rect(self.x0 + d, self.y0 + d, self.x1 - d, self.y1 - d)

    def contains(self, x: float, y: float) -> bool:
        return self.x0 <= x <= self.x1 and self.y0 <= y <= self.y1


@dataclass
class Room:
    name: str  # its type, numbered from the second of a type: kitchen, bedroom, bedroom_2 ...
    kind: str  # kitchen | living | bedroom | bathroom | hall | study
    cell: Rect  # between wall centre lines
    spawn: tuple[float, float, float] = (0.0, 0.0, 0.0)  # x, y, yaw: a clear pose (set by the generator)

    @property
    def floor(self) -> Rect:
        """The floor inside the walls (the `rooms` metadata)."""
        return self.cell.shrunk(WALL / 2)


@dataclass(frozen=True)
class Door:
    a: str  # the rooms it joins
    b: str
    x: float  # the centre of the opening
    y: float
    width: float  # clear width
    along_x: bool  # the wall runs along x (the door is crossed along y)

    def opening(self) -> Rect:
        """The opening in the wall (wall thickness deep)."""
        hw, ht = self.width / 2, WALL / 2
        if self.along_x:
            return Rect(self.x - hw, self.y - ht, self.x + hw, self.y + ht)
        return Rect(self.x - ht, self.y - hw, self.x + ht, self.y + hw)


@dataclass(frozen=True)
class Wall:
    """A wall's box: centre, half sizes (axis aligned), as MuJoCo writes a box."""

    x: float
    y: float
    hx: float
    hy: float


@dataclass(frozen=True)
class Part:
    """One box of a piece of furniture, in the piece's frame (pos = centre, half sizes)."""

    pos: tuple[float, float, float]
    half: tuple[float, float, float]
    rgba: tuple[float, float, float, float]


@dataclass(frozen=True)
class Piece:
    """A piece of furniture: a named body of boxes. Its first part spans its whole footprint
    (`world_footprints` reads a body's first geom)."""

    name: str
    kind: str  # bed, counter, fridge, sofa, coffee_table, ...
    room: str
    x: float
    y: float
    yaw: float  # a multiple of pi/2
    hx: float  # footprint half sizes in its own frame
    hy: float
    height: float
    parts: tuple[Part, ...]
    opaque: bool = True  # False: on legs, the camera sees under it

    def box(self) -> Rect:
        """The footprint in the world frame (axis aligned: the yaw is a multiple of pi/2)."""
        turned = round(self.yaw / (math.pi / 2)) % 2 == 1
        hx, hy = (self.hy, self.hx) if turned else (self.hx, self.hy)
        return Rect(self.x - hx, self.y - hy, self.x + hx, self.y + hy)


@dataclass(frozen=True)
class Item:
    """A household object (a mesh), on the floor."""

    name: str  # the body name: its label (teddy_bear, mug, ...)
    room: str
    x: float  # the body's origin
    y: float
    yaw: float
    radius: float  # the circle around its footprint, centred on (cx, cy)
    cx: float
    cy: float
    near: str  # the piece it was put by ('' when none)


@dataclass
class House:
    seed: int
    outline: Rect
    rooms: list[Room]
    doors: list[Door]
    walls: list[Wall]
    pieces: list[Piece] = field(default_factory=list)
    items: list[Item] = field(default_factory=list)

    def room(self, name: str) -> Room:
        return next(r for r in self.rooms if r.name == name)

    def room_at(self, x: float, y: float) -> Room | None:
        return next((r for r in self.rooms if r.floor.contains(x, y)), None)

    def door_path(self, a: str, b: str) -> list[Door]:
        return door_path(self.doors, a, b)


def door_path(doors: Sequence[Door], a: str, b: str) -> list[Door]:
    """The doors on the way from room a to room b through the fewest doors (breadth first; among
    equals, the way whose narrowest door is widest). HouseError when no way joins them."""
    best: dict[str, tuple[int, float, list[Door]]] = {a: (0, math.inf, [])}
    frontier = [a]
    while frontier:
        nxt: list[str] = []
        for r in frontier:
            n, narrow, path = best[r]
            for d in doors:
                if r not in (d.a, d.b):
                    continue
                other = d.b if d.a == r else d.a
                cand = (n + 1, min(narrow, d.width), [*path, d])
                old = best.get(other)
                if old is None:
                    nxt.append(other)
                if old is None or (cand[0] == old[0] and cand[1] > old[1]):
                    best[other] = cand
        frontier = nxt
    if b not in best:
        raise HouseError(f"no way from {a} to {b}")
    return best[b][2]


def _split(rect: Rect, k: int, rng: np.random.Generator, cuts: list[tuple[Rect, float, bool]]) -> list[Rect]:
    """Cut `rect` into k cells; each cut is recorded as (rect, position, along_x)."""
    if k == 1:
        return [rect]
    k1 = int(rng.integers(1, k))
    along_x = rect.h > rect.w if abs(rect.h - rect.w) > 0.5 else bool(rng.integers(2))  # cut the long side
    size = rect.h if along_x else rect.w
    t = size * (k1 / k) * float(rng.uniform(0.85, 1.15))
    if along_x:
        pos = rect.y0 + t
        a, b = Rect(rect.x0, rect.y0, rect.x1, pos), Rect(rect.x0, pos, rect.x1, rect.y1)
    else:
        pos = rect.x0 + t
        a, b = Rect(rect.x0, rect.y0, pos, rect.y1), Rect(pos, rect.y0, rect.x1, rect.y1)
    cuts.append((rect, pos, along_x))
    return _split(a, k1, rng, cuts) + _split(b, k - k1, rng, cuts)


def _fits(cell: Rect) -> bool:
    lo, hi = MIN_SIDE + WALL, MAX_SIDE + WALL
    return lo <= cell.w <= hi and lo <= cell.h <= hi


def _shared(a: Rect, b: Rect) -> tuple[float, float, float, bool] | None:
    """The wall two cells share: (fixed coordinate, lo, hi, along_x), or None."""
    eps = 1e-6
    if abs(a.x1 - b.x0) < eps or abs(b.x1 - a.x0) < eps:
        lo, hi = max(a.y0, b.y0), min(a.y1, b.y1)
        return (a.x1 if abs(a.x1 - b.x0) < eps else a.x0), lo, hi, False
    if abs(a.y1 - b.y0) < eps or abs(b.y1 - a.y0) < eps:
        lo, hi = max(a.x0, b.x0), min(a.x1, b.x1)
        return (a.y1 if abs(a.y1 - b.y0) < eps else a.y0), lo, hi, True
    return None


def _r(v: float) -> float:
    return round(float(v), 3)


def make_plan(seed: int, n_rooms: int, rng: np.random.Generator) -> House:
    """Rooms, doors, walls and room types of a house of `n_rooms` rooms."""
    if not MIN_ROOMS <= n_rooms <= MAX_ROOMS:
        raise HouseError(f"{n_rooms} rooms do not fit: a house has {MIN_ROOMS} to {MAX_ROOMS} rooms")
    for _ in range(400):
        area = float(sum(rng.uniform(9.0, 22.0) for _ in range(n_rooms)))
        aspect = float(rng.uniform(0.7, 1.5))
        w = math.sqrt(area * aspect)
        outline = Rect(0.0, 0.0, _r(w), _r(area / w))
        cuts: list[tuple[Rect, float, bool]] = []
        cells = _split(outline, n_rooms, rng, cuts)
        cells = [Rect(_r(c.x0), _r(c.y0), _r(c.x1), _r(c.y1)) for c in cells]
        if all(_fits(c) for c in cells):
            break
    else:
        raise HouseError(f"no plan of {n_rooms} rooms of {MIN_SIDE:g} to {MAX_SIDE:g} m found")
    # Walls that can take a door: pairs of cells with enough wall in common for the widest door.
    pairs: list[tuple[int, int, float, float, float, bool]] = []
    for i in range(len(cells)):
        for j in range(i + 1, len(cells)):
            s = _shared(cells[i], cells[j])
            if s is not None and s[2] - s[1] >= max(DOOR_WIDTHS) + 2 * DOOR_END_GAP:
                pairs.append((i, j, *s))
    degree = [sum(1 for p in pairs if k in p[:2]) for k in range(len(cells))]
    # A spanning tree grown from the best-connected cell, picking among the walls on its edge at random.
    start = int(np.argmax(degree))
    joined, chosen = {start}, []
    while len(joined) < len(cells):
        edge = [p for p in pairs if (p[0] in joined) != (p[1] in joined)]
        if not edge:
            raise HouseError("a room shares no wall long enough for a door")
        chosen.append(edge[int(rng.integers(len(edge)))])
        joined |= set(chosen[-1][:2])
    rest = [p for p in pairs if p not in chosen]
    if n_rooms >= 4 and rest and rng.uniform() < EXTRA_DOOR_P:
        chosen.append(rest[int(rng.integers(len(rest)))])
    door_degree = [sum(1 for p in chosen if k in p[:2]) for k in range(len(cells))]
    kinds = _room_kinds(cells, door_degree, rng)
    names = _names(kinds)
    rooms = [Room(names[k], kinds[k], cells[k]) for k in range(len(cells))]
    doors = []
    for i, j, fixed, lo, hi, along_x in chosen:
        width = float(rng.choice(DOOR_WIDTHS, p=DOOR_WEIGHTS))
        c = float(rng.uniform(lo + width / 2 + DOOR_END_GAP, hi - width / 2 - DOOR_END_GAP))
        x, y = (c, fixed) if along_x else (fixed, c)
        doors.append(Door(names[i], names[j], _r(x), _r(y), width, along_x))
    walls = _walls(outline, cuts, doors)
    return House(seed, outline, rooms, doors, walls)


def _room_kinds(cells: list[Rect], degree: list[int], rng: np.random.Generator) -> list[str]:
    """Room types by size and place (module docstring)."""
    n = len(cells)
    area = [c.w * c.h for c in cells]
    kinds: list[str | None] = [None] * n
    free = set(range(n))
    if n >= 5:  # the most connected room is the hall
        k = max(free, key=lambda i: (degree[i], -area[i]))
        kinds[k] = "hall"
        free.discard(k)
    k = max(free, key=lambda i: area[i])
    kinds[k] = "living"
    free.discard(k)
    if n >= 4:  # the smallest dead end (or the smallest room) is the bathroom
        ends = [i for i in free if degree[i] == 1] or list(free)
        k = min(ends, key=lambda i: area[i])
        kinds[k] = "bathroom"
        free.discard(k)
    extra = ["study", "bedroom"]
    rng.shuffle(extra)
    want = ["kitchen", "bedroom", *extra, "bedroom"]
    for k, kind in zip(sorted(free, key=lambda i: -area[i]), want, strict=False):
        kinds[k] = kind
    return [k or "study" for k in kinds]


def _names(kinds: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for kind in kinds:
        seen[kind] = seen.get(kind, 0) + 1
        out.append(kind if seen[kind] == 1 else f"{kind}_{seen[kind]}")
    return out


def _walls(outline: Rect, cuts: list[tuple[Rect, float, bool]], doors: list[Door]) -> list[Wall]:
    """Wall boxes: the outline's four sides and every cut, each less its doors' openings."""
    t = WALL / 2
    lines: list[tuple[float, float, float, bool]] = [  # fixed coordinate, lo, hi, along_x
        (outline.y0, outline.x0 - t, outline.x1 + t, True),
        (outline.y1, outline.x0 - t, outline.x1 + t, True),
        (outline.x0, outline.y0 + t, outline.y1 - t, False),
        (outline.x1, outline.y0 + t, outline.y1 - t, False),
    ]
    for rect, pos, along_x in cuts:  # a cut runs between the walls it meets
        lo, hi = (rect.x0, rect.x1) if along_x else (rect.y0, rect.y1)
        lines.append((_r(pos), lo + t, hi - t, along_x))
    out = []
    for fixed, lo, hi, along_x in lines:
        gaps = sorted(
            (d.x if along_x else d.y, d.width)
            for d in doors
            if d.along_x == along_x
            and abs((d.y if along_x else d.x) - fixed) < 1e-6
            and lo < (d.x if along_x else d.y) < hi
        )
        start = lo
        for c, width in [*gaps, (hi + 1.0, 0.0)]:
            end = min(c - width / 2, hi)
            if end - start > 1e-3:
                mid, half = (start + end) / 2, (end - start) / 2
                out.append(Wall(_r(mid), _r(fixed), _r(half), t) if along_x else Wall(_r(fixed), _r(mid), t, _r(half)))
            start = c + width / 2
    return out
