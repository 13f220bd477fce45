"""A grounded box -> a place in the world, at the pose of the frame it describes.

    placed = place("blue cylinder", (x1, y1, x2, y2), stamp, pose_at_stamp, camera, mount, ranger, scan_points)

An answer is about a frame with a stamp, and the robot's pose at that stamp is known (poses.py). The
box's bearing comes from the camera model (geometry/camera.py, built from the real CameraInfo), its
range from the monocular ranging of perception/ranging.py (the target_tracker's: bottom edge, then
calibrated size) and, where the scan taken at that stamp covers the box's bearings, from the lidar.
So a box placed 10 s after its frame, with the robot turned away since, lands where the object is.

Rules
- The box must be finite, at least `min_box_px` a side after clipping to the image, and not absurd
  (more than twice the image): else `bad_box`.
- Range, camera -> the object's near surface, horizontally: the ranging reading (a depth for the
  bottom edge of boxes and cylinders and for a box's width, a distance along the ray otherwise), or
  the nearest scan return within the box's bearings (the middle half of them) when it agrees with the
  monocular range (nearer or farther by at most `lidar_agree_m` or `lidar_agree_frac` of it: a
  bottom edge drawn a few pixels low, as a model's box often is, reads a cylinder 2.5 m away half a
  metre near) or when there is no monocular range and the return is within `lidar_only_max_m`; and
  only a return of the object's surface (world/ranging.py `is_surface`, the tracked target's rule):
  as wide as the box (not a table leg before a tray) and running on past neither of its edges at
  that range (the wall behind a small object below the scan, which a noisy bottom edge may happen
  to agree with, nearer or farther). Neither: a
  bearing-only sighting (`range_m` None), which can confirm an object already remembered along that
  bearing but places nothing new. So is a
  box whose scan return is much nearer than its monocular range (`hidden`: something in front hides
  its bottom edge), and a box cut by one side of the image (`cut`: its middle is not the object's),
  unless it is a ball or a cylinder more than half in view: its centre then lies a half-angle
  (asin(r / (range + r))) inside the edge the image did not cut.
- The object's centre is half its depth behind the near surface (a ball's or cylinder's radius, half a
  box's width), from the ranger's calibrated size.
- Uncertainty (1 sigma): range 5 cm + 1 % (lidar), 5 cm + 3 % of d^2 (bottom edge), 5 cm + 10 %
  (calibrated size), 10 cm + 25 % (a default size); bearing 0.02 rad + a tenth of the box's width.
  A range by size is the size over the box's width, so its error also grows as the box narrows: the
  range times `box_px_sigma` per side over the width in pixels. Far away a small object is a few
  pixels wide, and one pixel less read a mug 6 m away at 19 m; so unsure, it starts no object of its
  own (the memory's `new_max_sigma_m`) and moves the one it fits little.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from go2vlm.geometry.camera import PinholeCamera
from go2vlm.geometry.scan import nearest_return
from go2vlm.perception.ranging import RangeEstimator
from go2vlm.robot_profile import RobotProfile
from go2vlm.robot_profile import go2 as spec
from go2vlm.vocabulary.words import ROUND_SHAPES, SHAPES
from go2vlm.world.poses import Pose2D, wrap_angle
from go2vlm.world.ranging import SIZE_METHODS, RangingParams, is_surface

__all__ = ["CameraMount", "Placed", "PlacementError", "PlacementParams", "check_box", "place", "rebase"]

Box = tuple[float, float, float, float]  # x1, y1, x2, y2 in pixels
DEPTH_READINGS = {("box", "bottom"), ("cylinder", "bottom"), ("box", "size"), ("box", "default_size")}
RANGE_SIGMA = {  # method -> (a, b, power): sigma = a + b * d ** power
    "lidar": (0.05, 0.01, 1),
    "bottom": (0.05, 0.03, 2),
    "size": (0.05, 0.10, 1),
    "default_size": (0.10, 0.25, 1),
}


@dataclass(frozen=True)
class CameraMount:
    """The camera in the base frame (x forward, y left), its height above the floor and pitch (+ down)."""

    forward_m: float = spec.HEAD_CAMERA_POS[0]
    left_m: float = spec.HEAD_CAMERA_POS[1]
    height_m: float = spec.HEAD_CAMERA_HEIGHT
    pitch_rad: float = 0.0

    def floor_seen_from(self, fovy_rad: float) -> float:
        """How far ahead of the base centre (m) the frame's lower edge meets the floor: nearer, a
        small thing on the floor is below the picture."""
        down = fovy_rad / 2.0 + self.pitch_rad
        return self.forward_m + (self.height_m / math.tan(down) if down < math.pi / 2 else 0.0)

    @classmethod
    def of(cls, robot: RobotProfile) -> CameraMount:
        """The head camera of `robot`, as its profile has it (the one camera mount)."""
        cam = robot.head_camera
        return cls(cam.pos[0], cam.pos[1], robot.head_camera_height, math.radians(cam.pitch_deg))


@dataclass(frozen=True)
class PlacementParams:
    min_box_px: float = 2.0
    box_px_sigma: float = 1.0  # px: how far each side of a box may be off (a range by size over its width)
    border_px: float = 3.0  # a box edge this close to the image's side is cut by it
    lidar_agree_m: float = 0.5  # lidar and monocular ranges agree within this ...
    lidar_agree_frac: float = 0.35  # ... or within this fraction of the monocular range
    lidar_only_max_m: float = 2.0  # without a monocular range, a scan return this close is the object
    max_range_m: float = 15.0  # a place farther than this is absurd
    ranging: RangingParams = field(default_factory=RangingParams)  # is_surface's: the target's rule
    free_depth_m: float = 1.0  # an object of no known shape is taken no deeper than this (m)


@dataclass(frozen=True)
class Placed:
    """One grounded box, placed. World frame; `range_m` None: a bearing-only sighting (x, y NaN)."""

    label: str
    stamp: float
    x: float
    y: float
    z: float  # the centre's height
    cov: tuple[float, float, float]  # position covariance xx, xy, yy (m^2)
    size: tuple[float, float, float | None]  # width, depth, height (m); height None: not seen whole
    range_m: float | None  # camera -> the near surface, horizontal (m)
    bearing: float  # world direction from the camera to the box's centre (rad)
    span: tuple[float, float]  # world directions of the box's right and left edges (rad)
    method: str  # lidar | bottom | size | default_size | fills_view | cut | hidden | none
    camera: tuple[float, float]  # the camera's place in the world at that stamp

    @property
    def ranged(self) -> bool:
        return self.range_m is not None


class PlacementError(ValueError):
    """A box that cannot be placed; `reason` is a short word for the status counters."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason, self.detail = reason, detail


