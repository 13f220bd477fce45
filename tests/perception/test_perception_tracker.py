"""The histogram tracker on a drawn blob that moves and grows, and then disappears."""

from __future__ import annotations

import cv2
import numpy as np

from go2vlm.perception.tracker import HistTracker

BGR = {"red": (0, 0, 255), "green": (0, 200, 0), "blue": (255, 0, 0), "yellow": (0, 230, 255)}


def test_tracker_follows_a_moving_and_growing_blob_and_reports_loss() -> None:
    tracker = HistTracker()
    img = np.full((480, 640, 3), 40, np.uint8)
    cv2.circle(img, (100, 240), 30, BGR["blue"], -1)
    assert tracker.init(img, (70, 210, 60, 60))
    for i in range(1, 30):
        img = np.full((480, 640, 3), 40, np.uint8)
        cx, r = 100 + 12 * i, 30 + i
        cv2.circle(img, (cx, 240), r, BGR["blue"], -1)
        track = tracker.update(img)
        assert track is not None, f"lost at frame {i}"
        x1, y1, x2, y2 = track.xyxy
        assert abs((x1 + x2) / 2 - cx) < 4 and abs((x2 - x1) - 2 * r) < 6
    assert tracker.update(np.full((480, 640, 3), 40, np.uint8)) is None
    assert not tracker.active
    assert not tracker.init(np.full((480, 640, 3), 40, np.uint8), (0, 0, 50, 50))  # nothing coloured to track
