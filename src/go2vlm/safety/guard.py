"""The collision guard: the safety gate's last word on a command, from the range scan. Pure, driven by
explicit timestamps, like SafetyCore (safety/mux.py), which applies it to every output.

    guard = CollisionGuard(GuardConfig(margin=0.05, margin_per_speed_s=0.4))
    guard.scan(Scan("base_link", ranges, angle_min, angle_increment, range_min, range_max), now)
    out = guard.limit(Velocity(0.5, 0, 0), now, limits)   # the command, scaled down or as it is

Rules
- Stopping, not steering: the guard only scales a command down, all components by one factor in
  [0, 1], so the robot keeps its direction (the arc of its twist) and only its speed drops. It never
  raises anything, whatever it is given.
- The margin is the clearance rule (geometry/footprint.py `Clearance`), the one the planners keep:
  `margin` at a creep, `margin_per_speed_s` more per m/s of the footprint's fastest point (linear
  speed plus turn rate times the corner radius) at the scaled command. A creep keeps a few
  centimetres, so a Go2 walks through a 0.8 m doorway square-on (0.245 m each side); at 0.5 m/s the
  defaults keep 0.25 m.
- With a fresh scan: the command passes at the largest scale s at which the robot can still stop
  before any obstacle comes within the margin at s of its footprint. The stopping path is the command's own
  arc (forward, sideways, turning: the footprint rectangle sweeps as it turns): first `reaction_s` plus
  the scan's age at speed s*v (the robot moves before it hears the next command, and moved since the
  scan), then braking at the deceleration the gate's acceleration limits allow (linear and angular
  brake together, the slower sets the time). The path is checked every `step` (1 cm) of footprint
  travel, with the margin widened by that step so that nothing is missed between checks. The scale
  is bisected (the stopping path grows and the margin widens with it: both only tighten as s grows).
- With an obstacle already inside the margin (the robot was placed or pushed there), the rule is that
  the footprint's clearance never drops below what it is now: the robot can always back away, and
  move past a post beside it, never closer. (Along a wall inside the margin this may refuse more than
  it must: the wall's beams are not quite in line. No slack is given there: each scan would allow a
  little more, and a steady command would creep into the wall.)
- Blind: no scan yet, a scan older than `scan_timeout_s`, or a scan that is garbage (NaN/-inf or
  negative ranges, no beams, a broken geometry, another frame than `frame`): the command is capped so
  that no point of the footprint moves faster than `blind_speed` (linear speed plus turn rate times
  the footprint's corner radius). A garbage scan also throws the previous one away.
- +inf ranges are REP 117 "nothing within range_max": free space. A sensor that sees nothing at all
  publishes no scan (msgs/pointcloud.py), and the guard goes blind after scan_timeout_s.
- `state` says what the guard did on the last call: mode (clear, limited, blind, off), why, the scale,
  the nearest obstacle in the path; /safety/status carries it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from go2vlm.declare import from_core, param
from go2vlm.geometry.footprint import Clearance, rect_distance
from go2vlm.geometry.scan import frame_scan_points
from go2vlm.robot_profile import DEFAULT_ROBOT, PROFILES, RobotProfile
from go2vlm.safety.limits import ZERO, Limits, Velocity

__all__ = ["CollisionGuard", "GuardConfig", "GuardState", "Scan", "stop_path", "twist_pose"]

MAX_SAMPLES = 600  # path checks per call; beyond this the step grows (and the margin with it)
TINY = 1e-3  # m/s, rad/s: a scaled command below this is a stop


@dataclass(frozen=True)
class GuardConfig:
    # Declared with `param`: the safety gate's parameters too (read-only).
    # The clearance rule's (one rule: the planners keep it too); not live here: the gate reads it at start.
    margin: float = from_core(Clearance, "creep_m", live=False)
    margin_per_speed_s: float = from_core(Clearance, "per_speed_s", live=False)
    blind_speed: float = param(
        0.2, help="guard: fastest footprint point (m/s) without a fresh, valid scan", min=0.0, max=1.0
    )
    scan_timeout_s: float = param(0.5, help="guard: a scan older than this (s) is no scan", min=0.05, max=5.0)
    reaction_s: float = param(
        0.1, help="guard: time (s) the robot keeps going before it brakes (gate tick + robot latency)",
        min=0.0, max=2.0,
    )  # fmt: skip
    half_length: float = PROFILES[DEFAULT_ROBOT].footprint_length / 2
    half_width: float = PROFILES[DEFAULT_ROBOT].footprint_width / 2
    frame: str = PROFILES[DEFAULT_ROBOT].frames.base
    step: float = 0.01  # m of footprint travel between path checks

    @classmethod
    def of(cls, robot: RobotProfile, **kw: float) -> GuardConfig:
        """The guard of `robot`: its footprint and base frame, with these settings."""
        return cls(
            half_length=robot.footprint_length / 2,
            half_width=robot.footprint_width / 2,
            frame=robot.frames.base,
            **kw,
        )

    def __post_init__(self) -> None:
        for name in (
            "margin",
            "margin_per_speed_s",
            "blind_speed",
            "scan_timeout_s",
            "reaction_s",
            "half_length",
            "half_width",
            "step",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"guard {name} must be a finite number >= 0, got {v}")
        if self.step <= 0 or self.scan_timeout_s <= 0:
            raise ValueError("guard step and scan_timeout_s must be positive")

    @property
    def corner(self) -> float:
        return math.hypot(self.half_length, self.half_width)

    @property
    def clearance(self) -> Clearance:
        return Clearance(creep_m=self.margin, per_speed_s=self.margin_per_speed_s)


@dataclass(frozen=True)
class Scan:
    frame_id: str
    ranges: list[float] | np.ndarray
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float


@dataclass
class GuardState:
    mode: str = "blind"  # clear | limited | blind | off
    reason: str = "no scan yet"
    scale: float = 1.0
    nearest_m: float | None = None  # nearest obstacle within reach of the stopping path, from the footprint
    scan_age_s: float | None = None

    def as_dict(self) -> dict[str, object]:
        return {
            "mode": self.mode,
            "reason": self.reason,
            "scale": round(self.scale, 3),
            "nearest_m": None if self.nearest_m is None else round(self.nearest_m, 3),
            "scan_age_s": None if self.scan_age_s is None else round(self.scan_age_s, 3),
        }


def twist_pose(v: Velocity, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses (x, y, yaw) after moving with the constant twist `v` for times `p` (an array)."""
    th = v.wz * p
    if abs(v.wz) < 1e-9:
        return v.vx * p, v.vy * p, th
    s, c = np.sin(th), 1.0 - np.cos(th)
    return (v.vx * s - v.vy * c) / v.wz, (v.vx * c + v.vy * s) / v.wz, th


