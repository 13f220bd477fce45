"""Houses from seeds: floor plans with doors, furniture and objects, checked, as MJCF worlds.

    house = generate(17)                 # the house of seed 17 (or of the next seed that passes)
    house.house.rooms, house.digest      # its plan and its hash; house.skipped: seeds that failed
    house_file(17)                       # its world file, written to the cache: `--world house:17`

One seed, one house, one MJCF text (the generator draws only from numpy's generator seeded with the
seed). The steps, each its own module: plan.py (rooms, walls, doors, room types), furniture.py,
objects.py (the household meshes where people keep them), check.py (reachable and visible by the
Go2, nothing overlapping; it also picks each room's spawn), mjcf.py (the world file).

A seed whose house fails a step or the check is replaced by the next seed (up to MAX_REPLACED of them),
and `Generated.skipped` says which and why; `generate(..., strict=True)` refuses instead (a suite that
names a house). A world name `house:SEED` (or `house:SEED:rooms=N`) is a house wherever a world is
named (sim/worlds.py `world_path`): its file is written under the cache folder
($XDG_CACHE_HOME/go2vlm/houses, ~/.cache when unset), never into the package.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from go2vlm.sim.houses.check import check_house, floor_grid, hidden_items, spawns, unreachable_rooms
from go2vlm.sim.houses.furniture import furnish
from go2vlm.sim.houses.mjcf import house_mjcf
from go2vlm.sim.houses.objects import OBJECTS, place_objects
from go2vlm.sim.houses.plan import MAX_ROOMS, MIN_ROOMS, House, HouseError, make_plan

__all__ = [
    "MAX_REPLACED",
    "OBJECTS",
    "PREFIX",
    "SEED_MAX",
    "Generated",
    "House",
    "HouseError",
    "cache_dir",
    "check_house",
    "generate",
    "house_file",
    "is_house",
    "parse_house",
]

SEED_MAX = 2**31 - 1
MAX_REPLACED = 20
REPAIR_ROUNDS = 3
PREFIX = "house:"


@dataclass(frozen=True)
class Generated:
    house: House
    asked: int  # the seed asked for; house.seed is the one used
    digest: str  # sha256 of the plan (rooms, doors, walls, furniture, objects), 16 hex digits
    mjcf: str
    skipped: tuple[tuple[int, str], ...] = ()  # (seed, why) of the seeds that failed before it

    @property
    def seed(self) -> int:
        return self.house.seed

    def note(self) -> str | None:
        """One line on the replaced seeds (None when the asked seed's house passed)."""
        if not self.skipped:
            return None
        why = "; ".join(f"house {s}: {w}" for s, w in self.skipped)
        return f"house {self.asked} failed its check ({why}); house {self.seed} is used"


def _digest(house: House) -> str:
    text = json.dumps(dataclasses.asdict(house), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _one(seed: int, rooms: int | None, objects: tuple[str, ...]) -> tuple[House, list[str]]:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(MIN_ROOMS, MAX_ROOMS + 1)) if rooms is None else rooms
    house = make_plan(seed, n, rng)
    furnish(house, rng)
    place_objects(house, rng, objects)
    floor = floor_grid(house)
    spawns(house, floor)
    for _ in range(REPAIR_ROUNDS):  # a room furniture cuts off (and the rooms next to it) furnished anew
        lost = set(unreachable_rooms(house, floor)[0])
        if not lost:
            break
        lost |= {d.a for d in house.doors if d.b in lost} | {d.b for d in house.doors if d.a in lost}  # the way in
        furnish(house, rng, lost)
        place_objects(house, rng, tuple(i.name for i in house.items if i.room in lost))
        floor = floor_grid(house)
        spawns(house, floor)
    for _ in range(REPAIR_ROUNDS):  # an object the robot cannot reach or see is put elsewhere
        hidden = hidden_items(house, floor)
        if not hidden:
            break
        place_objects(house, rng, tuple(hidden))
        floor = floor_grid(house)
        spawns(house, floor)
    return house, check_house(house, floor)


def _request(seed: int, rooms: int | None, objects: tuple[str, ...]) -> None:
    """HouseError for what no seed can give: a seed out of range, more rooms than fit, an unknown object."""
    if not 0 <= seed <= SEED_MAX - MAX_REPLACED:
        raise HouseError(f"house seed {seed} is out of range (0 to {SEED_MAX - MAX_REPLACED})")
    if rooms is not None and not MIN_ROOMS <= rooms <= MAX_ROOMS:
        raise HouseError(f"{rooms} rooms do not fit: a house has {MIN_ROOMS} to {MAX_ROOMS} rooms")
    unknown = [o for o in objects if o not in OBJECTS]
    if unknown:
        names = ", ".join(o.replace("_", " ") for o in unknown)
        raise HouseError(f"no room of a house holds a {names} (objects: {', '.join(OBJECTS)})")


def generate(
    seed: int, rooms: int | None = None, objects: tuple[str, ...] = OBJECTS, strict: bool = False
) -> Generated:
    """The house of `seed` (module docstring); HouseError for an impossible request, or when no seed
    of the replacement window passes (with `strict`: when this seed's house does not)."""
    _request(seed, rooms, objects)
    skipped: list[tuple[int, str]] = []
    for s in range(seed, seed + MAX_REPLACED + 1):
        try:
            house, problems = _one(s, rooms, objects)
        except HouseError as exc:
            problems = [str(exc)]
        if not problems:
            digest = _digest(house)
            return Generated(house, seed, digest, house_mjcf(house, digest), tuple(skipped))
        skipped.append((s, problems[0] + (f" (+{len(problems) - 1} more)" if len(problems) > 1 else "")))
        if strict:
            raise HouseError(f"house {seed} fails its check: {skipped[-1][1]}")
    raise HouseError(f"no house from seed {seed} to {seed + MAX_REPLACED} passes its check: {skipped[0][1]}")


def is_house(name: str) -> bool:
    return name.startswith(PREFIX)


def parse_house(name: str) -> tuple[int, int | None]:
    """`house:SEED` or `house:SEED:rooms=N` -> (seed, rooms); HouseError naming the form otherwise."""
    parts = name.removeprefix(PREFIX).split(":")
    try:
        seed = int(parts[0])
        rooms = None
        for extra in parts[1:]:
            key, _, value = extra.partition("=")
            if key != "rooms":
                raise ValueError(extra)
            rooms = int(value)
    except ValueError:
        raise HouseError(f"a house world is house:SEED or house:SEED:rooms=N (SEED 0 to {SEED_MAX - MAX_REPLACED}), "
                         f"not {name!r}") from None  # fmt: skip
    return seed, rooms


def cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "go2vlm" / "houses"


_MEMO: dict[tuple[Path, str], tuple[Path, Generated]] = {}  # (cache folder, name): generated once a process


def house_file(name: str) -> tuple[Path, Generated]:
    """The world file of a house world name (written to the cache when missing or not as generated)."""
    folder = cache_dir()
    key = (folder, name)
    if key in _MEMO and _MEMO[key][0].is_file():
        path, gen = _MEMO[key]
        if path.read_text(encoding="utf-8") == gen.mjcf:
            return path, gen
    seed, rooms = parse_house(name)
    gen = _MEMO[key][1] if key in _MEMO else generate(seed, rooms)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"house-{seed}{'' if rooms is None else f'-r{rooms}'}.xml"
    if not path.is_file() or path.read_text(encoding="utf-8") != gen.mjcf:  # a file edited by hand is rewritten
        fd, tmp = tempfile.mkstemp(dir=folder, suffix=".xml.tmp")
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(gen.mjcf)
        os.replace(tmp, path)
    _MEMO[key] = (path, gen)
    return path, gen
