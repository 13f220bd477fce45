"""test_pattern: the VLM article's test image publisher (section 3.3), a camera without a camera.

Topics
  publishes  /camera/image_raw    sensor_msgs/Image, 640x480 bgr8, frame_id = frame_id: black, a filled
                                  green rectangle (100,200)-(300,400), a filled red circle centre
                                  (450,150) radius 80, white text `Frame N` at (50,50); N counts from 0
             /camera/camera_info  sensor_msgs/CameraInfo (latched), same stamp as each image

Parameters at runtime: frame_id and hfov_rad (from the next frame); period_s is read-only.
QoS: the topic table's (bus/topics.py: CAMERA_IMAGE, reliable keep-last 2), so best-effort and
reliable readers both match. The first frame goes out at start-up, and a fresh frame whenever a
new reader matches, so a late joiner does not wait a whole period_s (5 s by default, as in the
article).
Time: period_s, the new-reader check and the stamps are in the node's clock (sim time with
use_sim_time: nothing but the first frame, stamped 0, goes out before /clock starts).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from go2vlm.bus import Node, param
from go2vlm.bus.topics import CAMERA_IMAGE, CAMERA_INFO
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.msgs.image import camera_info, numpy_to_image

__all__ = ["TestPatternConfig", "TestPatternNode", "draw_pattern"]

WIDTH, HEIGHT = 640, 480


def draw_pattern(n: int) -> np.ndarray:
    """The article's frame number `n` as a 480x640x3 BGR array."""
    img = np.zeros((HEIGHT, WIDTH, 3), dtype=np.uint8)
    cv2.rectangle(img, (100, 200), (300, 400), (0, 255, 0), -1)
    cv2.circle(img, (450, 150), 80, (0, 0, 255), -1)
    cv2.putText(img, f"Frame {n}", (50, 50), cv2.FONT_HERSHEY_SIMPLEX, 1, (255, 255, 255), 2)
    return img


@dataclass
class TestPatternConfig:
    period_s: float = param(5.0, help="seconds between frames (the article: 5.0)", min=0.001, max=3600.0)
    frame_id: str = param("camera", help="header.frame_id of image and camera_info", live=True)
    hfov_rad: float = param(1.2, help="horizontal field of view for camera_info", min=0.01, max=3.1, live=True)


class TestPatternNode(Node):
    name = "test_pattern"
    Config = TestPatternConfig

    def __init__(self, config: TestPatternConfig | None = None, **kwargs: object) -> None:
        super().__init__(config, **kwargs)  # type: ignore[arg-type]
        self.image_pub = CAMERA_IMAGE.publisher(self)
        self.info_pub = CAMERA_INFO.publisher(self)
        self.frame = 0
        self._matched = 0
        self._again_at: float | None = None
        self.publish_frame()
        self.create_timer(self.config.period_s, self.publish_frame)
        if self.config.period_s > 0.2:
            self.create_timer(0.1, self._on_new_reader)

    def publish_frame(self) -> None:
        header = self.header(self.config.frame_id)
        self.info_pub.publish(camera_info(PinholeCamera.from_hfov(WIDTH, HEIGHT, self.config.hfov_rad), header=header))
        self.image_pub.publish(numpy_to_image(draw_pattern(self.frame), "bgr8", header=header))
        self.log.debug(f"published frame #{self.frame}")
        self.frame += 1

    def _on_new_reader(self) -> None:
        now = self.clock.monotonic()
        matched = self.image_pub.matched
        if matched > self._matched:
            self.publish_frame()
            # Once more a little later: the reader may not have matched us back yet.
            self._again_at = now + 0.5
        elif self._again_at is not None and now >= self._again_at:
            self._again_at = None
            self.publish_frame()
        self._matched = matched