def check_box(box: Box, cam: PinholeCamera, min_px: float = 2.0) -> Box:
    """The box clipped to the image, or PlacementError(`bad_box`) for NaN, absurd or empty boxes."""
    if len(box) != 4 or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in box):
        raise PlacementError("bad_box", f"{box} is not four finite numbers")
    x1, y1, x2, y2 = (float(v) for v in box)
    w, h = cam.width, cam.height
    if x2 - x1 > 2 * w or y2 - y1 > 2 * h or x2 < x1 or y2 < y1:
        raise PlacementError("bad_box", f"{tuple(round(v) for v in box)} is absurd for a {w}x{h} image")
    x1, y1, x2, y2 = max(0.0, x1), max(0.0, y1), min(float(w), x2), min(float(h), y2)
    if x2 - x1 < min_px or y2 - y1 < min_px:
        raise PlacementError("bad_box", f"{tuple(round(v) for v in box)} has no area inside the {w}x{h} image")
    return x1, y1, x2, y2


def rebase(points: np.ndarray, from_pose: Pose2D, to_pose: Pose2D) -> np.ndarray:
    """(N, 2) points in the base frame at `from_pose` -> the base frame at `to_pose` (via the world)."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    c, s = math.cos(from_pose.yaw), math.sin(from_pose.yaw)
    wx = from_pose.x + c * p[:, 0] - s * p[:, 1] - to_pose.x
    wy = from_pose.y + s * p[:, 0] + c * p[:, 1] - to_pose.y
    c2, s2 = math.cos(to_pose.yaw), math.sin(to_pose.yaw)
    return np.column_stack([c2 * wx + s2 * wy, -s2 * wx + c2 * wy])


def _sigma(method: str, d: float, width_px: float, px_sigma: float) -> float:
    """The range's 1 sigma (m): the method's, and for a range by size, the box's width read off by
    `px_sigma` on each side (`width_px`: the box's width)."""
    a, b, n = RANGE_SIGMA.get(method, RANGE_SIGMA["default_size"])
    by_width = d * math.sqrt(2.0) * px_sigma / max(width_px, 1.0) if method in SIZE_METHODS else 0.0
    return a + b * d**n + by_width


def place(
    label: str,
    box: Box,
    stamp: float,
    pose: Pose2D,
    cam: PinholeCamera,
    mount: CameraMount,
    ranger: RangeEstimator,
    scan_points: np.ndarray | None = None,
    params: PlacementParams | None = None,
    pitch: float = 0.0,
) -> Placed:
    """`box` (pixels of `cam`'s image) about the frame taken at `pose` -> a Placed (module docstring).
    `ranger` is the label's range estimator (its size calibration carries across answers);
    `scan_points` the scan nearest the stamp, in the base frame at `pose`; `pitch` the body's then (rad,
    + nose down), added to the mount's. PlacementError: bad_box,
    out_of_range."""
    p = params or PlacementParams()
    x1, y1, x2, y2 = check_box(box, cam, p.min_box_px)
    shape = ranger.shape
    b_r, b_l = cam.bearing(x2), cam.bearing(x1)
    b_c = (b_r + b_l) / 2.0  # the centre's bearing: between the edge rays (exact for a round object)
    lat_c = math.tan(b_c)  # + left
    reading = ranger.estimate((x1, y1, x2, y2), cam, pitch)
    size_known = ranger.size
    if shape in ROUND_SHAPES:
        half_depth, width = size_known, 2.0 * size_known
    elif shape == "box":
        half_depth, width = size_known / 2.0, size_known
    else:  # free text: as wide as the box looks (set below), as deep as it is wide
        half_depth, width = 0.0, 0.0
    stretch = math.sqrt(1.0 + lat_c * lat_c)  # depth along the axis -> distance along the ray
    depth_reading = (shape or "box", reading.method) in DEPTH_READINGS
    mono: float | None = None  # camera -> near surface along the ray, horizontal
    if reading.distance is not None and reading.method != "fills_view":
        d = max(0.0, float(reading.distance))
        mono = d * stretch if depth_reading else d
    quarter = (b_l - b_r) / 4.0
    origin, ends = (mount.forward_m, mount.left_m), (b_r, b_l)
    cut = (x2 >= cam.width - p.border_px, x1 <= p.border_px)  # right, left: the object may go on out of view
    lidar = nearest_return(scan_points, origin, b_r + quarter, b_l - quarter)
    rng, method = mono, reading.method
    if lidar is not None and mono is not None and mono - lidar > max(p.lidar_agree_m, p.lidar_agree_frac * mono):
        rng, method = None, "hidden"  # something nearer along its bearings: its bottom edge may be the other's
    elif lidar is not None and (
        scan_points is None or not is_surface(p.ranging, scan_points, origin, lidar, *ends, cut)
    ):
        pass  # a surface narrower or wider than the box at that range (a leg, the wall behind): not the object
    elif lidar is not None:
        # Either side of the monocular range: the wall behind a small object is ruled out above (it runs
        # on past the box's edges), and a model's bottom edge errs both ways.
        agree = mono is not None and abs(mono - lidar) <= max(p.lidar_agree_m, p.lidar_agree_frac * mono)
        if agree or (mono is None and lidar <= p.lidar_only_max_m):
            rng, method = lidar, "lidar"
    if (x1 <= p.border_px) != (x2 >= cam.width - p.border_px):  # cut by one side of the image
        half = math.asin(min(1.0, size_known / (rng + size_known))) if rng is not None else 0.0
        if shape not in ROUND_SHAPES or rng is None or b_l - b_r < half:
            rng, method = None, "cut"  # its middle is not the object's, nor its width
        else:  # a round object more than half in view: its centre is a half-angle inside the uncut edge
            b_c = b_r + half if x1 <= p.border_px else b_l - half
            lat_c = math.tan(b_c)
            stretch = math.sqrt(1.0 + lat_c * lat_c)
    cx_w, cy_w = pose.to_world(mount.forward_m, mount.left_m)
    bearing = wrap_angle(pose.yaw + b_c)
    span = (wrap_angle(pose.yaw + b_r), wrap_angle(pose.yaw + b_l))
    height: float | None = None
    if shape == "ball":
        height = 2.0 * size_known
    elif y1 > 3.0 and rng is not None:  # the top is in the picture
        depth_near = rng / stretch
        top = math.atan((y1 - cam.cy) / cam.fy) + mount.pitch_rad + pitch  # below the horizon
        height = max(0.0, mount.height_m - depth_near * math.tan(top))
    if shape not in SHAPES:
        width = max(0.05, (rng if rng is not None else 1.0) * (math.tan(b_l) - math.tan(b_r)))
        # How deep it is, the picture does not show: no deeper than it is wide or (seen whole) tall, nor
        # than free_depth_m; cut by both sides of the image (a wall across the view), only its face is known
        across = x1 <= p.border_px and x2 >= cam.width - p.border_px
        half_depth = 0.0 if across else min(width, height if height else width, p.free_depth_m) / 2.0
    if rng is None:
        return Placed(label, stamp, math.nan, math.nan, math.nan, (math.inf, 0.0, math.inf),
                      (width, width, height), None, bearing, span, method, (cx_w, cy_w))  # fmt: skip
    if rng > p.max_range_m:
        raise PlacementError("out_of_range", f"{label!r} would be {rng:.1f} m away")
    if method != "lidar" and depth_reading:  # exact for a cylinder: its centre is a radius deeper
        fwd = float(reading.distance or 0.0) + half_depth
        centre = fwd * stretch
    else:
        centre = rng + half_depth
    x, y = cx_w + centre * math.cos(bearing), cy_w + centre * math.sin(bearing)
    s_r = _sigma(method, rng, x2 - x1, p.box_px_sigma)
    s_b = 0.02 + 0.1 * (b_l - b_r)
    s_t = centre * s_b
    c, s = math.cos(bearing), math.sin(bearing)
    cov = (c * c * s_r**2 + s * s * s_t**2, c * s * (s_r**2 - s_t**2), s * s * s_r**2 + c * c * s_t**2)
    z = (height if height is not None else mount.height_m) / 2.0
    return Placed(label, stamp, x, y, z, cov, (width, width, height), rng, bearing, span, method, (cx_w, cy_w))
