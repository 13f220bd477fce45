"""The household objects (the meshes of sim/assets/household that the hand-made worlds use), put where
people keep them: a mug by the kitchen counter or the dining table, a teddy bear by a bed, a rubber
duck by the bath ... and now and then somewhere else (`ELSEWHERE_P`), so that a room's type is a
hint for a search, not an answer. Every house holds each object once, on the floor, its body named
as the object (its ground-truth label, sim/render.py `labelled_bodies`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from go2vlm.sim.houses.furniture import door_zones, overlaps
from go2vlm.sim.houses.plan import House, HouseError, Item, Piece, Rect, Room

__all__ = ["ASSETS", "ELSEWHERE_P", "MESHES", "OBJECTS", "Mesh", "mesh_extent", "place_objects"]

ASSETS = Path(__file__).resolve().parent.parent / "assets" / "household"
ELSEWHERE_P = 0.15  # an object in a room where it does not belong
TRIES = 80  # in the room it belongs in
TRIES_ELSEWHERE = 20  # in each other room, when that one has no place


@dataclass(frozen=True)
class Mesh:
    file: str
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rgba: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    texture: str = ""  # a png beside the mesh


MESHES: dict[str, Mesh] = {
    "teddy_bear": Mesh("teddy_bear.obj", rgba=(0.55, 0.36, 0.2, 1.0)),
    "duck": Mesh("duck.obj", texture="duck.png"),
    "soccer_ball": Mesh("soccer_ball.obj", rgba=(0.7, 0.4, 1.0, 1.0), texture="soccer_ball.png"),
    "mug": Mesh("mug.obj", rgba=(0.9, 0.9, 0.88, 1.0)),
    "lego_brick": Mesh("lego_brick.obj", rgba=(0.95, 0.8, 0.1, 1.0)),
    "tray": Mesh("tray.obj", rgba=(0.45, 0.75, 0.75, 1.0), texture="tray.png"),
    "cone": Mesh("cone.obj", rgba=(1.0, 0.45, 0.05, 1.0)),
    "toy_chest": Mesh("toy_chest.obj", scale=(0.5, 0.34, 0.32), rgba=(0.72, 0.42, 0.18, 1.0)),
}

# object -> (room kind, the piece it is kept by ('' anywhere in the room), weight)
PLACES: dict[str, tuple[tuple[str, str, float], ...]] = {
    "mug": (
        ("kitchen", "counter", 3),
        ("kitchen", "dining_table", 3),
        ("living", "coffee_table", 1),
        ("study", "desk", 1),
    ),
    "teddy_bear": (("bedroom", "bed", 4), ("living", "sofa", 1)),
    "duck": (("bathroom", "bathtub", 4), ("bedroom", "bed", 1)),
    "soccer_ball": (("hall", "", 2), ("bedroom", "", 1), ("living", "", 1)),
    "lego_brick": (("bedroom", "", 2), ("living", "coffee_table", 1), ("study", "", 1)),
    "tray": (("kitchen", "counter", 2), ("living", "coffee_table", 2)),
    "cone": (("hall", "", 1), ("study", "", 1), ("bedroom", "", 1)),
    "toy_chest": (("bedroom", "", 2), ("living", "shelf", 1)),
}
OBJECTS = tuple(MESHES)


@functools.cache
def mesh_extent(name: str) -> tuple[float, float, float]:
    """(cx, cy, radius): the circle round a mesh's floor footprint in its body frame."""
    m = MESHES[name]
    pts = []
    with (ASSETS / m.file).open(encoding="utf-8") as f:
        for line in f:
            if line.startswith("v "):
                pts.append(line.split()[1:3])
    xy = np.asarray(pts, dtype=float) * np.asarray(m.scale[:2])
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    c = (lo + hi) / 2
    return float(c[0]), float(c[1]), float(np.hypot(*(hi - lo)) / 2)


