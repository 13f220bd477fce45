"""Furniture that says what a room is: a bed in a bedroom, a counter and a fridge in a kitchen, a sofa
and a coffee table in a living room; tables and desks on legs with their chairs, low shelves.

Each piece is a few boxes (cheap to render), its back against a wall or, for the tables that stand
free, with room to walk round them; none stands in front of a door. A piece's frame: +y is its front
(into the room), its back at -hy. A required piece that finds no place fails the house (the generator
then takes the next seed).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from dataclasses import replace

import numpy as np

from go2vlm.sim.houses.plan import Door, House, HouseError, Part, Piece, Rect, Room

__all__ = ["DOOR_CLEAR", "PASSAGE", "door_zones", "furnish", "overlaps"]

DOOR_CLEAR = 0.9  # kept free in front of a door, on both sides
PASSAGE = 0.65  # around a table that stands free: room for the robot to pass
TRIES = 60

WOOD = (0.45, 0.32, 0.2, 1.0)
DARK_WOOD = (0.36, 0.25, 0.17, 1.0)
WHITE = (0.92, 0.92, 0.9, 1.0)
STEEL = (0.8, 0.8, 0.82, 1.0)
FABRIC = (0.32, 0.45, 0.55, 1.0)
LINEN = (0.78, 0.76, 0.72, 1.0)
PAINT = (0.6, 0.66, 0.58, 1.0)


def _block(kind: str, w: float, d: float, h: float, rgba: tuple[float, float, float, float]) -> Piece:
    return Piece("", kind, "", 0.0, 0.0, 0.0, w / 2, d / 2, h, (Part((0.0, 0.0, h / 2), (w / 2, d / 2, h / 2), rgba),))


def _legs(w: float, d: float, h: float, top: float, rgba: tuple[float, float, float, float]) -> tuple[Part, ...]:
    lx, ly, lh = w / 2 - 0.04, d / 2 - 0.04, (h - top) / 2
    return tuple(Part((sx * lx, sy * ly, lh), (0.025, 0.025, lh), rgba) for sx in (-1, 1) for sy in (-1, 1))


def _table(kind: str, w: float, d: float, h: float, rgba: tuple[float, float, float, float]) -> Piece:
    top = 0.03
    parts = (Part((0.0, 0.0, h - top / 2), (w / 2, d / 2, top / 2), rgba), *_legs(w, d, h, top, DARK_WOOD))
    return Piece("", kind, "", 0.0, 0.0, 0.0, w / 2, d / 2, h, parts, opaque=False)


def _chair() -> Piece:
    w = d = 0.44
    seat = 0.45
    parts = (
        Part((0.0, 0.0, seat - 0.02), (w / 2, d / 2, 0.02), WOOD),
        *_legs(w, d, seat, 0.04, DARK_WOOD),
        Part((0.0, -d / 2 + 0.02, seat + 0.22), (w / 2, 0.02, 0.22), WOOD),
    )
    return Piece("", "chair", "", 0.0, 0.0, 0.0, w / 2, d / 2, seat + 0.44, parts, opaque=False)


def _with_back(
    kind: str, w: float, d: float, h: float, back_h: float, rgba: tuple[float, float, float, float]
) -> Piece:
    """A seat or a bed: the body over the whole footprint, a back (headboard) along its back edge."""
    parts = (
        Part((0.0, 0.0, h / 2), (w / 2, d / 2, h / 2), rgba),
        Part((0.0, -d / 2 + 0.06, back_h / 2), (w / 2, 0.06, back_h / 2), DARK_WOOD if kind == "bed" else rgba),
    )
    return Piece("", kind, "", 0.0, 0.0, 0.0, w / 2, d / 2, back_h, parts)


def _bed(rng: np.random.Generator) -> Piece:
    bed = _with_back("bed", float(rng.choice((0.9, 1.4, 1.6))), 2.0, 0.5, 0.95, LINEN)
    return bed


def _sofa(rng: np.random.Generator) -> Piece:
    return _with_back("sofa", float(rng.uniform(1.6, 2.2)), 0.85, 0.42, 0.8, FABRIC)


def _armchair() -> Piece:
    return _with_back("armchair", 0.8, 0.8, 0.42, 0.8, FABRIC)


def _shelf(rng: np.random.Generator) -> Piece:
    return _block("shelf", float(rng.uniform(0.8, 1.4)), 0.35, float(rng.uniform(0.5, 0.9)), DARK_WOOD)


def _front(yaw: float) -> tuple[float, float]:
    return -math.sin(yaw), math.cos(yaw)


def _at(p: Piece, x: float, y: float, yaw: float, room: Room, name: str) -> Piece:
    return replace(p, x=round(x, 3), y=round(y, 3), yaw=round(yaw, 4), room=room.name, name=name)


def door_zones(doors: list[Door]) -> list[Rect]:
    """The floor kept free in front of each door, both sides, a little wider than the door."""
    out = []
    for d in doors:
        hw = d.width / 2 + 0.15
        if d.along_x:
            out.append(Rect(d.x - hw, d.y - DOOR_CLEAR, d.x + hw, d.y + DOOR_CLEAR))
        else:
            out.append(Rect(d.x - DOOR_CLEAR, d.y - hw, d.x + DOOR_CLEAR, d.y + hw))
    return out


def overlaps(a: Rect, b: Rect, gap: float = 0.0) -> bool:
    return a.x0 < b.x1 + gap and b.x0 < a.x1 + gap and a.y0 < b.y1 + gap and b.y0 < a.y1 + gap


def _inside(r: Rect, floor: Rect) -> bool:
    e = 1e-6
    return r.x0 >= floor.x0 - e and r.y0 >= floor.y0 - e and r.x1 <= floor.x1 + e and r.y1 <= floor.y1 + e


class _Room:
    """Placing pieces in one room: what is there already, what must stay free."""

    def __init__(self, room: Room, house: House, counts: dict[str, int]) -> None:
        self.room = room
        self.floor = room.floor
        self.keep_free = [z for z in door_zones(house.doors) if overlaps(z, self.floor)]
        self.placed: list[tuple[Piece, float]] = []  # piece, the gap others keep from it
        self.counts = counts  # the house's: body names are unique (bed, bed_2, ...)

    def name(self, kind: str) -> str:
        self.counts[kind] = self.counts.get(kind, 0) + 1
        n = self.counts[kind]
        return kind if n == 1 else f"{kind}_{n}"

    def fits(self, group: list[tuple[Piece, float]]) -> bool:
        for p, gap in group:
            box = p.box()
            if not _inside(box, self.floor):
                return False
            if any(overlaps(box, z) for z in self.keep_free):
                return False
            if any(overlaps(box, q.box(), max(gap, qgap)) for q, qgap in self.placed):
                return False
        return True

    def against_wall(self, p: Piece, rng: np.random.Generator) -> tuple[float, float, float]:
        """A pose with the piece's back against one of the room's walls."""
        f = self.floor
        side = int(rng.integers(4))
        yaw = (0.0, math.pi, -math.pi / 2, math.pi / 2)[side]
        along = p.hx  # its half width along the wall
        if side < 2:
            x = float(rng.uniform(f.x0 + along, f.x1 - along))
            y = f.y0 + p.hy if side == 0 else f.y1 - p.hy
        else:
            y = float(rng.uniform(f.y0 + along, f.y1 - along))
            x = f.x0 + p.hy if side == 2 else f.x1 - p.hy
        return x, y, yaw

    def free_standing(self, p: Piece, rng: np.random.Generator) -> tuple[float, float, float]:
        f = self.floor.shrunk(PASSAGE)
        yaw = float(rng.choice((0.0, math.pi / 2)))
        r = max(p.hx, p.hy)
        return (
            float(rng.uniform(f.x0 + r, max(f.x0 + r, f.x1 - r))),
            float(rng.uniform(f.y0 + r, max(f.y0 + r, f.y1 - r))),
            yaw,
        )

    def place(
        self,
        make: Callable[[float, float, float], list[tuple[Piece, float]]],
        pose: Callable[[], tuple[float, float, float]],
        required: bool,
        what: str,
    ) -> list[Piece]:
        for _ in range(TRIES):
            group = make(*pose())
            if self.fits(group):
                self.placed.extend(group)
                return [p for p, _ in group]
        if required:
            raise HouseError(f"no place for the {what} in the {self.room.name}")
        return []


def _single(r: _Room, p: Piece, rng: np.random.Generator, required: bool, gap: float = 0.05) -> list[Piece]:
    name = r.name(p.kind)

    def make(x: float, y: float, yaw: float) -> list[tuple[Piece, float]]:
        return [(_at(p, x, y, yaw, r.room, name), gap)]

    return r.place(make, lambda: r.against_wall(p, rng), required, p.kind)


def _with_chairs(r: _Room, table: Piece, n: int, rng: np.random.Generator, free: bool, required: bool) -> list[Piece]:
    """A table (or desk) and n chairs facing it (one in front of a desk; two across a table)."""
    tname = r.name(table.kind)
    chair = _chair()
    cnames = [r.name("chair") for _ in range(n)]

    def make(x: float, y: float, yaw: float) -> list[tuple[Piece, float]]:
        t = _at(table, x, y, yaw, r.room, tname)
        fx, fy = _front(yaw)
        out = [(t, PASSAGE if free else 0.05)]
        for k, side in enumerate((1.0, -1.0)[:n]):
            off = table.hy + 0.08 + chair.hy
            cyaw = yaw + math.pi if side > 0 else yaw
            c = _at(chair, x + side * fx * off, y + side * fy * off, math.atan2(math.sin(cyaw), math.cos(cyaw)), r.room,
                    cnames[k])  # fmt: skip
            out.append((c, 0.05))
        return out

    pose = (lambda: r.free_standing(table, rng)) if free else (lambda: r.against_wall(table, rng))
    return r.place(make, pose, required, table.kind)


def _sofa_and_table(r: _Room, rng: np.random.Generator) -> list[Piece]:
    sofa = _sofa(rng)
    table = _table("coffee_table", float(rng.uniform(0.9, 1.2)), 0.55, 0.45, WOOD)
    sname, tname = r.name("sofa"), r.name("coffee_table")

    def make(x: float, y: float, yaw: float) -> list[tuple[Piece, float]]:
        fx, fy = _front(yaw)
        off = sofa.hy + 0.45 + table.hy
        return [(_at(sofa, x, y, yaw, r.room, sname), 0.05),
                (_at(table, x + fx * off, y + fy * off, yaw, r.room, tname), 0.45)]  # fmt: skip

    return r.place(make, lambda: r.against_wall(sofa, rng), True, "sofa and coffee table")


def _furnish_room(r: _Room, rng: np.random.Generator) -> list[Piece]:
    kind = r.room.kind
    out: list[Piece] = []
    if kind == "kitchen":
        out += _single(r, _block("counter", float(rng.uniform(1.4, 2.4)), 0.6, 0.9, STEEL), rng, True)
        out += _single(r, _block("fridge", 0.7, 0.7, 1.7, WHITE), rng, True)
        if min(r.floor.w, r.floor.h) >= 3.2 and rng.uniform() < 0.8:
            out += _with_chairs(r, _table("dining_table", float(rng.uniform(1.1, 1.4)), 0.8, 0.75, WOOD), 2, rng, True,
                                False)  # fmt: skip
    elif kind == "living":
        out += _sofa_and_table(r, rng)
        if rng.uniform() < 0.8:
            out += _single(r, _shelf(rng), rng, False)
        if rng.uniform() < 0.4:
            out += _single(r, _armchair(), rng, False)
    elif kind == "bedroom":
        out += _single(r, _bed(rng), rng, True)
        if rng.uniform() < 0.8:
            out += _single(r, _block("nightstand", 0.45, 0.4, 0.5, WOOD), rng, False)
        if rng.uniform() < 0.6:
            out += _single(r, _shelf(rng), rng, False)
    elif kind == "bathroom":
        out += _single(r, _block("bathtub", 1.6, 0.75, 0.55, WHITE), rng, True)
        out += _single(r, _block("sink", 0.6, 0.45, 0.85, WHITE), rng, True)
        if rng.uniform() < 0.9:
            out += _single(r, _block("toilet", 0.4, 0.65, 0.45, WHITE), rng, False)
    elif kind == "study":
        out += _with_chairs(r, _table("desk", float(rng.uniform(1.0, 1.4)), 0.6, 0.75, WOOD), 1, rng, False, True)
        if rng.uniform() < 0.8:
            out += _single(r, _shelf(rng), rng, False)
    elif kind == "hall" and rng.uniform() < 0.8:
        out += _single(r, replace(_shelf(rng), kind="shoe_rack"), rng, False)
    return out


def furnish(house: House, rng: np.random.Generator, rooms: Collection[str] | None = None) -> None:
    """Put each room's furniture in it, or only the named rooms' anew (their pieces taken away first);
    HouseError: a required piece found no place."""
    if rooms is not None:
        house.pieces[:] = [p for p in house.pieces if p.room not in rooms]
    counts: dict[str, int] = {}  # kind -> the highest number its names have (bed, bed_2, ...)
    for p in house.pieces:
        base, _, n = p.name.rpartition("_")
        counts[p.kind] = max(counts.get(p.kind, 0), int(n) if n.isdigit() and base == p.kind else 1)
    for room in house.rooms:
        if rooms is None or room.name in rooms:
            house.pieces.extend(_furnish_room(_Room(room, house, counts), rng))
