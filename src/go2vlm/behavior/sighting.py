"""A target_tracker report as the mission sees it: `Sighting`, and `sighting_of`, the one place where a
TrackedTarget's box becomes a normalised offset (geometry/target.py's /detected_target convention:
x in -1..1 from the image centre, + right). Pure."""

from __future__ import annotations

import math
from dataclasses import dataclass

from go2vlm.geometry.camera import focal_length
from go2vlm.geometry.target import circle_target
from go2vlm.msgs.go2vlm_msgs import STATE_NAMES, TrackedTarget

__all__ = ["MAX_IMAGE_SIDE", "Sighting", "sighting_of"]

MAX_IMAGE_SIDE = 100_000  # a TrackedTarget claiming a bigger image is garbage


@dataclass(frozen=True)
class Sighting:
    """One target_tracker report (a TrackedTarget), as it arrived."""

    t: float  # arrival time on the node's clock
    label: str  # what the tracker tracks
    state: str  # idle | searching | tracking | lost | ungroundable
    x: float = math.nan  # box centre, -1..1 from the image centre (geometry/target.py); NaN without a box
    distance: float | None = None  # camera -> near surface (m)
    range_method: str = "none"
    bearing: float = math.nan  # rad from the camera's axis, + left (NaN: not known)
    hfov: float = math.nan  # the camera's horizontal field of view (rad) the tracker's bearings come from
    width: float = math.nan  # rad: the box's angular width (a centred pinhole of `hfov`; NaN: not known)

    @property
    def tracked(self) -> bool:
        return self.state == "tracking" and math.isfinite(self.x) and abs(self.x) <= 2.0


def sighting_of(msg: TrackedTarget, t: float) -> tuple[Sighting, str | None]:
    """A TrackedTarget -> a Sighting (a bad one says `lost`), and what was wrong with it, if anything."""
    hfov = float(msg.hfov_rad)  # the Mission takes only a plausible one
    state = STATE_NAMES.get(int(msg.state))
    if state is None:
        return Sighting(t, msg.label, "lost", hfov=hfov), f"unknown state {msg.state}"
    if state != "tracking":
        return Sighting(t, msg.label, state, hfov=hfov), None
    b, w, h = msg.bbox, int(msg.image_width), int(msg.image_height)
    vals = (b.center.position.x, b.center.position.y, b.size_x, b.size_y)
    if not all(math.isfinite(v) for v in vals) or b.size_x <= 0 or b.size_y <= 0:
        return Sighting(t, msg.label, "lost", hfov=hfov), f"a tracking report with a bad box {vals}"
    if not (0 < w <= MAX_IMAGE_SIDE and 0 < h <= MAX_IMAGE_SIDE):
        return Sighting(t, msg.label, "lost", hfov=hfov), f"a tracking report with a bad image size {w}x{h}"
    x, _, _ = circle_target(b.center.position.x, b.center.position.y, max(b.size_x, b.size_y) / 2.0, w, h)
    d = msg.distance_m
    distance = float(d) if math.isfinite(d) and 0.0 <= d < 1000.0 else None
    bearing = float(msg.bearing_rad) if math.isfinite(msg.bearing_rad) and abs(msg.bearing_rad) < math.pi else math.nan
    width = math.nan
    if math.isfinite(hfov) and 0.0 < hfov < math.pi:
        f = focal_length(w, hfov)
        u1, u2 = b.center.position.x - b.size_x / 2.0 - w / 2.0, b.center.position.x + b.size_x / 2.0 - w / 2.0
        width = math.atan(u2 / f) - math.atan(u1 / f)
    return Sighting(t, msg.label, "tracking", x, distance, msg.range_method[:32], bearing, hfov, width), None
