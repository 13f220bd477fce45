"""plot.png of one episode: over sim time what the robot saw and did, and the top view of the world."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from go2vlm.geometry.footprint import Footprint

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["OccupancyGridDict", "draw_occupancy", "write_plot"]


def _top_view(ax: Any, m: dict[str, Any], s: dict[str, Any], shapes: dict[str, Footprint]) -> None:
    import matplotlib.patches as mp

    draw_occupancy(ax, m.get("map"))
    for name, sh in shapes.items():
        colour = "tab:orange" if name == m.get("target_body") else "0.6"
        if sh.kind == "circle":
            ax.add_patch(mp.Circle((sh.x, sh.y), sh.r, color=colour, alpha=0.5))
        else:
            corner = np.array([sh.x, sh.y]) + _rot(sh.yaw) @ np.array([-sh.hx, -sh.hy])
            ax.add_patch(
                mp.Rectangle(
                    tuple(corner), 2 * sh.hx, 2 * sh.hy, angle=float(np.degrees(sh.yaw)), color=colour, alpha=0.5
                )
            )
        if name != m.get("target_body") and m.get("goal") is None:
            continue
        ax.annotate(name, (sh.x, sh.y), fontsize=7, ha="center", va="center")
    target, robot = np.array(s["target_xy"]).reshape(-1, 2), np.array(s["robot_xy"]).reshape(-1, 2)
    if len(target) and np.ptp(target, axis=0).max() > 0.05:  # a moving target: its path
        ax.plot(target[:, 0], target[:, 1], color="tab:red", lw=1, label=m.get("target_body") or "target")
        ax.plot(*target[0], "o", color="tab:red", ms=5)
    if len(robot):
        ax.plot(robot[:, 0], robot[:, 1], color="tab:blue", lw=1.5, label="Go2")
        ax.plot(*robot[0], "s", color="tab:blue", ms=5)
        ax.plot(*robot[-1], ">", color="tab:blue", ms=6)
    _remembered(ax, m)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)


def _remembered(ax: Any, m: dict[str, Any]) -> None:
    """The object memory's objects at the end (x), each with a line to where it really is."""
    objs = (m.get("memory") or {}).get("objects") or []
    for k, o in enumerate(objs):
        colour = "tab:red" if o["phantom"] else "black"
        ax.plot(o["x"], o["y"], "x", color=colour, ms=7, mew=1.8, label="remembered" if k == 0 else None)
        if o["true_x"] is not None:
            ax.plot([o["x"], o["true_x"]], [o["y"], o["true_y"]], color=colour, lw=0.8)
        err = "phantom" if o["phantom"] else f"{100 * o['error_m']:.0f} cm"
        ax.annotate(f"{o['label']} {o['confidence']:.2f} ({err})", (o["x"], o["y"]), xytext=(4, -9),
                    textcoords="offset points", fontsize=6, color=colour)  # fmt: skip


def _rot(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def write_plot(m: dict[str, Any], s: dict[str, Any], shapes: dict[str, Footprint], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 5.5))
    ax1 = fig.add_subplot(2, 2, 1)
    ax2 = fig.add_subplot(2, 2, 3, sharex=ax1)
    ax3 = fig.add_subplot(1, 2, 2)
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
        prev = None
        for t, state in s["states"]:
            if state != prev:
                ax2.axvline(t, color="0.7", lw=0.6)
                ax2.annotate(
                    str(state), (t, 1.0), xycoords=("data", "axes fraction"), fontsize=6, rotation=90, va="top"
                )
                prev = state
        ax3.set_title(
            f"top view ({m['world']}, {m['mode']}, {m['sim_s']:.0f} s, {m['collisions']} collisions{fell})", fontsize=9
        )
    ax2.set_xlabel("sim time (s)")
    _top_view(ax3, m, s, shapes)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


class OccupancyGridDict(TypedDict):
    """nav_msgs/OccupancyGrid's layout as the metrics carry it (see `draw_occupancy`)."""

    origin: list[float]
    resolution: float
    width: int
    height: int
    data: list[int]


def draw_occupancy(ax: Axes, grid: OccupancyGridDict | None) -> None:
    """The hook for the robot's map under the top view (issue 30): `metrics["map"]` in
    nav_msgs/OccupancyGrid's layout, {"origin": [x, y], "resolution": metres a cell, "width": cells,
    "height": cells, "data": row-major from the origin, -1 unknown, 0 free .. 100 occupied}, in the
    world frame (the map's odom frame is the world's at the start). Unknown cells are left clear,
    free light, occupied dark. Nothing without a map."""
    if not grid:
        return
    w, h, res = int(grid["width"]), int(grid["height"]), float(grid["resolution"])
    cells = np.asarray(grid["data"], dtype=float).reshape(h, w)
    shade = np.ma.masked_less(cells, 0)  # unknown: not drawn
    x0, y0 = (float(v) for v in grid["origin"][:2])
    ax.imshow(shade, origin="lower", extent=(x0, x0 + w * res, y0, y0 + h * res), cmap="Greys", vmin=-30,
              vmax=100, alpha=0.6, interpolation="nearest", zorder=0)  # fmt: skip
