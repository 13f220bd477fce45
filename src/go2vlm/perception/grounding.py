"""Classical colour-shape grounding: "the blue cylinder" -> a box in the image, without weights.

Colour: the vocabulary's HSV ranges and mask (vocabulary/words.py, pixels.py). Every external
contour of the colour (not only the largest) is a candidate and gets shape scores from its outline:

* ball     -- round: a circle fitted to the outline (ignoring points on the image border, so a ball
              cut by the frame edge still counts) leaves a small residual, and the blob is not tall;
* box      -- a filled, roughly square-ish quadrilateral: high fill of its minimum-area rectangle,
              aspect (height / width) about 0.4-1.8, straight sides (not round);
* cylinder -- a tall rectangle with straight vertical sides: high rectangle fill, aspect >= ~1.4
              (a top or bottom cut by the frame makes it taller, not less of a cylinder).

The best candidate whose shape score clears `min_shape_score` wins (ties: the larger blob). With no
shape asked for, the largest blob of the colour wins; with no colour, every preset is tried.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from go2vlm.vocabulary.pixels import color_mask
from go2vlm.vocabulary.words import COLOR_HSV as PRESETS
from go2vlm.vocabulary.words import SHAPES

__all__ = ["SHAPES", "Candidate", "ShapeScores", "ground", "shape_scores"]


@dataclass(frozen=True)
class ShapeScores:
    ball: float
    box: float
    cylinder: float
    aspect: float  # height / width of the bounding box
    rect_fill: float  # area / minimum-area rectangle
    roundness: float  # 1 - circle-fit residual / radius, on points off the image border
    clipped: bool  # touches the image border

    def get(self, shape: str) -> float:
        return float(getattr(self, shape))

    def best(self) -> str:
        return max(SHAPES, key=self.get)


@dataclass(frozen=True)
class Candidate:
    color: str
    shape: str  # the best-scoring shape
    score: float  # score of the requested shape (or of `shape` when none was requested)
    bbox: tuple[int, int, int, int]  # x, y, w, h in pixels
    area: float
    shapes: ShapeScores = field(compare=False)

    @property
    def xyxy(self) -> tuple[float, float, float, float]:
        x, y, w, h = self.bbox
        return float(x), float(y), float(x + w), float(y + h)


def _ramp(v: float, lo: float, hi: float) -> float:
    """0 below lo, 1 above hi, linear between."""
    if hi == lo:
        return 1.0 if v >= hi else 0.0
    return float(min(1.0, max(0.0, (v - lo) / (hi - lo))))


def _circle_fit(pts: np.ndarray) -> tuple[float, float, float, float]:
    """Least-squares (Kasa) circle through points: cx, cy, r, rms residual."""
    x, y = pts[:, 0], pts[:, 1]
    a = np.stack([x, y, np.ones_like(x)], axis=1)
    b = x * x + y * y
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    cx, cy = sol[0] / 2.0, sol[1] / 2.0
    r2 = sol[2] + cx * cx + cy * cy
    if not r2 > 0:
        return float(cx), float(cy), 0.0, math.inf
    r = math.sqrt(r2)
    resid = np.sqrt((x - cx) ** 2 + (y - cy) ** 2) - r
    return float(cx), float(cy), r, float(np.sqrt(np.mean(resid**2)))


def _resample(pts: np.ndarray, n: int) -> np.ndarray:
    """`n` points evenly spaced along the closed outline (findContours leaves straight runs sparse,
    which would let the curved parts dominate a circle fit)."""
    closed = np.vstack([pts, pts[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if cum[-1] <= 0:
        return pts
    t = np.linspace(0.0, cum[-1], n, endpoint=False)
    return np.stack([np.interp(t, cum, closed[:, 0]), np.interp(t, cum, closed[:, 1])], axis=1)


def shape_scores(contour: np.ndarray, width: int, height: int) -> ShapeScores:
    """Ball/box/cylinder scores in [0, 1] for one contour of an image of `width` x `height`."""
    area = float(cv2.contourArea(contour))
    x, y, w, h = cv2.boundingRect(contour)
    aspect = h / max(w, 1)
    (_, _), (rw, rh), _ = cv2.minAreaRect(contour)
    rect_fill = area / max(rw * rh, 1.0)
    m = 2
    clipped_h = x <= m or x + w >= width - m
    clipped_v = y <= m or y + h >= height - m
    clipped = clipped_h or clipped_v
    pts = _resample(contour.reshape(-1, 2).astype(np.float64), 160)
    inner = pts[(pts[:, 0] > m) & (pts[:, 0] < width - 1 - m) & (pts[:, 1] > m) & (pts[:, 1] < height - 1 - m)]
    roundness = 0.0
    if len(inner) >= 8:
        _, _, r, rms = _circle_fit(inner)
        if r > 0 and math.isfinite(rms):
            roundness = max(0.0, 1.0 - rms / r * 10.0)  # 10 %-of-radius rms -> 0
            # A nearly straight outline fits a huge circle: that is a flat side, not a ball.
            if r > 3.0 * max(w, h):
                roundness = 0.0
    square_ish = _ramp(aspect, 0.35, 0.6) * (1.0 - _ramp(aspect, 1.6, 2.2))
    tall = _ramp(aspect, 1.2, 1.7)
    if clipped_v and not clipped_h:
        tall = max(tall, _ramp(aspect, 0.8, 1.2))  # cut at top/bottom: it is taller than it looks
    filled = _ramp(rect_fill, 0.75, 0.92)
    ball = roundness * (1.0 - _ramp(aspect, 1.5, 2.5) * (0.0 if clipped else 1.0))
    box = filled * square_ish * (1.0 - 0.8 * roundness)
    cylinder = _ramp(rect_fill, 0.7, 0.88) * tall * (1.0 - 0.8 * roundness)
    return ShapeScores(
        ball=round(ball, 4),
        box=round(box, 4),
        cylinder=round(cylinder, 4),
        aspect=aspect,
        rect_fill=rect_fill,
        roundness=roundness,
        clipped=clipped,
    )


def ground(
    bgr: np.ndarray,
    color: str | None,
    shape: str | None,
    *,
    min_area: float = 150.0,
    min_shape_score: float = 0.35,
    iterations: int = 2,
) -> list[Candidate]:
    """Candidates for "<color> <shape>", best first; empty if nothing matches.

    `color` is a preset name of perception/color.py or None (any preset); `shape` is ball, box,
    cylinder or None (any). Raises ValueError for an unknown colour or shape, or a bad image.
    """
    if shape is not None and shape not in SHAPES:
        raise ValueError(f"shape {shape!r} is not ball, box or cylinder")
    if color is not None and color not in PRESETS:
        raise ValueError(f"colour {color!r} is not one of {sorted(PRESETS)}")
    colors = [color] if color is not None else list(PRESETS)
    height, width = bgr.shape[:2]
    out: list[Candidate] = []
    for c in colors:
        mask = color_mask(bgr, PRESETS[c], iterations)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        for cnt in contours:
            area = float(cv2.contourArea(cnt))
            if area < min_area:
                continue
            s = shape_scores(cnt, width, height)
            best = s.best()
            score = s.get(shape) if shape is not None else 1.0
            if shape is not None and score < min_shape_score:
                continue
            x, y, w, h = cv2.boundingRect(cnt)
            out.append(Candidate(c, best, score, (int(x), int(y), int(w), int(h)), area, s))
    out.sort(key=lambda cand: (round(cand.score, 1), cand.area), reverse=True)
    return out