def _choose(name: str, house: House, rng: np.random.Generator) -> tuple[Room, str]:
    """The room (and the piece) for an object: a place where people keep it, or now and then any room."""
    rooms = house.rooms
    places = [(r, piece, w) for kind, piece, w in PLACES[name] for r in rooms if r.kind == kind]
    if not places or rng.uniform() < ELSEWHERE_P:
        return rooms[int(rng.integers(len(rooms)))], ""
    weights = np.asarray([w for *_, w in places], dtype=float)
    r, piece, _ = places[int(rng.choice(len(places), p=weights / weights.sum()))]
    return r, piece


def _near(piece: Piece, rng: np.random.Generator) -> tuple[float, float]:
    """A point on the floor beside a piece: in front of it mostly, or at one of its ends."""
    b = piece.box()
    gap = float(rng.uniform(0.2, 0.55))
    fx, fy = -math.sin(piece.yaw), math.cos(piece.yaw)  # its front
    side = int(rng.integers(4))
    if side <= 1:  # in front, along its front edge
        u = float(rng.uniform(-0.8, 0.8)) * piece.hx
        lx, ly = math.cos(piece.yaw), math.sin(piece.yaw)
        return piece.x + fx * (piece.hy + gap) + lx * u, piece.y + fy * (piece.hy + gap) + ly * u
    if side == 2:
        return float(rng.uniform(b.x0, b.x1)), (b.y0 - gap) if rng.uniform() < 0.5 else (b.y1 + gap)
    return (b.x0 - gap) if rng.uniform() < 0.5 else (b.x1 + gap), float(rng.uniform(b.y0, b.y1))


def _free(house: House, room: Room, cx: float, cy: float, r: float, zones: list[Rect]) -> bool:
    f = room.floor.shrunk(0.1)
    if not (f.x0 + r <= cx <= f.x1 - r and f.y0 + r <= cy <= f.y1 - r):
        return False
    disc = Rect(cx - r, cy - r, cx + r, cy + r)
    if any(overlaps(disc, z) for z in zones):
        return False
    if any(overlaps(disc, p.box(), 0.08) for p in house.pieces):
        return False
    return all(math.hypot(cx - i.cx, cy - i.cy) > r + i.radius + 0.25 for i in house.items)


def _place_one(house: House, name: str, rng: np.random.Generator, zones: list[Rect]) -> None:
    """Put one object: by the piece it is kept by, else anywhere in that room, else anywhere in
    another room (HouseError: no place in the house)."""
    ox, oy, r = mesh_extent(name)
    room, kept_by = _choose(name, house, rng)
    by = [p for p in house.pieces if p.room == room.name and p.kind == kept_by]
    rooms = [room, *(o for o in house.rooms if o is not room)]
    for k in range(TRIES + TRIES_ELSEWHERE * (len(rooms) - 1)):
        near = bool(by) and k < TRIES // 2
        where = rooms[0 if k < TRIES else 1 + (k - TRIES) // TRIES_ELSEWHERE]
        if near:
            x, y = _near(by[int(rng.integers(len(by)))], rng)
        else:
            f = where.floor.shrunk(0.2)
            x, y = float(rng.uniform(f.x0, f.x1)), float(rng.uniform(f.y0, f.y1))
        yaw = float(rng.uniform(-math.pi, math.pi))
        c, s = math.cos(yaw), math.sin(yaw)
        bx, by_ = x - (c * ox - s * oy), y - (s * ox + c * oy)  # the body origin that centres it there
        if _free(house, where, x, y, r, zones):
            house.items.append(Item(name, where.name, round(bx, 3), round(by_, 3), round(yaw, 3), round(r, 3),
                                    round(x, 3), round(y, 3), kept_by if near else ""))  # fmt: skip
            return
    raise HouseError(f"no place for the {name.replace('_', ' ')} in the house")


def place_objects(house: House, rng: np.random.Generator, names: tuple[str, ...] = OBJECTS) -> None:
    """Put each object in the house (HouseError: an object that finds no place); an object placed
    already is taken away and placed anew (the generator moves one the robot cannot reach or see)."""
    zones = door_zones(house.doors)
    for name in names:
        if name not in MESHES:
            raise HouseError(f"no room of a house holds a {name.replace('_', ' ')} (objects: {', '.join(OBJECTS)})")
        house.items[:] = [i for i in house.items if i.name != name]
        _place_one(house, name, rng, zones)
