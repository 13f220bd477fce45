"""video_source: a camera from OpenCV VideoCapture: a video file, a device index or an RTSP/HTTP URL.

Topics
  publishes  /camera/image_raw    sensor_msgs/Image bgr8 (reliable keep-last 2), at most rate_hz
             /camera/camera_info  sensor_msgs/CameraInfo (latched), same stamp as each image

`source`: a path (`clip.mp4`), a device index (`0`, or `/dev/video0`) or a URL (`rtsp://...`,
`http://...`). A file plays once, or forever with loop=true; a file at its end without loop stops
publishing (the node stays up). A source that cannot be opened, or a stream/device that stops
delivering frames, is retried with exponential backoff (reconnect_min_s doubling up to
reconnect_max_s), every attempt logged; the node never exits because of it.
Frames are read and published on the node's own worker thread, so a slow or hung source never
blocks the node's executor. A file is paced at rate_hz frame by frame; a device or stream is read at
its own rate and only the newest frame is published at most rate_hz times a second (no stale
driver queue). Streams get 5 s open and read timeouts.
Parameters at runtime: loop, frame_id, width/height (set both at once: `go2vlm param set` with
--atomic), hfov_rad, reconnect_min_s/max_s; source and rate_hz are read-only.
Time: rate_hz pacing and the stamps are in the node's clock (sim time with use_sim_time: a file is
then paced at rate_hz of sim time); the open/read timeouts and the reconnect backoff are wall time,
since they wait on a device or a network.
"""

from __future__ import annotations

import os
import re
import threading
from dataclasses import dataclass
from typing import Any

from go2vlm.bus import Node, param
from go2vlm.bus.topics import CAMERA_IMAGE, CAMERA_INFO
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.msgs.image import camera_info, numpy_to_image

__all__ = ["VideoSourceConfig", "VideoSourceNode", "parse_source"]

_URL = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*://")


def parse_source(source: str) -> tuple[str, int | str]:
    """('device', 0) | ('url', 'rtsp://...') | ('file', '/path')."""
    s = source.strip()
    if not s:
        raise ValueError("source is empty; give a file path, a device index or an rtsp:// / http:// URL")
    if s.isdigit():
        return "device", int(s)
    m = re.fullmatch(r"/dev/video(\d+)", s)
    if m:
        return "device", int(m.group(1))
    if _URL.match(s):
        return "url", s
    return "file", os.path.expanduser(s)


@dataclass
class VideoSourceConfig:
    source: str = param("0", help="file path, device index (0, /dev/video0) or rtsp:// / http:// URL")
    rate_hz: float = param(30.0, help="publishing rate ceiling (a file is paced at this rate)", min=0.1, max=240.0)
    loop: bool = param(False, help="restart a file at its end", live=True)
    frame_id: str = param("camera", help="header.frame_id", live=True)
    width: int = param(0, help="resize to this width (0 = as captured)", min=0, max=8192, live=True)
    height: int = param(0, help="resize to this height (0 = as captured)", min=0, max=8192, live=True)
    hfov_rad: float = param(1.2, help="horizontal field of view for camera_info", min=0.01, max=3.1, live=True)
    reconnect_min_s: float = param(0.5, help="first retry delay", min=0.01, max=60.0, live=True)
    reconnect_max_s: float = param(10.0, help="retry delay ceiling", min=0.01, max=600.0, live=True)

    def validate(self) -> None:
        parse_source(self.source)
        if (self.width == 0) != (self.height == 0):
            raise ValueError("set both width and height, or neither")


