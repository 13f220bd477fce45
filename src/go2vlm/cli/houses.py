"""`go2vlm houses show SEED|FILE [--rooms N] [--out FILE]`: a generated house's plan as a PNG.

    go2vlm houses show 3                    house 3's plan in houses/house-3.png: rooms by type and name,
                                            walls, doors with their clear widths, furniture, objects, spawns
    go2vlm houses show 3 --rooms 6          the house of seed 3 with six rooms
    go2vlm houses show my-house.xml         a house world file (one of the cache, edited by hand)

It prints the seed used (a seed whose house fails its check is replaced by the next, and it says
so), the house's hash, its rooms, doors and objects, and the world file (`--world house:3` runs in
it: go2vlm sim, demo, eval suites). Exit 2 with one line for a seed out of range, more rooms than
fit, or a world file that does not load.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from go2vlm.errors import ConfigError


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "houses", help="generated houses (--world house:SEED): draw one's plan", description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    verbs = p.add_subparsers(dest="verb", metavar="VERB", required=True)
    show = verbs.add_parser("show", help="write a house's plan as a PNG and print what it holds")
    show.add_argument("house", metavar="SEED|FILE", help="a seed (0 to 2147483627) or a house world file (.xml)")
    show.add_argument("--rooms", type=int, default=None, help="how many rooms (3 to 7; default: drawn from the seed)")
    show.add_argument("--out", type=Path, default=None, help="the PNG (default houses/house-SEED.png)")
    show.set_defaults(func=cmd_show)


def _world(arg: str, rooms: int | None) -> str:
    if arg.endswith(".xml"):
        if rooms is not None:
            raise ConfigError("--rooms is for a seed, not a world file")
        if not Path(arg).is_file():
            raise ConfigError(f"no world file {arg!r}")
        return arg
    try:
        seed = int(arg)
    except ValueError:
        raise ConfigError(f"a house is a seed (a whole number) or a world file (.xml), not {arg!r}") from None
    return f"house:{seed}" + ("" if rooms is None else f":rooms={rooms}")


def cmd_show(args: argparse.Namespace) -> int:
    from go2vlm.sim.houses import house_file, is_house

    world = _world(args.house, args.rooms)
    note = None
    if is_house(world):
        path, gen = house_file(world)
        note = gen.note()
    else:
        path = Path(world)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from go2vlm.apps.episodes.plot import draw_plan
    from go2vlm.sim.worlds import world_footprints, world_model

    try:
        model, info = world_model(world)
    except Exception as exc:  # MuJoCo's XML, mesh and texture errors are ValueErrors; a bad file may be others
        first = " ".join(str(exc).split()) or type(exc).__name__
        raise ConfigError(f"world {world!r} does not load: {first}") from None
    if not info.rooms:
        raise ConfigError(f"world {world!r} has no rooms (no `rooms` metadata): not a house")
    shapes = world_footprints(model)
    name = f"house-{args.house}" if is_house(world) else Path(world).stem
    out = args.out or Path("houses") / f"{name}.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    xs = [v for r in info.rooms for v in (r.x0, r.x1)]
    ys = [v for r in info.rooms for v in (r.y0, r.y1)]
    w, h = max(xs) - min(xs), max(ys) - min(ys)
    fig, ax = plt.subplots(figsize=(min(16.0, 2 + 0.9 * w), min(14.0, 1.6 + 0.9 * h)))
    draw_plan(ax, info, shapes)
    ax.set_xlim(min(xs) - 0.4, max(xs) + 0.4)
    ax.set_ylim(min(ys) - 0.4, max(ys) + 0.4)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.06), fontsize=7, ncol=2, frameon=False)
    ax.set_title(
        f"{info.name}: {len(info.rooms)} rooms, {len(info.doors)} doors ({info.house or 'no seed'})", fontsize=10
    )
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
    if note:
        print(f"go2vlm houses: {note}", file=sys.stderr)
    print(f"{info.name}: {info.house}" if info.house else info.name)
    print(f"  rooms: {', '.join(f'{r.name} {r.x1 - r.x0:.1f} x {r.y1 - r.y0:.1f} m' for r in info.rooms)}")
    print(f"  doors: {', '.join(f'{d.a}-{d.b} {d.width:.2f} m' for d in info.doors)}")
    objects = [n for n in shapes if not n.startswith("wall")]
    where = {n: info.room_of(shapes[n].x, shapes[n].y) or "?" for n in objects}
    print(f"  bodies: {', '.join(f'{n} ({where[n]})' for n in sorted(objects))}")
    print(f"  world file: {path}")
    print(f"  plan: {out}")
    return 0
