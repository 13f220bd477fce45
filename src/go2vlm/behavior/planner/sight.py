"""What a stand sees of a place on the costmap: the global planner's `goal_in_sight` and the
navigator's "there" ask it. Pure."""

from __future__ import annotations

import math

import numpy as np

from go2vlm.world.occupancy import LETHAL

__all__ = ["in_sight"]


def in_sight(data: np.ndarray, cells: np.ndarray, goal: tuple[int, int], body: float, own: float = 0.0) -> np.ndarray:
    """bool per (row, col) of `cells`: does the straight line from it to cell `goal` cross no obstacle
    cell (LETHAL) but the goal's own? Its own: those within `body` cells of `goal`, and every piece of
    obstacle lying wholly within `body + own` cells of it (a remembered place is off by up to `own`,
    and the object's cells with it; a wall running past is no such piece). Cells outside the grid
    hide nothing (unknown)."""
    cells = np.asarray(cells, dtype=int).reshape(-1, 2)
    if len(cells) == 0:
        return np.zeros(0, bool)
    d = cells - np.asarray(goal)
    n = int(np.abs(d).max()) + 1
    t = np.linspace(0.0, 1.0, n + 1)[None, :, None]
    pts = np.floor(np.asarray(goal)[None, None, :] + t * d[:, None, :] + 0.5).astype(int)  # (M, n + 1, 2)
    h, w = data.shape
    inside = (pts[..., 0] >= 0) & (pts[..., 0] < h) & (pts[..., 1] >= 0) & (pts[..., 1] < w)
    hit = np.zeros(inside.shape, bool)
    hit[inside] = data[pts[..., 0][inside], pts[..., 1][inside]] == LETHAL
    hit &= np.hypot(pts[..., 0] - goal[0], pts[..., 1] - goal[1]) > body
    if own > 0 and hit.any():
        mine = _own_pieces(data, goal, body + own)
        r = int(math.ceil(body + own)) + 1
        win = hit & (np.abs(pts[..., 0] - goal[0]) <= r) & (np.abs(pts[..., 1] - goal[1]) <= r)
        hit[win] = ~mine[pts[..., 0][win] - goal[0] + r, pts[..., 1][win] - goal[1] + r]
    return np.asarray(~hit.any(axis=1))


def _own_pieces(data: np.ndarray, goal: tuple[int, int], reach: float) -> np.ndarray:
    """The obstacle cells (LETHAL) of the pieces lying wholly within `reach` cells of `goal`, on the
    square window of half side ceil(reach) + 1 round it (cells off the grid: none)."""
    from scipy import ndimage  # the nav extra, as skimage below

    r = int(math.ceil(reach)) + 1
    win = np.zeros((2 * r + 1, 2 * r + 1), bool)
    r0, c0 = goal[0] - r, goal[1] - r
    a0, b0 = max(r0, 0), max(c0, 0)
    a1, b1 = min(goal[0] + r + 1, data.shape[0]), min(goal[1] + r + 1, data.shape[1])
    if a0 < a1 and b0 < b1:
        win[a0 - r0 : a1 - r0, b0 - c0 : b1 - c0] = data[a0:a1, b0:b1] == LETHAL
    labels, n = ndimage.label(win, structure=np.ones((3, 3), bool))
    if n == 0:
        return win
    rr, cc = np.indices(win.shape)
    far = np.hypot(rr - r, cc - r) > reach
    beyond = np.zeros(n + 1, bool)
    beyond[np.unique(labels[far & win])] = True  # a piece reaching past `reach` (or the window's edge)
    return win & ~beyond[labels]