class VideoSourceNode(Node):
    name = "video_source"
    Config = VideoSourceConfig

    def __init__(self, config: VideoSourceConfig | None = None, **kwargs: object) -> None:
        super().__init__(config, **kwargs)  # type: ignore[arg-type]
        self.kind, self.target = parse_source(self.config.source)
        self.image_pub = CAMERA_IMAGE.publisher(self)
        self.info_pub = CAMERA_INFO.publisher(self)
        self.frames = 0
        self.state = "starting"
        self._halt = threading.Event()
        self._worker = threading.Thread(target=self._capture_loop, name=f"{self.node_name}:capture", daemon=True)
        self._worker.start()

    # -- capture -----------------------------------------------------------------------------
    def _open(self) -> Any:
        import cv2

        if self.kind == "file" and not os.path.isfile(str(self.target)):
            raise OSError(f"video file {self.target!r} does not exist")
        if self.kind == "url":  # a dead stream must fail a read in seconds, not block forever
            timeouts = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, 5000, cv2.CAP_PROP_READ_TIMEOUT_MSEC, 5000]
            cap = cv2.VideoCapture(self.target, cv2.CAP_ANY, timeouts)
        else:
            cap = cv2.VideoCapture(self.target)
        if not cap.isOpened():
            cap.release()
            raise OSError(f"OpenCV cannot open {self.kind} {self.target!r}")
        return cap

    def _capture_loop(self) -> None:
        delay = self.config.reconnect_min_s
        attempt = 0
        while not self._halt.is_set():
            attempt += 1
            try:
                cap = self._open()
            except OSError as exc:
                self.count("open_failures")
                self.state = "retrying"
                self.log.error(f"{exc}; retry #{attempt} in {delay:.1f} s")
                if self._halt.wait(delay):  # wall time: retrying a device or a network
                    return
                delay = min(delay * 2.0, self.config.reconnect_max_s)
                continue
            self.log.info(f"opened {self.kind} {self.target!r}")
            self.state = "streaming"
            try:
                got_any, ended = self._stream(cap)
            finally:
                cap.release()
            if got_any:
                attempt, delay = 0, self.config.reconnect_min_s
            if self._halt.is_set():
                return
            if ended:  # a file reached its end without loop: idle, stay up
                self.state = "ended"
                self.log.info(f"end of {self.target!r} after {self.frames} frames (loop=false); idle")
                self._halt.wait()
                return
            self.count("stream_lost")
            self.state = "retrying"
            self.log.error(f"{self.kind} {self.target!r} stopped delivering frames; reconnecting in {delay:.1f} s")
            if self._halt.wait(delay):  # wall time: retrying a device or a network
                return
            delay = min(delay * 2.0, self.config.reconnect_max_s)

    def _stream(self, cap: Any) -> tuple[bool, bool]:
        """Publish frames until the source fails. Returns (got any frame, a file ended normally)."""
        return self._stream_file(cap) if self.kind == "file" else self._stream_live(cap)

    def _stream_live(self, cap: Any) -> tuple[bool, bool]:
        """A device or stream: grab every frame at the source's own pace (so the driver's queue never
        goes stale) and decode and publish only the newest one when rate_hz says so."""
        period = 1.0 / self.config.rate_hz
        next_t = self.clock.monotonic()
        got_any = False
        while not self._halt.is_set():
            if not cap.grab():
                return got_any, False
            now = self.clock.monotonic()
            if now < next_t:
                continue
            ok, frame = cap.retrieve()
            if not ok or frame is None:
                return got_any, False
            got_any = True
            self._publish(self._prepare(frame))
            next_t = max(next_t + period, now)
        return got_any, False

    def _prepare(self, frame: Any) -> Any:
        import cv2

        cfg = self.config  # one snapshot: width and height may change together at runtime
        if cfg.width:
            frame = cv2.resize(frame, (cfg.width, cfg.height), interpolation=cv2.INTER_AREA)
        if frame.ndim == 2:
            frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
        return frame

    def _stream_file(self, cap: Any) -> tuple[bool, bool]:
        """A file: every frame in order, paced at rate_hz."""
        import cv2

        period = 1.0 / self.config.rate_hz
        next_t = self.clock.monotonic()
        got_any = rewound = False
        while not self._halt.is_set():
            ok, frame = cap.read()
            if not ok or frame is None:
                if self.kind == "file" and got_any:
                    # Loop by seeking; a file that cannot seek is reopened instead (the reconnect path).
                    if self.config.loop and not rewound and cap.set(cv2.CAP_PROP_POS_FRAMES, 0):
                        rewound = True
                        continue
                    return got_any, not self.config.loop
                return got_any, False
            got_any, rewound = True, False
            self._publish(self._prepare(frame))
            next_t += period
            if next_t > self.clock.monotonic():
                if self.clock.wait_until(next_t, self._halt):
                    break
            else:
                next_t = self.clock.monotonic()  # a slow source: don't burst to catch up
        return got_any, False

    def _publish(self, frame: Any) -> None:
        header = self.header(self.config.frame_id)
        h, w = frame.shape[:2]
        self.info_pub.publish(camera_info(PinholeCamera.from_hfov(w, h, self.config.hfov_rad), header=header))
        self.image_pub.publish(numpy_to_image(frame, "bgr8", header=header))
        self.frames += 1

    def close(self) -> None:
        self._halt.set()
        self._worker.join(3.0)
