"""The target_tracker's logic without any I/O: grounding answers in, one confirmed target per camera
frame out, driven by the frames' own stamps so it can be tested exhaustively.

    tracking = TargetTracking(TrackingParams(grounding="vlm"))
    tracking.set_query("blue cylinder")
    obs = tracking.on_frame(stamp, bgr, camera)            # every camera frame, in stamp order
    why = tracking.add_answer(Grounding(stamp, (("blue cylinder", (x1, y1, x2, y2)),)))  # a VLM answer

Rules
- The query is a label: "<colour> <shape>" in the vocabulary's words (vocabulary/words.py: COLORS, SHAPES;
  either may be left out) or free text for a VLM ("person"). No query: `idle`. A free-text
  query with the colour-shape grounder: `ungroundable` (it cannot find it), never a box.
- Grounding answers: `grounding="color"` runs the colour-shape grounder (perception/grounding.py) on
  a frame whenever there is no track, and every `reground_period_s` (frame stamps) while tracking;
  `grounding="vlm"` takes answers from outside (the vlm node's /vlm/detections) through `add_answer`.
- An answer describes an older frame. The tracker keeps the last `history` frames, seeds on the
  frame with the answer's stamp, confirms the seed on that frame and fast-forwards through the frames
  since, so the box is where the object is now. An answer about a frame not received yet waits for
  it (the newest such answer wins).
- Nothing unconfirmed is reported. An answer is refused, counted (`refused.<reason>`) and changes
  nothing when no box matches the query's label (`no_match`), when a matching box does not hold the
  colour the label names (`color_mismatch`: at least `min_label_color` of its pixels must be that
  colour), when it holds nothing the tracker can follow (`untrackable`), when the track is lost
  while catching up (`lost_in_catch_up`), when it is older than `max_answer_age_s` or than every
  stored frame (`stale`), or when its box is not finite and positive (`bad_box`).
- A track is `tracking` (with the box of this very frame) while the CamShift tracker (perception/
  tracker.py) follows it. When it loses it, or no answer has confirmed it for `max_grounding_age_s`,
  or `max_unconfirmed_answers` VLM answers in a row did not confirm it, it is `lost`: no box, never
  the last box, until an answer grounds it again. Before the first confirmed box it is `searching`.
- A new query drops everything of the old one (track, pending answer, range calibration).
- Ranging (perception/ranging.py) measures each tracked box, and the camera model (the frame's
  CameraInfo) gives its centre's bearing; `grounding_age` is the frame's stamp minus the stamp of the
  frame the last accepted answer described.
- The colour grounder's own answers (`grounding="color"`: each run, the frame's stamp and the box it
  found for the query, or None) are kept in `color_answers` until the caller takes them, so that they
  can be published like a VLM's (the object memory places them).
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass

import numpy as np

from go2vlm.declare import param
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.perception.grounding import ground
from go2vlm.perception.ranging import DEFAULT_SIZES, RangeEstimator
from go2vlm.perception.tracker import HistTracker
from go2vlm.robot_profile.go2 import HEAD_CAMERA_HEIGHT
from go2vlm.vocabulary.pixels import color_in_box, label_color_mask
from go2vlm.vocabulary.words import Label, label_match, parse_label

__all__ = [
    "STATES",
    "Box",
    "Grounding",
    "Observation",
    "TargetTracking",
    "TrackingParams",
]

Box = tuple[float, float, float, float]  # x1, y1, x2, y2 in pixels
STATES = ("idle", "searching", "tracking", "lost", "ungroundable")
STAMP_EPS_S = 1e-6  # stamps this close are the same frame's (float seconds from sec + nanosec)


@dataclass(frozen=True)
class Grounding:
    """One grounding answer: labelled boxes (pixels) about the frame stamped `stamp` (0: unknown)."""

    stamp: float
    boxes: tuple[tuple[str, Box], ...]


@dataclass(frozen=True)
class Observation:
    """The target in one frame: a box only while `state == "tracking"`."""

    stamp: float
    label: str
    state: str  # one of STATES
    box: Box | None
    width: int
    height: int
    confidence: float = 0.0
    distance: float | None = None  # camera -> near surface (m)
    range_method: str = "none"
    grounding_age: float | None = None  # s; None before any accepted answer for this query
    bearing: float | None = None  # the box centre's bearing from the optical axis (rad, + left); None: no camera


@dataclass(frozen=True)
class TrackingParams:
    """The tracking rules' settings; those declared with `param` are the target_tracker's parameters too
    (go2vlm/declare.py: the node takes them over with `from_core`)."""

    grounding: str = param("color", choices=("color", "vlm"), help="color: no model; vlm: /vlm/detections")
    reground_period_s: float = param(0.5, help="color: re-ground this often while tracking", min=0.0)
    min_shape_score: float = param(0.35, help="color: shape score the grounder needs", min=0.0, max=1.0)
    min_label_color: float = param(
        0.15, help="an answer's box must hold this fraction of the colour its label names", min=0.0, max=1.0
    )
    max_answer_age_s: float = param(
        5.0, help="refuse answers about frames older than this (vs the newest frame)", min=0.1, max=60.0
    )
    max_grounding_age_s: float = param(
        15.0, help="drop a track no answer confirmed for this long (0 = never)", min=0.0, max=600.0
    )
    max_unconfirmed_answers: int = param(
        3, help="vlm: drop a track this many answers in a row did not confirm (0 = never)", min=0, max=100
    )
    stamp_tolerance_s: float = 0.15  # an answer's frame: the stored frame closest to its stamp, this close
    history: int = 40  # frames kept for catching up (4 s at 10 Hz)
    camera_height_m: float = HEAD_CAMERA_HEIGHT  # the node's: its robot profile's head camera
    camera_pitch_rad: float = 0.0
    object_sizes: dict[str, float] = param(
        DEFAULT_SIZES, help="ranging before calibration: ball/cylinder radius, box width (m)"
    )

    def __post_init__(self) -> None:
        if self.grounding not in ("color", "vlm"):
            raise ValueError(f"grounding {self.grounding!r} is not color or vlm")


def _finite_box(box: Box) -> bool:
    x1, y1, x2, y2 = box
    return all(math.isfinite(v) for v in box) and x2 - x1 > 1.0 and y2 - y1 > 1.0


def _xywh(box: Box) -> tuple[float, float, float, float]:
    return box[0], box[1], box[2] - box[0], box[3] - box[1]


def _iou(a: Box, b: Box) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


class TargetTracking:
    """See the module docstring. Not thread-safe: one caller (the node's executor thread)."""

    def __init__(self, params: TrackingParams | None = None) -> None:
        self.params = params or TrackingParams()
        self.counters: Counter[str] = Counter()
        self.last_refusal = ""
        self.query: Label | None = None
        self._tracker = HistTracker()
        self._history: deque[tuple[float, np.ndarray]] = deque(maxlen=max(1, self.params.history))
        self._pending: Grounding | None = None
        self._box: Box | None = None  # the track in the newest frame
        self._confidence = 0.0
        self._ever_tracked = False
        self._confirmed: float | None = None  # stamp of the frame the last accepted answer described
        self._last_ground = -math.inf  # color: stamp of the last grounder run while tracking
        self._misses = 0
        self._ranger = RangeEstimator(None)
        self.color_answers: list[tuple[float, Box | None]] = []  # (frame stamp, box or None), taken by the caller

    # -- inputs --------------------------------------------------------------------------------
    def set_query(self, text: str) -> None:
        """Track `text` from now on ('' = nothing). The same query again changes nothing."""
        text = " ".join(str(text).split())
        if self.query is not None and text == self.query.text:
            return
        self.query = parse_label(text) if text else None
        self._drop_track()
        self._ever_tracked = False
        self._confirmed = None
        self._pending = None
        self._last_ground = -math.inf
        p = self.params
        sizes = {k: float(v) for k, v in p.object_sizes.items()}
        shape = self.query.shape if self.query else None
        self._ranger = RangeEstimator(
            shape, camera_height=p.camera_height_m, camera_pitch=p.camera_pitch_rad, default_sizes=sizes
        )

    @property
    def state(self) -> str:
        q = self.query
        if q is None:
            return "idle"
        if self.params.grounding == "color" and not q.classical:
            return "ungroundable"
        if self._box is not None:
            return "tracking"
        return "lost" if self._ever_tracked else "searching"

    def add_answer(self, answer: Grounding) -> str | None:
        """A grounding answer (vlm). None if it was accepted or waits for its frame, else why it was refused."""
        if self.query is None or self.state == "ungroundable":
            self.counters["answers_without_query"] += 1
            return None
        self.counters["answers"] += 1
        if self._history and answer.stamp > 0 and answer.stamp > self._history[-1][0] + STAMP_EPS_S:
            if self._pending is not None:
                self.counters["answers_replaced"] += 1
            self._pending = answer  # about a frame that has not arrived yet
            return None
        if not self._history:
            return self._refuse("stale", "no camera frame stored yet", miss=False)
        return self._apply(answer)

    def on_frame(self, stamp: float, bgr: np.ndarray, camera: PinholeCamera | None = None,
                 pitch: float = 0.0) -> Observation:  # fmt: skip
        """The next camera frame (stamps increasing): follow the target into it and report it; `pitch`:
        the body's then (rad, + nose down), for ranging."""
        h, w = bgr.shape[:2]
        if self._history and self._history[-1][1].shape != bgr.shape:
            self.counters["image_size_changed"] += 1
            self._history.clear()
            self._drop_track()
        self._history.append((stamp, bgr))
        seeded = False
        if self._pending is not None and self._pending.stamp <= stamp + STAMP_EPS_S:
            pending, self._pending = self._pending, None
            seeded = self._apply(pending) is None
        if not seeded and self._box is not None:
            track = self._tracker.update(bgr)
            if track is None:
                self.counters["tracks_lost"] += 1
                self._drop_track()
            else:
                self._box, self._confidence = track.xyxy, track.confidence
        p = self.params
        due = self._box is None or stamp - self._last_ground >= p.reground_period_s
        if p.grounding == "color" and self.state in ("searching", "lost", "tracking") and due:
            self._ground_color(stamp, bgr)
        confirmed = self._confirmed if self._confirmed is not None else math.inf
        if self._box is not None and p.max_grounding_age_s > 0 and stamp - confirmed > p.max_grounding_age_s:
            self.counters["tracks_dropped.stale_grounding"] += 1
            self._drop_track()
        return self._observe(stamp, w, h, camera, pitch)

    # -- internals -----------------------------------------------------------------------------
    def _drop_track(self) -> None:
        self._tracker.reset()
        self._box = None
        self._confidence = 0.0
        self._misses = 0

    def _refuse(self, reason: str, detail: str, *, miss: bool = True) -> str:
        self.counters[f"refused.{reason}"] += 1
        self.last_refusal = f"{reason}: {detail}"
        if miss and self._box is not None and self.params.grounding == "vlm":
            self._misses += 1
            n = self.params.max_unconfirmed_answers
            if n > 0 and self._misses >= n:
                self.counters["tracks_dropped.unconfirmed"] += 1
                self._drop_track()
        return reason

    def _label_mask(self, bgr: np.ndarray) -> np.ndarray | None:
        """The pixels of the colour the query names (None: it names none)."""
        color = self.query.color if self.query else None
        return None if color is None else label_color_mask(bgr, color)

    def _frame_index(self, stamp: float) -> int | None:
        frames = self._history
        if stamp <= 0:
            return len(frames) - 1  # an unstamped answer: about the newest frame
        i = min(range(len(frames)), key=lambda k: abs(frames[k][0] - stamp))
        return i if abs(frames[i][0] - stamp) <= self.params.stamp_tolerance_s else None

    def _apply(self, answer: Grounding) -> str | None:
        assert self.query is not None
        p = self.params
        newest = self._history[-1][0]
        if answer.stamp > 0 and newest - answer.stamp > p.max_answer_age_s:
            return self._refuse("stale", f"about a frame {newest - answer.stamp:.2f} s old", miss=False)
        idx = self._frame_index(answer.stamp)
        if idx is None:
            return self._refuse("stale", "its frame is no longer stored", miss=False)
        scored = [(label_match(self.query, label), label, box) for label, box in answer.boxes]
        matching = [(s, label, box) for s, label, box in scored if s > 0]
        if not matching:
            labels = sorted({label for _, label, _ in scored})
            return self._refuse("no_match", f"no box labelled {self.query.text!r} (got {labels})")
        frame = self._history[idx][1]
        h, w = frame.shape[:2]
        mask = self._label_mask(frame)
        candidates = []
        reason, detail = "bad_box", "no finite box of positive size"
        for score, label, box in sorted(matching, key=lambda m: -m[0]):
            if not _finite_box(box):
                continue
            x1, y1 = max(0.0, box[0]), max(0.0, box[1])
            x2, y2 = min(float(w), box[2]), min(float(h), box[3])
            if x2 - x1 < 2 or y2 - y1 < 2:
                reason, detail = "bad_box", f"{box} is outside the {w}x{h} image"
                continue
            frac = 1.0
            if mask is not None and self.query.color is not None:
                frac, why = color_in_box(
                    mask, (x1, y1, x2, y2), label=label, color=self.query.color, min_fraction=p.min_label_color,
                    shown=box,
                )  # fmt: skip
                if why:
                    if reason == "bad_box":
                        reason, detail = "color_mismatch", why
                    continue
            candidates.append((score, frac, (x1, y1, x2, y2)))
        if not candidates:
            return self._refuse(reason, detail)
        candidates.sort(key=lambda c: (-c[0], -c[1]))
        why = ""
        for _, _, box in candidates:
            why = self._seed(idx, box, mask)
            if not why:
                self._accept(answer.stamp if answer.stamp > 0 else self._history[-1][0])
                return None
        return self._refuse(why, f"the box on {self.query.text!r} could not be followed")

    def _seed(self, idx: int, box: Box, mask: np.ndarray | None) -> str:
        """Seed on frame `idx`, confirm on it, catch up to the newest frame. '' or why it failed."""
        frames = list(self._history)
        tracker = HistTracker()
        if not tracker.init(frames[idx][1], _xywh(box), mask):
            return "untrackable"
        track = tracker.update(frames[idx][1])  # the seed must hold up on its own frame
        if track is None:
            return "untrackable"
        for _, img in frames[idx + 1 :]:
            track = tracker.update(img)
            if track is None:
                return "lost_in_catch_up"
        self._tracker = tracker
        self._box, self._confidence = track.xyxy, track.confidence
        return ""

    def _accept(self, stamp: float) -> None:
        self._ever_tracked = True
        self._misses = 0
        self._confirmed = stamp if self._confirmed is None else max(self._confirmed, stamp)
        self.counters["accepted"] += 1

    def _ground_color(self, stamp: float, bgr: np.ndarray) -> None:
        assert self.query is not None
        self._last_ground = stamp
        self.counters["color_groundings"] += 1
        q = self.query
        cands = ground(bgr, q.color, q.shape, min_shape_score=self.params.min_shape_score)
        del self.color_answers[:-16]  # nobody takes them: keep only the newest
        if not cands:
            self.color_answers.append((stamp, None))
            return  # a failed re-grounding does not drop a track the tracker still follows
        pick = cands[0]
        if self._box is not None:  # prefer the candidate that is the tracked object
            best = max(cands, key=lambda c: _iou(c.xyxy, self._box))  # type: ignore[arg-type]
            if _iou(best.xyxy, self._box) >= 0.1:
                pick = best
        self.color_answers.append((stamp, tuple(float(v) for v in pick.xyxy)))  # type: ignore[arg-type]
        why = self._seed(len(self._history) - 1, pick.xyxy, self._label_mask(bgr))
        if why:
            self.counters[f"refused.{why}"] += 1
            return
        self._accept(stamp)

    def _observe(self, stamp: float, w: int, h: int, camera: PinholeCamera | None, pitch: float = 0.0) -> Observation:
        label = self.query.text if self.query else ""
        age = None if self._confirmed is None or self.query is None else max(0.0, stamp - self._confirmed)
        box = self._box
        if box is None:
            return Observation(stamp, label, self.state, None, w, h, grounding_age=age)
        distance, method, bearing = None, "none", None
        if camera is not None:
            cam = camera.scaled_to(w, h)
            reading = self._ranger.estimate(box, cam, pitch)
            distance, method = reading.distance, reading.method
            bearing = cam.bearing((box[0] + box[2]) / 2.0)
        return Observation(stamp, label, "tracking", box, w, h, self._confidence, distance, method, age, bearing)
