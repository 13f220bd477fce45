"""A world's top view for the docs: its rooms (the `rooms` metadata), walls and objects from their floor
footprints (sim/worlds.py `world_footprints`), each room's spawn pose, and beside it the world camera's
render. Usage:

    .venv/bin/python scripts/world_top_view.py apartment --out docs/img/apartment_top_view.png
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.patches as mp  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from go2vlm.sim import Go2Sim, SimConfig  # noqa: E402
from go2vlm.sim.worlds import world_footprints, world_model  # noqa: E402

ROOM_COLOURS = ("#dfe9f5", "#f5eedc", "#e3f2e1", "#f4e1e4", "#ece3f5", "#f0f0f0")
SATURATED = {"red_": "tab:red", "green_": "tab:green", "blue_": "tab:blue", "yellow_": "gold"}


def draw(world: str, out: Path) -> None:
    model, info = world_model(world)
    shapes = world_footprints(model)
    fig, (ax, cam) = plt.subplots(1, 2, figsize=(15, 6.6), gridspec_kw={"width_ratios": [1.25, 1]})
    for k, r in enumerate(info.rooms):
        ax.add_patch(mp.Rectangle((r.x0, r.y0), r.x1 - r.x0, r.y1 - r.y0, color=ROOM_COLOURS[k % len(ROOM_COLOURS)]))
        ax.annotate(r.name, ((r.x0 + r.x1) / 2, r.y1 - 0.3), ha="center", va="top", fontsize=11, weight="bold",
                    color="0.35")  # fmt: skip
    for name, s in shapes.items():
        wall = name.startswith("wall")
        colour = "0.25" if wall else next((c for p, c in SATURATED.items() if name.startswith(p)), "tab:brown")
        if s.kind == "circle":
            ax.add_patch(mp.Circle((s.x, s.y), s.r, color=colour, alpha=0.85))
        else:
            c, sn = math.cos(s.yaw), math.sin(s.yaw)
            corner = (s.x - c * s.hx + sn * s.hy, s.y - sn * s.hx - c * s.hy)
            ax.add_patch(mp.Rectangle(corner, 2 * s.hx, 2 * s.hy, angle=math.degrees(s.yaw), color=colour,
                                      alpha=1.0 if wall else 0.6))  # fmt: skip
        if not wall:
            ax.annotate(f"{name}\n({s.x:.1f}, {s.y:.1f})", (s.x, s.y), xytext=(0, -11), textcoords="offset points",
                        ha="center", va="top", fontsize=6.5)  # fmt: skip
    for _, (x, y, yaw) in info.room_spawns:
        ax.arrow(x, y, 0.45 * math.cos(yaw), 0.45 * math.sin(yaw), width=0.06, color="tab:purple")
    ax.plot([], [], ">", color="tab:purple", label="spawn_<room> (the demo's --spawn)")
    ax.set_aspect("equal")
    bounds = np.array([(r.x0, r.y0, r.x1, r.y1) for r in info.rooms])
    ax.set_xlim(bounds[:, 0].min() - 0.4, bounds[:, 2].max() + 0.4)
    ax.set_ylim(bounds[:, 1].min() - 0.4, bounds[:, 3].max() + 0.4)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(alpha=0.25)
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(f"{world}: rooms, walls, objects (x, y in m)", fontsize=10)
    sim = Go2Sim(SimConfig(world=world, mode="kinematic", spawn=info.spawn))
    try:
        cam.imshow(sim.render_world_camera(960, 720))
    finally:
        sim.close()
    cam.set_axis_off()
    cam.set_title("the world camera (MuJoCo render)", fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    plt.close(fig)
    print(f"wrote {out}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("world")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args()
    draw(args.world, args.out)


if __name__ == "__main__":
    main()
