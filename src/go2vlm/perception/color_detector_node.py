"""color_detector: finds the largest blob of one colour in the camera image (the follow article's
color_detector.py, section 5.2).

Topics
  subscribes  /camera/image_raw           sensor_msgs/Image (sensor-data QoS: matches reliable and
                                          best-effort cameras); bgr8, rgb8, bgra8, rgba8, mono8 ...
  publishes   /detected_target            geometry_msgs/PointStamped, one per image with a target:
                                          header.stamp = the image's stamp, frame_id = `camera`,
                                          x = (cx - w/2)/(w/2), y = (cy - h/2)/(h/2) (both -1..1, 0 =
                                          centre), z = radius/(w/2) (bigger = closer)
              /color_detector/debug_image sensor_msgs/Image bgr8, the image with the detection drawn;
                                          only while someone subscribes (or debug_image=true)

Detection (perception/color.py): HSV ranges (red wraps hue 0: two ranges), erode + dilate with 2
iterations, largest external contour, minimum enclosing circle, radius > min_radius (10 px).
Nothing is published for an image without a target: the follower stops on its own timeout.
Every parameter can change at runtime (`go2vlm param set color_detector color blue`).
A malformed image (bad step, truncated data, unknown encoding, 0x0, an absurd size) is dropped
with a rate-limited error and counted in `bad_images`; the node keeps running.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from go2vlm.bus import Node, param
from go2vlm.bus.topics import CAMERA_IMAGE, COLOR_DEBUG_IMAGE, DETECTED_TARGET
from go2vlm.msgs.geometry_msgs import Point, PointStamped
from go2vlm.msgs.image import numpy_to_image, to_bgr
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.std_msgs import Header
from go2vlm.perception.color import PRESETS, annotate, detect_color, resolve_ranges
from go2vlm.vocabulary.words import HsvRange

__all__ = ["ColorDetectorConfig", "ColorDetectorNode"]


@dataclass
class ColorDetectorConfig:
    color: str = param(
        "red", help="colour preset, or `custom` to use hsv_ranges", choices=(*PRESETS, "custom"), live=True
    )
    hsv_ranges: list[list[int]] = param(
        list, help="custom: [[h,s,v,h,s,v], ...] lower/upper pairs (OpenCV H 0..180, S, V 0..255)", live=True
    )
    min_radius: float = param(10.0, help="ignore blobs whose enclosing circle is this small (px)", min=0.0, live=True)
    iterations: int = param(2, help="erode and dilate iterations (3x3 kernel)", min=0, max=20, live=True)
    frame_id: str = param("camera", help="frame_id of /detected_target", live=True)
    debug_image: bool = param(False, help="always publish the debug image (default: only while subscribed)", live=True)

    def validate(self) -> None:
        self.ranges()

    def ranges(self) -> tuple[HsvRange, ...]:
        if self.color == "custom":
            if not self.hsv_ranges:
                raise ValueError("color=custom needs hsv_ranges, e.g. [[0,120,70,10,255,255]]")
            return resolve_ranges(self.hsv_ranges)
        return resolve_ranges(self.color)


class ColorDetectorNode(Node):
    name = "color_detector"
    Config = ColorDetectorConfig

    def __init__(self, config: ColorDetectorConfig | None = None, **kwargs: object) -> None:
        super().__init__(config, **kwargs)  # type: ignore[arg-type]
        self._ranges = self.config.ranges()
        self.target_pub = DETECTED_TARGET.publisher(self)
        self.debug_pub = COLOR_DEBUG_IMAGE.publisher(self)
        CAMERA_IMAGE.subscription(self, self.on_image)
        self._debug_wanted = self.config.debug_image
        self._debug_checked = 0.0
        self.frames = 0
        self.detections = 0

    def on_params_changed(self, old: ColorDetectorConfig, changed: frozenset[str]) -> None:
        if changed & {"color", "hsv_ranges"}:
            self._ranges = self.config.ranges()  # validate() already checked them

    def _want_debug(self) -> bool:
        if self.config.debug_image:
            return True
        # Wall time: this only bounds the CPU spent asking DDS for matches (a cost in wall time; on a
        # fast sim, sim time would ask more often), it decides nothing the robot does.
        now = time.monotonic()
        if now - self._debug_checked > 0.5:  # asking DDS for matches every frame would cost more than drawing
            self._debug_checked = now
            self._debug_wanted = self.debug_pub.matched > 0
        return self._debug_wanted

    def on_image(self, msg: Image) -> None:
        try:
            bgr = to_bgr(msg)
        except ValueError as exc:
            n = self.count("bad_images")
            self.log.throttled("error", 2.0, f"dropping a malformed image ({n} so far): {exc}", key="bad_image")
            return
        self.frames += 1
        det = detect_color(bgr, self._ranges, min_radius=self.config.min_radius, iterations=self.config.iterations)
        if det is not None:
            self.detections += 1
            x, y, z = det.normalized()
            self.target_pub.publish(
                PointStamped(header=Header(stamp=msg.header.stamp, frame_id=self.config.frame_id), point=Point(x, y, z))
            )
        if self._want_debug():
            self.debug_pub.publish(numpy_to_image(annotate(bgr, det), "bgr8", header=msg.header))
