"""plot.png of one episode: over sim time what the robot saw and did, and the top view of the world;
with a map node, the top view is drawn over the robot's map (unknown grey, free white, occupied
black) with the frontiers left, the frontiers the explorer walked to and the routes it planned
(series.json's map, frontiers, explored, plans: apps/episodes/navmap.py). In a generated house
(`--world house:SEED`) the top view also draws its plan under the rest: the rooms by type with their
names, the doors with their clear widths, each room's spawn (`draw_plan`, also `go2vlm houses show`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict, cast

import numpy as np

from go2vlm.geometry.footprint import Footprint, hull_outline

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from go2vlm.sim.worlds import WorldInfo

__all__ = ["UNKNOWN_GREY", "OccupancyGridDict", "draw_occupancy", "draw_plan", "draw_plot", "write_plot"]

UNKNOWN_GREY = "#b8b8b8"  # the map's unknown cells
ROOM_COLOURS = {"kitchen": "#f5eedc", "living": "#dfe9f5", "bedroom": "#e3f2e1", "bathroom": "#e0f0f4",
                "hall": "#eeeeee", "study": "#ece3f5"}  # fmt: skip


def draw_plan(
    ax: Axes, info: WorldInfo, shapes: Mapping[str, Footprint], objects: bool = True, fill: bool = True
) -> None:
    """A world's plan: its rooms (filled by type, or outlined without `fill`; named), walls and furniture
    (of `shapes`), doors (a gap with its clear width), and with `objects` the objects (named dots) and
    each room's spawn (an arrow)."""
    import matplotlib.patches as mp

    from go2vlm.sim.houses import OBJECTS

    for r in info.rooms:
        kind = r.name.rstrip("_0123456789")
        colour = ROOM_COLOURS.get(kind, "#f0f0f0")
        ax.add_patch(mp.Rectangle((r.x0, r.y0), r.x1 - r.x0, r.y1 - r.y0, facecolor=colour if fill else "none",
                                  edgecolor="none" if fill else "tab:cyan", lw=0.8,
                                  zorder=0 if fill else 2))  # fmt: skip
        ax.annotate(r.name, ((r.x0 + r.x1) / 2, (r.y0 + r.y1) / 2), ha="center", va="center", fontsize=9,
                    weight="bold", color="0.3", zorder=5, alpha=0.85,
                    bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.6})  # fmt: skip
    for name, sh in shapes.items():
        if name in OBJECTS:
            continue
        wall = name.startswith("wall")
        corner = np.array([sh.x, sh.y]) + _rot(sh.yaw) @ np.array([-sh.hx, -sh.hy])
        ax.add_patch(mp.Rectangle((float(corner[0]), float(corner[1])), 2 * sh.hx, 2 * sh.hy,
                                  angle=float(np.degrees(sh.yaw)), facecolor="0.2" if wall else "#c8a57a",
                                  edgecolor="0.2" if wall else "#7a5a3a", lw=0.6, zorder=1))  # fmt: skip
        if not wall:
            ax.annotate(name, (sh.x, sh.y), ha="center", va="center", fontsize=5.5, color="#5a3f25", zorder=2)
    for d in info.doors:
        dx, dy = (d.width / 2, 0.0) if d.along_x else (0.0, d.width / 2)
        ax.plot([d.x - dx, d.x + dx], [d.y - dy, d.y + dy], color="tab:green", lw=3, solid_capstyle="butt", zorder=2)
        ax.annotate(f"{d.width:.2f}", (d.x, d.y), xytext=(0, 5) if d.along_x else (5, 0),
                    textcoords="offset points", fontsize=6, color="tab:green", ha="center" if d.along_x else "left",
                    va="center", zorder=3)  # fmt: skip
    ax.plot([], [], color="tab:green", lw=3, label="door (clear width, m)")
    if not objects:
        return
    for name, sh in shapes.items():
        if name in OBJECTS:
            ax.add_patch(mp.Circle((sh.x, sh.y), 0.1, color="tab:orange", zorder=3))
            ax.annotate(name, (sh.x, sh.y), xytext=(0, -8), textcoords="offset points", ha="center", va="top",
                        fontsize=6.5, color="tab:red", zorder=4)  # fmt: skip
    for k, (_, (x, y, yaw)) in enumerate(info.room_spawns):
        ax.arrow(x, y, 0.4 * math.cos(yaw), 0.4 * math.sin(yaw), width=0.06, color="tab:purple", zorder=4,
                 label="spawn_<room>" if k == 0 else None)  # fmt: skip


