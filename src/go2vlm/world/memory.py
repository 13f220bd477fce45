"""The object memory without any I/O: placed answers in, remembered objects out, driven by the
answers' own stamps so it can be tested exhaustively.

    memory = ObjectMemory(MemoryParams())
    memory.observe([placed, ...], View(stamp, camera_xy, camera_yaw, hfov, covers={"blue cylinder"}))
    memory.where_is("blue cylinder")      # the objects that fit, the most confident first

Rules
- Every object has a label, a world position with its covariance, a size, a log-odds of being there
  (`confidence` = its logistic, 0..1), how often it was seen, refused and missed, and when it was
  first and last seen (the stamps of the frames).
- A ranged sighting joins the nearest object of its label whose place it fits (a Mahalanobis distance
  within `gate_sigma`, or closer than `gate_min_m`; never farther than `gate_max_m`; one sighting per
  object per answer): a Kalman update of the position, so repeated answers tighten it, and `hit` on
  the log-odds. Its sigma never falls below `bias_fraction` of its sharpest sighting's (nor
  `min_sigma_m`): the errors of sightings from one place repeat, so a hundred from far away must not
  shut out the first one from close by. A sighting that fits no object starts a new one (log-odds
  `prior + hit`: confidence 0.5): a wrong answer far from the others never moves an object, it is
  counted as refused by the objects of that label it did not fit. A sighting less sure of its place
  than `new_max_sigma_m` (a bottom edge or a size read from far away: its error grows with the
  square of the range) starts nothing (`refused.uncertain`): placed wrong by a metre, far out or
  behind a wall, nothing the robot sees later would ever refute it. It still joins an object it fits.
  A bearing-only sighting (no range) confirms the object of its label along its bearings within
  `bearing_only_max_m`, and places nothing new.
- An answer is about some labels (`View.covers`; None: every label, as the sim's ground truth is).
  An object with such a label that the answer did not see although it should have -- its centre well
  inside the camera's view, its surface `view_min_m`..`view_max_m` away, not hidden behind a scan
  return or a nearer remembered object -- loses `miss` on the log-odds. Below `forget_below` it is
  forgotten. With hit 1.0 and miss 0.1 a detector that finds a visible object one time in ten still
  keeps it; a place seen empty eleven times forgets a single wrong sighting.
- Two objects of one label that come closer than `merge_m`, or within `gate_sigma` of each other's
  uncertainty, are merged: a first, far and rough sighting and the sharp ones from close by are one
  object (inverse-variance weighted).
- Bounded: at most `max_objects`. A new object when full replaces the least confident one if that
  one is less confident than a first sighting, else it is refused (`memory_full`).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from go2vlm.declare import param
from go2vlm.world.labels import label_fits
from go2vlm.world.placement import Placed
from go2vlm.world.poses import wrap_angle

__all__ = ["MemoryObject", "MemoryParams", "ObjectMemory", "View", "confidence_of"]


def confidence_of(logodds: float) -> float:
    return 1.0 / (1.0 + math.exp(-logodds))


@dataclass(frozen=True)
class MemoryParams:
    """The memory's settings; those declared with `param` are the object_memory node's parameters too
    (go2vlm/declare.py: the node takes them over with `from_core`)."""

    max_objects: int = param(64, help="objects remembered at most", min=1, max=10_000)
    gate_sigma: float = param(
        3.5, help="a sighting joins an object within this many sigmas", min=0.5, max=10.0, live=True
    )
    gate_min_m: float = param(0.5, help="... or this close (m)", min=0.0, max=5.0, live=True)
    gate_max_m: float = 2.0  # ... and never farther
    hit: float = param(1.0, help="log-odds a sighting adds", min=0.01, max=5.0, live=True)
    miss: float = param(
        0.1, help="log-odds an answer that should have seen it, and did not, takes", min=0.0, max=5.0, live=True
    )
    prior: float = -1.0  # log-odds before the first sighting (after it: 0, confidence 0.5)
    max_logodds: float = 4.0  # confidence 0.98: a long-remembered object can still be forgotten
    forget_below: float = param(-1.0, help="forgotten below this log-odds (-1: confidence 0.27)", min=-20.0,
                                max=-0.01, live=True)  # fmt: skip
    min_sigma_m: float = 0.03  # a position is never believed closer than this: new views still count
    bias_fraction: float = 0.6  # ... nor closer than this part of its best sighting's sigma (errors from
    # one view point repeat: many far sightings are no better than a few, and a near one must still fit)
    bearing_only_max_m: float = 3.0  # a sighting without range confirms an object this close
    view_margin_rad: float = 0.05  # a miss counts only with the object this far inside the view ...
    view_min_m: float = 0.5  # ... its surface at least this far from the camera ...
    view_max_m: float = param(
        5.0, help="... and at most this far: an object farther than this is not missed (m)", min=0.5, max=50.0,
        live=True,
    )  # fmt: skip
    occlusion_m: float = 0.3  # a scan return this much nearer, in front of it, hides it
    merge_m: float = 0.3  # two objects of one label closer than this are one
    new_max_sigma_m: float = param(
        0.5, help="a sighting less sure of its place than this (1 sigma, m) starts no new object", min=0.05,
        max=10.0, live=True,
    )  # fmt: skip

    def __post_init__(self) -> None:
        if self.max_objects < 1:
            raise ValueError(f"max_objects must be at least 1, got {self.max_objects}")
        if not (self.hit > 0 and self.miss >= 0 and self.forget_below < self.prior + self.hit <= self.max_logodds):
            raise ValueError("need hit > 0, miss >= 0 and forget_below < prior + hit <= max_logodds")


@dataclass
class MemoryObject:
    id: str
    label: str
    x: float
    y: float
    z: float  # the centre's height
    cov: tuple[float, float, float]  # xx, xy, yy (m^2)
    size: tuple[float, float, float]  # width, depth, height (m)
    logodds: float
    seen: int = 1
    refused: int = 0
    missed: int = 0
    first_seen: float = 0.0
    last_seen: float = 0.0
    best_sigma: float = math.inf  # its sharpest sighting's sigma (m): a floor for its own (not saved)

    @property
    def confidence(self) -> float:
        return confidence_of(self.logodds)

    @property
    def sigma(self) -> float:
        """The larger standard deviation of its position (m)."""
        return _max_sigma(self.cov)

    @property
    def radius(self) -> float:
        return max(self.size[0], self.size[1]) / 2.0


@dataclass(frozen=True)
class View:
    """The frame an answer describes: where the camera was and what the answer was about."""

    stamp: float
    camera: tuple[float, float]  # world
    yaw: float  # the camera's heading in the world
    hfov: float  # rad
    covers: frozenset[str] | None = None  # labels the answer was asked about; None: every label
    occluders: np.ndarray | None = None  # scan returns at that stamp, world frame (N, 2)


def _mahalanobis2(dx: float, dy: float, cov: tuple[float, float, float]) -> float:
    xx, xy, yy = cov
    det = xx * yy - xy * xy
    if det <= 1e-12:
        return math.inf
    return (yy * dx * dx - 2 * xy * dx * dy + xx * dy * dy) / det


def _sigma_of(cov: tuple[float, float, float]) -> float:
    return math.sqrt(max(0.0, (cov[0] + cov[2]) / 2.0))


def _max_sigma(cov: tuple[float, float, float]) -> float:
    """The larger standard deviation of a position covariance (m)."""
    xx, xy, yy = cov
    return math.sqrt(max(0.0, (xx + yy) / 2 + math.sqrt(((xx - yy) / 2) ** 2 + xy * xy)))


def _add(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    return a[0] + b[0], a[1] + b[1], a[2] + b[2]


@dataclass
class ObjectMemory:
    params: MemoryParams = field(default_factory=MemoryParams)

    def __post_init__(self) -> None:
        self.objects: dict[str, MemoryObject] = {}
        self.counters: Counter[str] = Counter()
        self._ids: Counter[str] = Counter()  # per label: the last id number handed out

    # -- queries ---------------------------------------------------------------------------------
    def snapshot(self) -> list[MemoryObject]:
        """Every object, copied, in id order."""
        return [replace(o) for _, o in sorted(self.objects.items())]

    def where_is(self, label: str) -> list[MemoryObject]:
        """The objects whose label `label` names (label_fits), exact names and confident ones first."""
        fits = [(label_fits(label, o.label), o) for o in self.objects.values()]
        return [replace(o) for f, o in sorted(fits, key=lambda fo: (-fo[0], -fo[1].confidence, fo[1].id)) if f > 0]

    # -- updates ---------------------------------------------------------------------------------
    def observe(self, sightings: Iterable[Placed], view: View) -> list[str]:
        """One answer: its sightings (labels normalised) about the frame `view`. Returns, per sighting,
        the id of the object it joined or started, or `refused.<reason>`."""
        touched: set[str] = set()
        out = []
        for s in sightings:
            self.counters["sightings"] += 1
            res = self._sighting(s, touched) if s.ranged else self._bearing_only(s, touched)
            if res.startswith("refused."):
                self.counters[res] += 1
            else:
                touched.add(res)
            out.append(res)
        self._misses(view, touched)
        for oid in sorted(touched):
            self._merge(oid)
        return out

    def load(self, objects: Iterable[MemoryObject]) -> None:
        """Replace everything with `objects` (a memory file, already checked), each clamped to what this
        memory allows: log-odds at most max_logodds, a position never surer than min_sigma_m."""
        p = self.params
        floor = p.min_sigma_m**2
        objs = [
            replace(o, logodds=min(o.logodds, p.max_logodds), cov=(max(floor, xx), xy, max(floor, yy)))
            for o in list(objects)[: p.max_objects]
            for xx, xy, yy in [o.cov]
        ]
        self.objects = {o.id: o for o in objs}
        self._ids = Counter()
        for o in objs:
            head, _, n = o.id.rpartition("_")
            if n.isascii() and n.isdigit():  # memory_file.py checks; this keeps load all or nothing anyway
                self._ids[head] = max(self._ids[head], int(n))

    def forget(self, oid: str) -> bool:
        return self.objects.pop(oid, None) is not None

    # -- internals -------------------------------------------------------------------------------
    def _sighting(self, s: Placed, touched: set[str]) -> str:
        p = self.params
        best, best_d2 = None, math.inf
        for o in self.objects.values():
            if o.label != s.label or o.id in touched:
                continue
            dx, dy = s.x - o.x, s.y - o.y
            e = math.hypot(dx, dy)
            d2 = _mahalanobis2(dx, dy, _add(o.cov, s.cov))
            if e <= p.gate_max_m and (d2 <= p.gate_sigma**2 or e <= p.gate_min_m) and d2 < best_d2:
                best, best_d2 = o, d2
        if best is not None:
            self._fuse(best, s)
            self.counters["fused"] += 1
            return best.id
        if _max_sigma(s.cov) > p.new_max_sigma_m:  # too unsure to say where it is: no new object
            return "refused.uncertain"
        for o in self.objects.values():  # a far answer: the objects of its label did not move
            if o.label == s.label and o.confidence >= 0.5:
                o.refused += 1
                self.counters["refused_by_objects"] += 1
        return self._new(s)

    def _bearing_only(self, s: Placed, touched: set[str]) -> str:
        p = self.params
        lo, hi = s.span
        best, best_d = None, math.inf
        for o in self.objects.values():
            if o.label != s.label or o.id in touched:
                continue
            dx, dy = o.x - s.camera[0], o.y - s.camera[1]
            d = math.hypot(dx, dy)
            if d - o.radius > p.bearing_only_max_m:
                continue
            b = math.atan2(dy, dx)
            slack = math.asin(min(1.0, o.radius / max(d, 1e-6))) + 0.05
            if wrap_angle(b - lo) >= -slack and wrap_angle(hi - b) >= -slack and d < best_d:
                best, best_d = o, d
        if best is None:
            return "refused.unranged"
        best.logodds = min(p.max_logodds, best.logodds + p.hit)
        best.seen += 1
        best.last_seen = max(best.last_seen, s.stamp)
        self.counters["confirmed_by_bearing"] += 1
        return best.id

    def _fuse(self, o: MemoryObject, s: Placed) -> None:
        p = self.params
        P = np.array([[o.cov[0], o.cov[1]], [o.cov[1], o.cov[2]]])
        R = np.array([[s.cov[0], s.cov[1]], [s.cov[1], s.cov[2]]])
        K = P @ np.linalg.inv(P + R)
        x = np.array([o.x, o.y]) + K @ np.array([s.x - o.x, s.y - o.y])
        P = (np.eye(2) - K) @ P
        P = (P + P.T) / 2
        o.best_sigma = min(o.best_sigma, _sigma_of(s.cov))
        floor = max(p.min_sigma_m, p.bias_fraction * o.best_sigma) ** 2
        o.x, o.y = float(x[0]), float(x[1])
        o.cov = (max(floor, float(P[0, 0])), float(P[0, 1]), max(floor, float(P[1, 1])))
        w = 1.0 / min(o.seen + 1, 10)  # sizes: a running mean over the last ~10 sightings
        o.size = (
            o.size[0] + w * (s.size[0] - o.size[0]),
            o.size[1] + w * (s.size[1] - o.size[1]),
            o.size[2] if s.size[2] is None else o.size[2] + w * (s.size[2] - o.size[2]),
        )
        o.z = o.size[2] / 2.0
        o.logodds = min(p.max_logodds, o.logodds + p.hit)
        o.seen += 1
        o.last_seen = max(o.last_seen, s.stamp)

    def _new(self, s: Placed) -> str:
        p = self.params
        if len(self.objects) >= p.max_objects:
            weakest = min(self.objects.values(), key=lambda o: (o.logodds, o.last_seen))
            if weakest.logodds >= p.prior + p.hit:
                return "refused.memory_full"
            del self.objects[weakest.id]
            self.counters["evicted"] += 1
        slug = "_".join(s.label.split()) or "object"
        self._ids[slug] += 1
        oid = f"{slug}_{self._ids[slug]}"
        floor = p.min_sigma_m**2
        height = s.size[2] if s.size[2] is not None else 2.0 * s.z
        self.objects[oid] = MemoryObject(
            oid, s.label, s.x, s.y, s.z, (max(floor, s.cov[0]), s.cov[1], max(floor, s.cov[2])),
            (s.size[0], s.size[1], height), p.prior + p.hit, first_seen=s.stamp, last_seen=s.stamp,
            best_sigma=_sigma_of(s.cov),
        )  # fmt: skip
        self.counters["new"] += 1
        return oid

    def expected_visible(self, o: MemoryObject, view: View) -> bool:
        """Should an answer about `view` have seen `o`? (The miss rule of the module docstring.)"""
        p = self.params
        dx, dy = o.x - view.camera[0], o.y - view.camera[1]
        d = math.hypot(dx, dy)
        surface = d - o.radius
        if not p.view_min_m <= surface <= p.view_max_m:
            return False
        b = math.atan2(dy, dx)
        half = math.asin(min(1.0, o.radius / max(d, 1e-6)))
        if abs(wrap_angle(b - view.yaw)) > view.hfov / 2 - max(p.view_margin_rad, 0.5 * half):
            return False
        if view.occluders is not None and len(view.occluders):
            rel = np.asarray(view.occluders, dtype=float).reshape(-1, 2) - view.camera
            ang = np.abs((np.arctan2(rel[:, 1], rel[:, 0]) - b + math.pi) % (2 * math.pi) - math.pi)
            near = np.hypot(rel[:, 0], rel[:, 1]) < surface - p.occlusion_m
            if np.any(near & (ang <= half)):
                return False
        for other in self.objects.values():
            if other.id == o.id or other.confidence < 0.5:
                continue
            ox, oy = other.x - view.camera[0], other.y - view.camera[1]
            od = math.hypot(ox, oy)
            if od + p.occlusion_m < d and abs(wrap_angle(math.atan2(oy, ox) - b)) <= math.asin(
                min(1.0, other.radius / max(od, 1e-6))
            ):
                return False
        return True

    def _misses(self, view: View, seen: set[str]) -> None:
        p = self.params
        for o in list(self.objects.values()):
            if o.id in seen or (view.covers is not None and o.label not in view.covers):
                continue
            if not self.expected_visible(o, view):
                continue
            o.logodds -= p.miss
            o.missed += 1
            self.counters["missed"] += 1
            if o.logodds < p.forget_below:
                del self.objects[o.id]
                self.counters["forgotten"] += 1

    def _merge(self, oid: str) -> None:
        o = self.objects.get(oid)
        if o is None:
            return
        for other in list(self.objects.values()):
            if other.id == o.id or other.label != o.label:
                continue
            dx, dy = other.x - o.x, other.y - o.y
            near = math.hypot(dx, dy) <= self.params.merge_m
            if not near and _mahalanobis2(dx, dy, _add(o.cov, other.cov)) > self.params.gate_sigma**2:
                continue
            keep, gone = (o, other) if (o.seen, -o.first_seen) >= (other.seen, -other.first_seen) else (other, o)
            w1, w2 = 1.0 / max(keep.cov[0] + keep.cov[2], 1e-9), 1.0 / max(gone.cov[0] + gone.cov[2], 1e-9)
            keep.x = (w1 * keep.x + w2 * gone.x) / (w1 + w2)
            keep.y = (w1 * keep.y + w2 * gone.y) / (w1 + w2)
            keep.cov = min(keep.cov, gone.cov, key=lambda c: c[0] + c[2])
            keep.best_sigma = min(keep.best_sigma, gone.best_sigma)
            keep.logodds = min(self.params.max_logodds, max(keep.logodds, gone.logodds))
            keep.seen += gone.seen
            keep.refused += gone.refused
            keep.missed += gone.missed
            keep.first_seen = min(keep.first_seen, gone.first_seen)
            keep.last_seen = max(keep.last_seen, gone.last_seen)
            del self.objects[gone.id]
            self.counters["merged"] += 1
            if gone is o:
                return
