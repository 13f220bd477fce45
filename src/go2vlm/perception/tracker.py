"""A fast single-target tracker between (slow) grounding answers: hue-saturation histogram
back-projection + CamShift (OpenCV), a few milliseconds per 640x480 frame on one core.

Seeded from a grounded box (`init`), it follows the target every camera frame (`update`), and is
re-seeded on every new grounding answer. The histogram comes from the box with low-saturation and
dark pixels masked out (floor, sky, shadows), so a coloured object is followed across scale changes
and partial views. `update` returns None -- the target is lost -- when the back-projection inside
the new window is too weak or the window collapses.

Why not cv2.TrackerCSRT: opencv-python-headless 5.x ships only TrackerMIL plus DNN trackers that need
model files; MIL is ~10x slower and drifts on plain-coloured objects. CamShift also adapts the box
size as the robot approaches, which the distance estimate needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["HistTracker", "Track"]

_H_BINS, _S_BINS = 30, 32
_RANGES = [0, 180, 0, 256]


@dataclass(frozen=True)
class Track:
    bbox: tuple[int, int, int, int]  # x, y, w, h in pixels
    confidence: float  # mean back-projection in the box, 0..1

    @property
    def xyxy(self) -> tuple[float, float, float, float]:
        x, y, w, h = self.bbox
        return float(x), float(y), float(x + w), float(y + h)


class HistTracker:
    def __init__(
        self, *, min_saturation: int = 60, min_value: int = 40, min_confidence: float = 0.25, min_size_px: int = 6
    ) -> None:
        self.min_saturation = min_saturation
        self.min_value = min_value
        self.min_confidence = min_confidence
        self.min_size_px = min_size_px
        self.hist: np.ndarray | None = None
        self.window: tuple[int, int, int, int] | None = None
        self._term = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 1.0)

    @property
    def active(self) -> bool:
        return self.hist is not None and self.window is not None

    def reset(self) -> None:
        self.hist = None
        self.window = None

    def _valid_mask(self, hsv: np.ndarray) -> np.ndarray:
        return cv2.inRange(hsv, (0, self.min_saturation, self.min_value), (180, 255, 255))

    def init(self, bgr: np.ndarray, bbox: tuple[float, float, float, float], mask: np.ndarray | None = None) -> bool:
        """Seed from `bbox` = (x, y, w, h) in pixels. False (and inactive) if the box holds no colour.
        `mask` (uint8, the image's size): learn the histogram only from these pixels (e.g. the pixels of
        the colour a label names), so a box that also covers another object does not teach its colour."""
        h_img, w_img = bgr.shape[:2]
        x, y, w, h = (int(round(v)) for v in bbox)
        x0, y0 = max(0, x), max(0, y)
        x1, y1 = min(w_img, x + max(w, 1)), min(h_img, y + max(h, 1))
        if x1 - x0 < 2 or y1 - y0 < 2:
            self.reset()
            return False
        hsv = cv2.cvtColor(bgr[y0:y1, x0:x1], cv2.COLOR_BGR2HSV)
        mask = self._valid_mask(hsv) if mask is None else cv2.bitwise_and(self._valid_mask(hsv), mask[y0:y1, x0:x1])
        if cv2.countNonZero(mask) < 0.05 * mask.size:
            self.reset()
            return False
        hist = cv2.calcHist([hsv], [0, 1], mask, [_H_BINS, _S_BINS], _RANGES)
        cv2.normalize(hist, hist, 0, 255, cv2.NORM_MINMAX)
        self.hist = hist
        self.window = (x0, y0, x1 - x0, y1 - y0)
        return True

    def update(self, bgr: np.ndarray) -> Track | None:
        """Follow the target into this frame; None if it is lost (the tracker then stays inactive)."""
        if self.hist is None or self.window is None:
            return None
        h_img, w_img = bgr.shape[:2]
        hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)
        back = cv2.calcBackProject([hsv], [0, 1], self.hist, _RANGES, 1)
        back &= self._valid_mask(hsv)  # type: ignore[misc]  # uint8; the stubs allow a float image
        x, y, w, h = self.window
        # Search a window grown by half its size: CamShift only climbs from where it starts.
        gx, gy = max(0, x - w // 2), max(0, y - h // 2)
        gw, gh = min(w_img - gx, w * 2), min(h_img - gy, h * 2)
        if gw < 1 or gh < 1:
            self.reset()
            return None
        _, win = cv2.CamShift(back, (gx, gy, gw, gh), self._term)
        wx, wy, ww, wh = (int(v) for v in win)
        wx, wy = max(0, wx), max(0, wy)
        ww, wh = min(w_img - wx, ww), min(h_img - wy, wh)
        if ww < self.min_size_px or wh < self.min_size_px:
            self.reset()
            return None
        # CamShift's box comes from image moments and runs ~20 % large: tighten it to the largest
        # blob of strong back-projection around it, so box edges (used for ranging) are the object's.
        mx, my = ww // 4 + 4, wh // 4 + 4
        rx, ry = max(0, wx - mx), max(0, wy - my)
        roi = back[ry : min(h_img, wy + wh + my), rx : min(w_img, wx + ww + mx)]
        contours, _ = cv2.findContours(cv2.inRange(roi, 64, 255), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        if contours:
            bx, by, bw, bh = cv2.boundingRect(max(contours, key=cv2.contourArea))
            if bw >= self.min_size_px and bh >= self.min_size_px:
                wx, wy, ww, wh = rx + bx, ry + by, bw, bh
        conf = float(back[wy : wy + wh, wx : wx + ww].mean()) / 255.0
        if conf < self.min_confidence:
            self.reset()
            return None
        self.window = (wx, wy, ww, wh)
        return Track(self.window, conf)