def _top_view(ax: Any, m: dict[str, Any], s: dict[str, Any], shapes: dict[str, Footprint]) -> None:
    import matplotlib.patches as mp

    from go2vlm.sim.houses import is_house

    grid = s.get("map")
    draw_occupancy(ax, grid)
    on_map = bool(grid)
    if is_house(str(m.get("world") or "")):  # a generated house: its rooms and doors (over a map: outlined)
        from go2vlm.sim.worlds import world_info

        draw_plan(ax, world_info(m["world"]), {}, objects=False, fill=not on_map)
    for name, sh in shapes.items():
        is_target = name == m.get("target_body")
        colour = "tab:orange" if is_target else ("tab:olive" if on_map else "0.6")
        # Over a map the world's bodies are outlines, so the map's cells show through.
        fill = is_target or not on_map
        face, alpha, lw = (colour, 0.5, 0.0) if fill else ("none", 0.8, 0.8)
        if sh.kind == "circle":
            ax.add_patch(mp.Circle((sh.x, sh.y), sh.r, facecolor=face, edgecolor=colour, alpha=alpha, lw=lw))
        elif sh.kind == "hull":
            ax.add_patch(
                mp.Polygon(hull_outline(sh), closed=True, facecolor=face, edgecolor=colour, alpha=alpha, lw=lw)
            )
        else:
            corner = np.array([sh.x, sh.y]) + _rot(sh.yaw) @ np.array([-sh.hx, -sh.hy])
            ax.add_patch(mp.Rectangle((float(corner[0]), float(corner[1])), 2 * sh.hx, 2 * sh.hy,
                                      angle=float(np.degrees(sh.yaw)), facecolor=face, edgecolor=colour, alpha=alpha,
                                      lw=lw))  # fmt: skip
        if not is_target and (m.get("goal") is None or name.startswith("wall")):
            continue
        ax.annotate(name, (sh.x, sh.y), fontsize=7 if not is_target else 9, ha="center", va="center",
                    weight="bold" if is_target else "normal", color="tab:brown" if is_target else "0.25")  # fmt: skip
    _routes(ax, s)
    target, robot = np.array(s["target_xy"]).reshape(-1, 2), np.array(s["robot_xy"]).reshape(-1, 2)
    if len(target) and np.ptp(target, axis=0).max() > 0.05:  # a moving target: its path
        ax.plot(target[:, 0], target[:, 1], color="tab:red", lw=1, label=m.get("target_body") or "target")
        ax.plot(*target[0], "o", color="tab:red", ms=5)
    if len(robot):
        ax.plot(robot[:, 0], robot[:, 1], color="tab:blue", lw=1.5, label="Go2 (ground truth)" if on_map else "Go2")
        ax.plot(*robot[0], "s", color="tab:blue", ms=5)
        ax.plot(*robot[-1], ">", color="tab:blue", ms=6)
    _remembered(ax, m, quiet=on_map)
    if grid:  # the map's extent (and the path) fills the panel, 1:1
        x0, y0 = (float(v) for v in grid["origin"][:2])
        x1, y1 = x0 + grid["width"] * grid["resolution"], y0 + grid["height"] * grid["resolution"]
        if len(robot):
            (x0, y0), (x1, y1) = np.minimum((x0, y0), robot.min(axis=0)), np.maximum((x1, y1), robot.max(axis=0))
        ax.set_xlim(x0 - 0.5, x1 + 0.5)
        ax.set_ylim(y0 - 0.5, y1 + 0.5)
        ax.set_aspect("equal", adjustable="box")
    else:
        ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(alpha=0.3)
    if on_map:
        import matplotlib.patches as mp

        handles, _ = ax.get_legend_handles_labels()
        cells = [mp.Patch(facecolor=c, edgecolor="0.4", lw=0.5, label=lab)
                 for c, lab in ((UNKNOWN_GREY, "unknown"), ("white", "free"), ("black", "occupied"))]  # fmt: skip
        ax.legend(handles=[*handles, *cells], loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=4, fontsize=7,
                  frameon=False)  # fmt: skip  # below the map: nothing of it hidden
    else:
        ax.legend(loc="best", fontsize=8)


