"""Variants of a world with every doorway narrowed to a given clear width: the walls either side of each
gap in a straight wall line are lengthened towards its centre, so that the gap is `--width` m clear.
Nothing else changes (rooms metadata, spawns, objects). Written once per variant and committed:

    .venv/bin/python scripts/narrow_doorways.py apartment 0.8    # -> sim/worlds/apartment_door080.xml
"""

from __future__ import annotations

import argparse
import re
from collections import defaultdict
from pathlib import Path

WORLDS = Path(__file__).resolve().parents[1] / "src" / "go2vlm" / "sim" / "worlds"
NUM = r"([-\d.]+)"
WALL = re.compile(rf'<body name="(wall_[a-z0-9_]+)" pos="{NUM} {NUM} {NUM}"><geom type="box" size="{NUM} {NUM} {NUM}"')
MAX_DOORWAY_M = 2.0  # a gap wider than this in a wall line is no doorway (an open side of a room)


def narrow(text: str, width: float) -> tuple[str, int]:
    """The world's XML with every doorway `width` m clear, and how many doorways it narrowed."""
    walls = {m.group(1): [float(v) for v in m.groups()[1:]] for m in WALL.finditer(text)}
    lines: dict[tuple[int, float], list[str]] = defaultdict(list)  # (axis along, across coordinate)
    for name, (x, y, _z, sx, sy, _sz) in walls.items():
        axis = 0 if sx > sy else 1
        lines[(axis, round(y if axis == 0 else x, 3))].append(name)
    grow: dict[str, tuple[float, float]] = {}  # name -> (extend the low end, extend the high end)
    doors = 0
    for (axis, _), names in lines.items():
        segs = sorted((walls[n][axis] - walls[n][3 + axis], walls[n][axis] + walls[n][3 + axis], n) for n in names)
        for (_, a_hi, a), (b_lo, _, b) in zip(segs[:-1], segs[1:], strict=True):
            gap = b_lo - a_hi
            if width < gap <= MAX_DOORWAY_M:
                d = (gap - width) / 2
                grow[a] = (grow.get(a, (0.0, 0.0))[0], d)
                grow[b] = (d, grow.get(b, (0.0, 0.0))[1])
                doors += 1
    for name, (lo, hi) in grow.items():
        x, y, z, sx, sy, sz = walls[name]
        axis = 0 if sx > sy else 1
        pos, size = [x, y, z], [sx, sy, sz]
        pos[axis] += (hi - lo) / 2
        size[axis] += (hi + lo) / 2
        old = WALL.search(text[text.index(f'name="{name}"') - 6 :])
        assert old is not None
        new = (
            f'<body name="{name}" pos="{pos[0]:g} {pos[1]:g} {pos[2]:g}"><geom type="box" '
            f'size="{size[0]:g} {size[1]:g} {size[2]:g}"'
        )
        text = text.replace(old.group(0), new, 1)
    return text, doors


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("world")
    ap.add_argument("width", type=float, help="clear width of every doorway (m)")
    args = ap.parse_args()
    src = WORLDS / f"{args.world}.xml"
    text, doors = narrow(src.read_text(), args.width)
    name = f"{args.world}_door{round(args.width * 100):03d}"
    note = (
        f"<!-- {name}: generated from {args.world}.xml by scripts/narrow_doorways.py: every doorway "
        f"({doors}) narrowed to {args.width:g} m clear, nothing else changed. -->\n"
    )
    text = note + text.replace(f'<mujoco model="{args.world}">', f'<mujoco model="{name}">')
    out = WORLDS / f"{name}.xml"
    out.write_text(text)
    print(f"{out}: {doors} doorways at {args.width:g} m")


if __name__ == "__main__":
    main()
