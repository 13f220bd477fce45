"""How far the tracked target is: the tracker's per-frame range fused with the scan and the object
memory, as one estimator (`TargetRanging`). Pure: no I/O; every call takes the time it is about.

    ranging = TargetRanging()
    d = ranging.base_distance(params, sighting, now, scan, camera_forward_m, remembered)
    ranging.ranged_by            # what the range came from: the tracker's method, "lidar" or "memory"

perception/ranging.py ranges one box in one frame (bottom edge, size); this module weighs that range
against what the world holds at the same moment:

- The scan. Near its target a range may be lost (the box's bottom edge leaves the image), or off (by
  an assumed size). The nearest scan return on the target's bearing (within `scan_cone_deg`) and
  within `scan_range_m` of the camera is the range wherever it is nearer than the tracker's (a
  farther one may be what is behind a small object), but not below `scan_agree` of it (base frame:
  a much nearer return is something else on the bearing, a door jamb with the object beyond it),
  and only where what it hits is the object's surface (`is_surface`): as wide as the box, the returns
  within `scan_depth_m` behind it spanning at least `scan_cover` of the box's angular width (a table
  leg is not the tray on it), and no wider: no returns within `surface_m` of its range beyond either
  edge of the box (past a gap of `past_gap_rad`, out to the box's width or `past_rad`), or it is a
  surface that runs on past the object (a bed before the toy chest behind it: the robot stopped
  0.84 m from the bed, 1.7 m from the chest; the wall behind a small object). An object against a
  wall at its own range loses the lidar, and is ranged by the tracker. A box that fills the view
  ("fills_view": near, not how near) takes the scan's return alike.
- The memory. The tracker's box can spread onto what stands before its object (a door leaf of the
  object's colour). A confident remembered object of the goal's label on the bearing (within
  `memory_cone_deg`, or half the box), seen in the last `memory_fresh_s`, whose surface lies more than
  `memory_far` times and `memory_gap_m` beyond the range, is the range (`remembered_on`), and it stands
  `memory_hold_s` after it last overruled while the tracker's range is still as far short of it.
- The go-to cap. A range by the object's size beyond a cap counts only once such ranges have held
  `far_hold_s` (`capped`): one frame of a sliver of the object can range it tens of metres away.

The object memory's placement (world/placement.py) asks the scan the same question of an answer's
box before a return ranges it (`is_surface`).

Distances are base centre -> the object's surface (m); the tracker's are camera -> surface, and the
camera sits `camera_forward_m` ahead of the base centre.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from go2vlm.declare import param
from go2vlm.geometry.scan import nearest_return
from go2vlm.world.labels import label_fits
from go2vlm.world.poses import Pose2D, wrap_angle

__all__ = [
    "SIZE_METHODS",
    "MemoryEntry",
    "RangingParams",
    "Reading",
    "TargetRanging",
    "as_wide",
    "is_surface",
    "remembered_on",
]

SIZE_METHODS = ("size", "default_size")  # the tracker's methods that range by the object's size
CUT_MARGIN = 0.02  # a box's edge within this share of the half field of view from the border is cut by it


class Reading(Protocol):
    """What the estimator reads of one tracker report (behavior's Sighting is one)."""

    @property
    def distance(self) -> float | None: ...  # camera -> near surface (m); None: not ranged

    @property
    def range_method(self) -> str: ...  # bottom | size | default_size | fills_view | none

    @property
    def bearing(self) -> float: ...  # rad from the camera's axis, + left; NaN: not known

    @property
    def width(self) -> float: ...  # rad: the box's angular width; NaN: not known

    @property
    def hfov(self) -> float: ...  # rad: the camera's field of view (a box's edge at its border is cut); NaN


class MemoryEntry(Protocol):
    """What the estimator reads of one remembered object (world/objects_msg.py's Remembered is one)."""

    @property
    def label(self) -> str: ...

    @property
    def x(self) -> float: ...  # its place (odometry frame, m)

    @property
    def y(self) -> float: ...

    @property
    def radius(self) -> float: ...  # m, from its centre to its surface

    @property
    def confidence(self) -> float: ...

    @property
    def last_seen(self) -> float: ...  # s, on the caller's clock


@dataclass(frozen=True)
class RangingParams:
    """The estimator's thresholds (module docstring; docs/goals.md, "Distance")."""

    scan_cone_deg: float = param(
        3.0, help="ranging: a scan return this near the target's bearing ranges it (deg)", min=0.1, max=30.0
    )
    scan_range_m: float = param(
        2.0, help="ranging: ... and this near the camera (m; farther, it may be what is behind it)", min=0.1,
        max=20.0,
    )  # fmt: skip
    scan_agree: float = param(
        0.45, help="ranging: ... and at least this share of the tracker's range (base frame)", min=0.0, max=1.0
    )
    scan_depth_m: float = param(
        0.25, help="ranging: the returns this far behind the nearest one are what it hits (m)", min=0.0, max=2.0
    )
    scan_cover: float = param(
        0.4, help="ranging: ... and must span this share of the box's angular width", min=0.0, max=1.0
    )
    surface_m: float = param(
        0.3, help="ranging: returns this near a return's range beyond an edge of the box make it a surface that "
        "runs on past the object (m) ...", min=0.0, max=2.0,
    )  # fmt: skip
    past_rad: float = param(
        0.1, help="ranging: ... looked for this far beyond each edge, or the box's width if wider (rad) ...", min=0.0,
        max=1.0,
    )  # fmt: skip
    past_gap_rad: float = param(
        0.035, help="ranging: ... past a gap of this (rad: the scan's edge blur, two of its 2-degree bins)", min=0.0,
        max=0.5,
    )  # fmt: skip
    far_hold_s: float = param(
        1.0, help="ranging: a range by size beyond the go-to cap counts once held this long (s)", min=0.0,
        max=30.0,
    )  # fmt: skip
    memory_cone_deg: float = param(
        5.0, help="ranging: a remembered object this near the bearing (or half the box) is on it (deg)", min=0.1,
        max=45.0,
    )  # fmt: skip
    memory_fresh_s: float = param(2.0, help="ranging: ... if seen in the last this long (s)", min=0.0, max=60.0)
    memory_far: float = param(
        2.0, help="ranging: ... and its surface lies more than this many times the range beyond", min=1.0,
        max=20.0,
    )  # fmt: skip
    memory_gap_m: float = param(
        1.5, help="ranging: ... and more than this beyond the range (m): then it is the range", min=0.0, max=20.0
    )
    memory_hold_s: float = param(
        3.0, help="ranging: the memory's range stands this long after it last overruled (s)", min=0.0, max=30.0
    )


@dataclass
class TargetRanging:
    """The fused range of one goal's target and what it keeps between steps: what the range came
    from last (`ranged_by`), when the memory last overruled the range and with what (`overruled`), and
    since when a range by size has put the target beyond the go-to cap (`far_since`). `forget` for a
    new goal."""

    ranged_by: str = ""  # the tracker's method, "lidar" or "memory"
    overruled: tuple[float, float] | None = None  # (when, the memory's range)
    far_since: float | None = None

    def forget(self) -> None:
        self.overruled = None
        self.far_since = None

    def base_distance(
        self,
        p: RangingParams,
        s: Reading,
        now: float,
        scan: np.ndarray | None,
        camera_forward_m: float,
        remembered: float | None = None,
    ) -> float | None:
        """Base centre -> the surface of the confirmed target of reading `s` (module docstring): the
        tracker's range, the scan's return on its bearing, or the memory's range `remembered` (the
        goal's remembered object on the bearing, `remembered_on`); None: not ranged. `scan`: fresh
        obstacle points in the base frame, or None."""
        cf = camera_forward_m
        own = s.distance if s.distance is not None and math.isfinite(s.distance) else None
        self.ranged_by = s.range_method
        if not math.isfinite(s.bearing):
            return None if own is None else own + cf
        cone = math.radians(p.scan_cone_deg)
        d = nearest_return(scan, (cf, 0.0), s.bearing - cone, s.bearing + cone)
        ref = None if s.range_method == "fills_view" else own  # "fills the view" says near, not how near
        agrees = (
            d is not None and d <= p.scan_range_m and (ref is None or p.scan_agree * (ref + cf) <= d + cf < ref + cf)
        )
        b_r, b_l = s.bearing - s.width / 2.0, s.bearing + s.width / 2.0
        border = s.hfov / 2.0 * (1.0 - CUT_MARGIN)  # NaN: not known, and no edge counts as cut
        cut = (s.range_method == "fills_view" or b_r <= -border, s.range_method == "fills_view" or b_l >= border)
        if agrees and d is not None and scan is not None and is_surface(p, scan, (cf, 0.0), d, b_r, b_l, cut):
            self.ranged_by, ranged = "lidar", d + cf
        elif own is None:
            return None
        else:
            ranged = own + cf

        def far(mem: float) -> bool:
            return mem > p.memory_far * ranged and mem > ranged + p.memory_gap_m

        if remembered is not None and far(remembered):
            self.overruled = (now, remembered)
        held = self.overruled
        if held is not None and 0.0 <= now - held[0] <= p.memory_hold_s and far(held[1]):
            self.ranged_by, ranged = "memory", held[1]
        return ranged

    def capped(self, p: RangingParams, d: float | None, method: str, cap: float, now: float) -> float | None:
        """A range `d` (base_distance's) as the go-to `cap` (m) judges it: a range by the object's size
        (`method`, the tracker's) beyond the cap counts only once such ranges have held `far_hold_s`."""
        if d is None or d <= cap or method not in SIZE_METHODS:
            self.far_since = None
            return d
        if self.far_since is None:
            self.far_since = now
        return d if now - self.far_since >= p.far_hold_s else None


def remembered_on(
    p: RangingParams,
    s: Reading,
    now: float,
    pose: Pose2D,
    memory: Sequence[MemoryEntry],
    label: str,
    min_confidence: float,
) -> float | None:
    """Base centre (at `pose`) -> the surface of the nearest remembered object of `label`, at least
    `min_confidence` sure and seen in the last `memory_fresh_s`, on the bearing of reading `s` (within
    `memory_cone_deg`, or half its box); None: none."""
    cone = max(math.radians(p.memory_cone_deg), s.width / 2.0 if math.isfinite(s.width) else 0.0)
    best: float | None = None
    for o in memory:
        if o.confidence < min_confidence or not 0.0 <= now - o.last_seen <= p.memory_fresh_s:
            continue
        if not label_fits(label, o.label):
            continue
        dx, dy = o.x - pose.x, o.y - pose.y
        if abs(wrap_angle(math.atan2(dy, dx) - pose.yaw - s.bearing)) <= cone:
            d = math.hypot(dx, dy) - o.radius
            best = d if best is None else min(best, d)
    return best


def as_wide(
    p: RangingParams, points: np.ndarray, origin: tuple[float, float], d: float, bearing: float, width: float
) -> bool:
    """Do the scan points `d`..`d` + scan_depth_m from `origin`, within the box's bearings, span at
    least scan_cover of its angular `width` (rad)? Each return stands for its bin (the scan's angular
    step, from the points, at most the scan cone): far away one return may be all an object gives.
    A box no wider than the scan cone, or of unknown width, passes."""
    cone = 2.0 * math.radians(p.scan_cone_deg)
    if not math.isfinite(width) or width <= cone:
        return True
    rel = np.asarray(points, dtype=float).reshape(-1, 2) - origin
    ang, rng = np.arctan2(rel[:, 1], rel[:, 0]), np.hypot(rel[:, 0], rel[:, 1])
    near = (rng >= d - 1e-6) & (rng <= d + p.scan_depth_m)
    hit = (np.abs(ang - bearing) <= width / 2.0) & near & (rel[:, 0] > 0.0)
    gaps = np.diff(np.unique(ang))
    step = min(float(np.median(gaps[gaps > 1e-9])), cone) if (gaps > 1e-9).any() else 0.0
    return bool(hit.any() and float(ang[hit].max() - ang[hit].min()) + step >= p.scan_cover * width)


def is_surface(
    p: RangingParams,
    points: np.ndarray,
    origin: tuple[float, float],
    d: float,
    b_r: float,
    b_l: float,
    cut: tuple[bool, bool] = (False, False),
) -> bool:
    """Is the scan's return at range `d` from `origin` the surface of the object in a box whose edges lie
    at bearings `b_r`..`b_l` (rad, + left): as wide as the box (`as_wide`) and no wider (no returns at
    about its range beyond either edge: a surface running on past the object, one side enough, as in a
    corner the other wall lies at another range)? An edge `cut` by the image's border (right, left) may
    run on: the object goes on out of view. A box of unknown width (NaN) asks only `as_wide`."""
    width = b_l - b_r
    if not as_wide(p, points, origin, d, (b_r + b_l) / 2.0, width):
        return False
    if not math.isfinite(width):
        return True
    rel = np.asarray(points, dtype=float).reshape(-1, 2) - origin
    ang, rng = np.arctan2(rel[:, 1], rel[:, 0]), np.hypot(rel[:, 0], rel[:, 1])
    at = (np.abs(rng - d) <= p.surface_m) & (rel[:, 0] > 0.0)
    reach = max(width, p.past_rad)
    left = at & (ang > b_l + p.past_gap_rad) & (ang <= b_l + reach) & (not cut[1])
    right = at & (ang < b_r - p.past_gap_rad) & (ang >= b_r - reach) & (not cut[0])
    return not bool(left.any() or right.any())