def _routes(ax: Axes, s: Mapping[str, object]) -> None:
    """The routes on /plan (older ones faint, the last dashed), the frontiers left (the newest
    costmap's, a dot sized by its edge) and those the explorer walked to (numbered stars)."""
    plans = cast("list[tuple[float, list[list[float]]]]", s.get("plans") or [])
    for k, (_, pts) in enumerate(plans):
        xy = np.asarray(pts, dtype=float).reshape(-1, 2)
        last = k == len(plans) - 1
        ax.plot(xy[:, 0], xy[:, 1], color="tab:green", lw=1.6 if last else 0.8, ls="--" if last else "-",
                alpha=0.9 if last else 0.35, label="planned route (last)" if last else None,
                zorder=3)  # fmt: skip
    if len(plans) > 1:
        ax.plot([], [], color="tab:green", lw=0.8, alpha=0.35, label=f"earlier routes ({len(plans) - 1})")
    fr = np.asarray(cast("list[list[float]]", s.get("frontiers") or []), dtype=float).reshape(-1, 3)
    if len(fr):
        ax.scatter(fr[:, 0], fr[:, 1], s=12 + 12 * np.clip(fr[:, 2], 0, 6), marker="o", facecolor="none",
                   edgecolor="tab:purple", lw=1.2, zorder=4, label=f"frontiers left ({len(fr)})")  # fmt: skip
    explored = np.asarray(cast("list[list[float]]", s.get("explored") or []), dtype=float).reshape(-1, 2)
    if len(explored):
        ax.scatter(explored[:, 0], explored[:, 1], s=90, marker="*", color="tab:purple", edgecolor="white",
                   lw=0.5, zorder=5, label="frontiers walked to")  # fmt: skip
        for k, (x, y) in enumerate(explored, start=1):
            ax.annotate(str(k), (x, y), xytext=(5, 4), textcoords="offset points", fontsize=7, color="tab:purple")


def _remembered(ax: Any, m: dict[str, Any], quiet: bool = False) -> None:
    """The object memory's objects at the end (x), each with a line to where it really is; `quiet`
    (over a map): small marks, no names and no lines, so the map and the routes stay readable."""
    objs = (m.get("memory") or {}).get("objects") or []
    phantoms = sum(1 for o in objs if o["phantom"])
    for k, o in enumerate(objs):
        colour = "tab:red" if o["phantom"] else "black"
        label = (f"remembered ({len(objs)}, {phantoms} phantom)" if quiet else "remembered") if k == 0 else None
        ax.plot(o["x"], o["y"], "x", color=colour, ms=4 if quiet else 7, mew=1.0 if quiet else 1.8, label=label,
                alpha=0.6 if quiet else 1.0)  # fmt: skip
        if quiet:
            continue
        if o["true_x"] is not None:
            ax.plot([o["x"], o["true_x"]], [o["y"], o["true_y"]], color=colour, lw=0.8)
        err = "phantom" if o["phantom"] else f"{100 * o['error_m']:.0f} cm"
        ax.annotate(f"{o['label']} {o['confidence']:.2f} ({err})", (o["x"], o["y"]), xytext=(4, -9),
                    textcoords="offset points", fontsize=6, color=colour)  # fmt: skip


