"""Footprints on the floor plane: circles and oriented rectangles, their gaps and distances.

Pure 2D geometry for judging episodes from ground truth (collisions, clearance, distance to a goal
object) and for drawing spawn poses that do not start inside an object. A robot is an oriented
rectangle (`Footprint.rect`); an object is a circle (sphere, cylinder) or a rectangle (box).
`rect_distance` is the same distance for many points at once, in the robot's frame: the safety
gate's guard and the behaviour's local planner judge the footprint's clearance with it.

`Clearance` is the one clearance rule: how far the footprint keeps from anything, by speed (a few
centimetres at a creep, more at speed). The costmap's lethal radius and the global planner's footprint
check (at a creep), the local planner's corridors and the collision guard's margin all read it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from go2vlm.declare import param

Num = float | np.ndarray  # a number, or a column of them (one a rectangle)

__all__ = ["Clearance", "Footprint", "clearance", "hull_distance", "hull_outline", "rect_distance", "surface_distance"]


@dataclass(frozen=True)
class Clearance:
    """The gap (m) kept between the robot's footprint and any obstacle: `creep_m` standing or at a
    creep, `per_speed_s` more per m/s of the fastest footprint point (about the distance it covers in
    that time while tracking, sensing and leg sway add up). Non-decreasing in speed. With the
    defaults a Go2 (0.31 m wide) keeps a few centimetres at a creep (0.11 m at 0.15 m/s), crosses a
    0.8 m doorway square-on at up to 0.49 m/s (0.245 m each side), refuses a 0.4 m gap (0.045 m each
    side, less than `creep_m`), and keeps 0.25 m at 0.5 m/s."""

    # bound="min": a clearance is a safety limit, it may only grow while a node runs (declare.py)
    creep_m: float = param(
        0.05, help="clearance: gap (m) the footprint keeps from any obstacle standing (more at speed)", min=0.0,
        max=1.5, live=True, bound="min",
    )  # fmt: skip
    per_speed_s: float = param(
        0.4, help="clearance: gap added (m) per m/s of the footprint's fastest point", min=0.0, max=3.0,
        live=True, bound="min",
    )  # fmt: skip
    creep_mps: float = param(
        0.15, help="clearance: a creep (m/s): how fast it passes where only the creep's gap is free", min=0.02, max=1.0
    )

    def __post_init__(self) -> None:
        for name in ("creep_m", "per_speed_s", "creep_mps"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"clearance {name} must be a finite number >= 0, got {v}")

    def at(self, speed: float) -> float:
        """The gap (m) to keep at `speed` (m/s; its size: a negative speed is as fast backwards)."""
        return self.creep_m + self.per_speed_s * abs(speed) if math.isfinite(speed) else math.inf

    def speed_for(self, gap: float) -> float:
        """The fastest speed (m/s) at which `gap` (m) is clearance enough: 0 below `creep_m`."""
        if not gap >= self.creep_m:  # also NaN
            return 0.0
        return math.inf if self.per_speed_s == 0 else (gap - self.creep_m) / self.per_speed_s

    @property
    def creep(self) -> float:
        """The gap (m) kept at a creep (`creep_mps`)."""
        return self.at(self.creep_mps)


@dataclass(frozen=True)
class Footprint:
    kind: str  # circle | rect | hull
    x: float
    y: float
    yaw: float = 0.0
    r: float = 0.0  # circle radius
    hx: float = 0.0  # rect half sizes (along its own x and y); a hull's bounding box's
    hy: float = 0.0
    pts: tuple[tuple[float, float], ...] = ()  # hull: its convex outline (counter-clockwise, its own frame)

    @staticmethod
    def rect(x: float, y: float, yaw: float, length: float, width: float) -> Footprint:
        return Footprint("rect", x, y, yaw, hx=length / 2, hy=width / 2)

    def moved(self, x: float, y: float, yaw: float | None = None) -> Footprint:
        """The same shape at another pose (a moving body's pose from ground truth)."""
        return replace(self, x=x, y=y, yaw=self.yaw if yaw is None else yaw)


def _to_local(px: float, py: float, x: float, y: float, yaw: float) -> tuple[float, float]:
    dx, dy = px - x, py - y
    c, s = math.cos(yaw), math.sin(yaw)
    return c * dx + s * dy, -s * dx + c * dy


def rect_distance(px: np.ndarray, py: np.ndarray, hx: float | np.ndarray, hy: float | np.ndarray) -> np.ndarray:
    """Signed distance from points (the rectangle's frame) to the centred rectangle of half sizes
    `hx`, `hy` (negative inside)."""
    dx, dy = np.abs(px) - hx, np.abs(py) - hy
    outside = np.hypot(np.maximum(dx, 0.0), np.maximum(dy, 0.0))
    return np.where(outside > 0, outside, np.maximum(dx, dy))


def _rect_dist(px: float, py: float, rect: Footprint) -> float:
    """Signed distance from a point to an oriented rectangle (negative inside)."""
    lx, ly = _to_local(px, py, rect.x, rect.y, rect.yaw)
    dx, dy = abs(lx) - rect.hx, abs(ly) - rect.hy
    outside = math.hypot(max(dx, 0.0), max(dy, 0.0))
    return outside if outside > 0 else max(dx, dy)


_OUTLINE = np.linspace(-1.0, 1.0, 12)  # points along each side, as fractions of its half length


def _rect_points(rect: Footprint) -> tuple[np.ndarray, np.ndarray]:
    """Points along a rectangle's outline (12 a side), world x and y."""
    f, one = _OUTLINE, np.ones_like(_OUTLINE)
    lx = np.concatenate((f * rect.hx, f * rect.hx, one * rect.hx, -one * rect.hx))
    ly = np.concatenate((one * rect.hy, -one * rect.hy, f * rect.hy, f * rect.hy))
    c, s = math.cos(rect.yaw), math.sin(rect.yaw)
    return rect.x + c * lx - s * ly, rect.y + s * lx + c * ly


def _least_dist(px: np.ndarray, py: np.ndarray, x: Num, y: Num, yaw: Num, hx: Num, hy: Num) -> np.ndarray:
    """The least signed distance from each row of points (world, (..., N)) to an oriented rectangle
    (centre, yaw, half sizes: numbers, or columns with one rectangle a row)."""
    c, s = np.cos(yaw), np.sin(yaw)
    dx, dy = px - x, py - y
    return rect_distance(c * dx + s * dy, -s * dx + c * dy, hx, hy).min(axis=-1)


def _least_rect_dist(px: np.ndarray, py: np.ndarray, rect: Footprint) -> np.ndarray:
    return _least_dist(px, py, rect.x, rect.y, rect.yaw, rect.hx, rect.hy)


def hull_outline(sh: Footprint) -> np.ndarray:
    """A hull's vertices in the world (N, 2), counter-clockwise."""
    v = np.asarray(sh.pts, dtype=float).reshape(-1, 2)
    c, s = math.cos(sh.yaw), math.sin(sh.yaw)
    return np.column_stack((sh.x + c * v[:, 0] - s * v[:, 1], sh.y + s * v[:, 0] + c * v[:, 1]))


def hull_distance(px: np.ndarray, py: np.ndarray, verts: np.ndarray) -> np.ndarray:
    """Signed distance from points to the convex polygon `verts` (N, 2, counter-clockwise; negative
    inside): to its nearest edge, inside where the point is on the inner side of every edge."""
    a, b = verts, np.roll(verts, -1, axis=0)
    ab = b - a
    px, py = np.asarray(px, dtype=float)[..., None], np.asarray(py, dtype=float)[..., None]
    t = np.clip(((px - a[:, 0]) * ab[:, 0] + (py - a[:, 1]) * ab[:, 1]) / np.maximum((ab**2).sum(axis=1), 1e-12), 0, 1)
    d = np.hypot(px - (a[:, 0] + t * ab[:, 0]), py - (a[:, 1] + t * ab[:, 1])).min(axis=-1)
    inside = ((ab[:, 0] * (py - a[:, 1]) - ab[:, 1] * (px - a[:, 0])) >= 0).all(axis=-1)
    return np.where(inside, -d, d)


def _hull_points(verts: np.ndarray, per_edge: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Points along a hull's outline: its vertices and `per_edge` - 1 more along each edge."""
    f = np.arange(per_edge)[:, None, None] / per_edge
    pts = (verts[None] + f * (np.roll(verts, -1, axis=0) - verts)[None]).reshape(-1, 2)
    return pts[:, 0], pts[:, 1]


def clearance(robot: Footprint, shape: Footprint) -> float:
    """Gap between a rectangular robot footprint and an object's footprint (negative: they overlap).
    Rectangle against rectangle is sampled along both outlines (12 points a side: a few mm)."""
    return float(clearances(robot, [shape])[0])


def clearances(robot: Footprint, shapes: list[Footprint]) -> np.ndarray:
    """`clearance` of the robot to each of `shapes`, all at once (an episode's every pose against
    every piece of furniture)."""
    out = np.empty(len(shapes))
    circles = [i for i, sh in enumerate(shapes) if sh.kind == "circle"]
    rects = [i for i, sh in enumerate(shapes) if sh.kind == "rect"]
    px, py = _rect_points(robot)
    for i, sh in enumerate(shapes):
        if sh.kind == "hull":  # the hull's outline against the robot, and the robot's against the hull
            verts = hull_outline(sh)
            hx, hy = _hull_points(verts)
            out[i] = min(float(_least_rect_dist(hx, hy, robot)), float(hull_distance(px, py, verts).min()))
    if circles:
        cx, cy = np.array([shapes[i].x for i in circles]), np.array([shapes[i].y for i in circles])
        out[circles] = _least_rect_dist(cx[:, None], cy[:, None], robot) - [shapes[i].r for i in circles]
    if rects:
        rs = [shapes[i] for i in rects]
        sx, sy = (np.stack(v) for v in zip(*(_rect_points(sh) for sh in rs), strict=True))
        to_robot = _least_rect_dist(sx, sy, robot)  # the shapes' outlines against the robot
        x, y, yaw, hx, hy = np.array([[sh.x, sh.y, sh.yaw, sh.hx, sh.hy] for sh in rs]).T[..., None]
        to_shape = _least_dist(px[None, :], py[None, :], x, y, yaw, hx, hy)  # our outline against each of theirs
        out[rects] = np.minimum(to_robot, to_shape)
    return out


def surface_distance(x: float, y: float, shape: Footprint) -> float:
    """A point (the robot's base centre) -> the object's surface: centre distance minus the radius,
    or the distance to a box's footprint or a hull's."""
    if shape.kind == "circle":
        return math.hypot(shape.x - x, shape.y - y) - shape.r
    if shape.kind == "hull":
        return float(hull_distance(np.array(x), np.array(y), hull_outline(shape)))
    return _rect_dist(x, y, shape)