def stop_path(v: Velocity, reaction: float, limits: Limits) -> tuple[float, float]:
    """(t_r, c): the robot commanded `s*v` stops after moving like `v` for t_r*s + c*s^2 seconds of twist
    time: t_r*s at speed, then braking (both parts of the twist brake together in the slower time)."""
    lin = math.hypot(v.vx, v.vy)
    t_stop = max(lin / max(limits.accel_linear, 1e-9), abs(v.wz) / max(limits.accel_angular, 1e-9))
    return reaction, t_stop / 2.0


@dataclass
class CollisionGuard:
    config: GuardConfig = field(default_factory=GuardConfig)
    enabled: bool = True

    def __post_init__(self) -> None:
        self._points: np.ndarray | None = None  # (N, 2) in the base frame
        self._t: float | None = None
        self._why_blind = "no scan yet"
        self.state = GuardState() if self.enabled else GuardState("off", "guard disabled")
        self.counters: dict[str, int] = {}

    def _count(self, key: str) -> None:
        self.counters[key] = self.counters.get(key, 0) + 1

    # -- input -------------------------------------------------------------------------------
    def scan(self, scan: Scan, now: float) -> str | None:
        """Take a scan received at `now`; returns why it is garbage (then the guard is blind), or None."""
        try:
            pts = frame_scan_points(
                self.config.frame, scan.frame_id, scan.ranges, scan.angle_min, scan.angle_increment,
                scan.range_min, scan.range_max,
            )  # fmt: skip
        except (ValueError, TypeError, OverflowError) as exc:
            self._count("scans_rejected")
            self._points, self._t, self._why_blind = None, None, f"last scan rejected: {exc}"
            return str(exc)
        self._points, self._t = pts, now
        self._count("scans")
        return None

    # -- output ------------------------------------------------------------------------------
    def blind(self, now: float) -> str | None:
        """Why the guard has no usable scan at `now`, or None."""
        if self._points is None or self._t is None:
            return self._why_blind
        age = now - self._t
        if not 0.0 <= age <= self.config.scan_timeout_s:
            return f"no /scan for {age:.2f} s (scan_timeout_s {self.config.scan_timeout_s:g})"
        return None

    def limit(self, v: Velocity, now: float, limits: Limits) -> Velocity:
        """`v` scaled so that the robot can stop short of every obstacle less the margin."""
        if not self.enabled:
            return v
        cfg = self.config
        age = None if self._t is None else now - self._t
        why = self.blind(now)
        if why is not None:
            point_speed = math.hypot(v.vx, v.vy) + abs(v.wz) * cfg.corner
            s = 1.0 if point_speed <= cfg.blind_speed else cfg.blind_speed / point_speed
            self.state = GuardState("blind", f"blind, capped at {cfg.blind_speed:g} m/s: {why}", s, None, age)
            return self._scaled(v, s)
        if v.is_zero:
            self.state = GuardState("clear", "", 1.0, None, age)
            return v
        assert self._points is not None and age is not None
        s, nearest = self._path_scale(v, cfg.reaction_s + max(age, 0.0), limits)
        if s >= 1.0:
            self.state = GuardState("clear", "", 1.0, nearest, age)
            return v
        kept = cfg.clearance.at(s * (math.hypot(v.vx, v.vy) + abs(v.wz) * cfg.corner))
        reason = (
            f"obstacle {nearest:.2f} m from the footprint in the path: slowed to {s:.0%} to stop {kept:.2f} m short"
            if nearest is not None
            else "obstacle in the path"
        )
        self.state = GuardState("limited", reason, s, nearest, age)
        return self._scaled(v, s)

    @staticmethod
    def _scaled(v: Velocity, s: float) -> Velocity:
        s = min(max(s, 0.0), 1.0)
        out = Velocity(v.vx * s, v.vy * s, v.wz * s)
        if math.hypot(out.vx, out.vy) < TINY and abs(out.wz) < TINY:
            return ZERO
        return out

    def _path_scale(self, v: Velocity, reaction: float, limits: Limits) -> tuple[float, float | None]:
        """The largest scale in [0, 1] whose stopping path keeps the margin, and the nearest obstacle
        on the full-speed stopping path (footprint clearance, m), None when there is none."""
        cfg = self.config
        tr, c = stop_path(v, reaction, limits)
        p1 = tr + c  # twist time to stop from full speed
        speed = math.hypot(v.vx, v.vy) + abs(v.wz) * cfg.corner  # fastest footprint point
        clear = cfg.clearance
        reach = p1 * speed + clear.at(speed) + cfg.corner + cfg.step
        pts = self._points
        assert pts is not None
        pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= reach]
        if len(pts) == 0:
            return 1.0, None
        n = max(1, math.ceil(p1 * speed / cfg.step))
        step = cfg.step
        if n > MAX_SAMPLES:
            n, step = MAX_SAMPLES, p1 * speed / MAX_SAMPLES
        p = np.linspace(0.0, p1, n + 1)
        x, y, th = twist_pose(v, p)
        # Obstacles in the robot frame at each pose: (n+1, N).
        dx, dy = pts[None, :, 0] - x[:, None], pts[None, :, 1] - y[:, None]
        cs, sn = np.cos(th)[:, None], np.sin(th)[:, None]
        lx, ly = cs * dx + sn * dy, -sn * dx + cs * dy
        d = rect_distance(lx, ly, cfg.half_length, cfg.half_width)
        now = float(d[0].min())
        nearest_ahead = np.minimum.accumulate(d.min(axis=1))  # the nearest up to each sample

        def keeps(scale: float) -> bool:
            """Does the stopping path of `scale` * v keep the margin at that speed (or what it has now)?"""
            # the samples on it, and the first one past its end (nothing is missed between two)
            reached = min(int(np.searchsorted(p, tr * scale + c * scale * scale, side="left")) + 1, len(p))
            thr = min(clear.at(scale * speed) + step, now)  # inside the margin already: never closer than now
            return bool(nearest_ahead[max(reached - 1, 0)] >= thr - 1e-9)

        if keeps(1.0):
            return 1.0, now
        lo, hi = 0.0, 1.0
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if keeps(mid) else (lo, mid)
        return lo, now