def _rot(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def write_plot(m: dict[str, Any], s: dict[str, Any], shapes: dict[str, Footprint], path: Path) -> None:
    import matplotlib.pyplot as plt

    fig = draw_plot(m, s, shapes)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def draw_plot(m: dict[str, Any], s: dict[str, Any], shapes: dict[str, Footprint]) -> Figure:
    """The plot's figure (the caller closes it): the time series left, the top view right (its last axes)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    on_map = bool(s.get("map"))
    fig = plt.figure(figsize=(14, 7) if on_map else (12, 5.5))
    gs = fig.add_gridspec(2, 2, width_ratios=(1, 1.4) if on_map else (1, 1))
    ax1 = fig.add_subplot(gs[0, 0])
    ax2 = fig.add_subplot(gs[1, 0], sharex=ax1)
    ax3 = fig.add_subplot(gs[:, 1])
    fell = ", FELL" if m.get("fell") else ""
    if m.get("goal") is None:  # the follow article's loop
        ax1.plot(s["target_sim_t"], s["target_x"], ".", ms=2, color="tab:red")
        ax1.axhline(0, color="0.5", lw=0.8)
        ax1.set_ylim(-1.05, 1.05)
        ax1.set_ylabel("x error (normalised)")
        ax1.set_title(
            f"tracking: ball visible {100 * m['target_visible_fraction']:.1f} % of frames, "
            f"mean |x| {m['mean_abs_x_error'] or 0:.3f}",
            fontsize=9,
        )
        ax2.plot(s["gt_sim_t"], s["distance"], color="tab:blue")
        ax2.set_ylabel("distance to ball (m)")
        ax3.set_title(
            f"top view ({m['mode']}, {m['duration_s']:.0f} s, rtf {m['real_time_factor']:.2f}{fell})", fontsize=9
        )
    else:
        cmd = np.array(s["cmd"]).reshape(-1, 3)
        if len(cmd):
            ax1.plot(cmd[:, 0], cmd[:, 1], color="tab:blue", lw=1, label="vx (m/s)")
            ax1.plot(cmd[:, 0], cmd[:, 2], color="tab:green", lw=1, label="wz (rad/s)")
            ax1.legend(loc="best", fontsize=8)
        ax1.axhline(0, color="0.5", lw=0.8)
        ax1.set_ylabel("/cmd_vel")
        verdict = "reached" if m["success"] else "NOT reached"
        ax1.set_title(f"{m['goal']!r}: {verdict} ({m['perception']}, final state {m.get('final_state')})", fontsize=9)
        ax2.plot(s["gt_sim_t"], s["distance"], color="tab:orange")
        ax2.set_ylabel("to the target's surface (m)")
        prev, named = None, -math.inf
        span = (s["states"][-1][0] - s["states"][0][0]) if s["states"] else 0.0
        for t, state in s["states"]:
            if state != prev:
                ax2.axvline(t, color="0.7", lw=0.6)
                if t - named > span / 60:  # a burst of changes (exploring <-> detouring): its first is named
                    ax2.annotate(
                        str(state), (t, 1.0), xycoords=("data", "axes fraction"), fontsize=6, rotation=90, va="top"
                    )
                    named = t
                prev = state
        ax3.set_title(
            f"top view ({m['world']}, {m['mode']}, {m['sim_s']:.0f} s, {m['path_length_m']:.1f} m walked, "
            f"{m['collisions']} collisions{fell})" + (": the robot's map, its frontiers and routes" if on_map else ""),
            fontsize=9,
        )
    ax2.set_xlabel("sim time (s)")
    _top_view(ax3, m, s, shapes)
    fig.tight_layout()
    return fig


class OccupancyGridDict(TypedDict):
    """nav_msgs/OccupancyGrid's layout as the metrics carry it (see `draw_occupancy`)."""

    origin: list[float]
    resolution: float
    width: int
    height: int
    data: list[int]


def draw_occupancy(ax: Axes, grid: OccupancyGridDict | None) -> None:
    """The robot's map under the top view: a grid in nav_msgs/OccupancyGrid's layout, {"origin": [x,
    y], "resolution": metres a cell, "width": cells, "height": cells, "data": row-major from the
    origin, -1 unknown, 0 free .. 100 occupied}, in the world frame (the map's odom frame is the
    world's at the start). Unknown cells grey, free white, occupied (>= 50) black. Nothing without a map."""
    if not grid:
        return
    from matplotlib.colors import ListedColormap

    w, h, res = int(grid["width"]), int(grid["height"]), float(grid["resolution"])
    cells = np.asarray(grid["data"], dtype=float).reshape(h, w)
    klass = np.where(cells < 0, 0, np.where(cells < 50, 1, 2))  # unknown, free, occupied
    x0, y0 = (float(v) for v in grid["origin"][:2])
    ax.imshow(klass, origin="lower", extent=(x0, x0 + w * res, y0, y0 + h * res),
              cmap=ListedColormap([UNKNOWN_GREY, "white", "black"]), vmin=0, vmax=2, interpolation="nearest",
              zorder=0)  # fmt: skip
