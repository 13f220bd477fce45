"""video_source: its source argument parsed (device, URL, file); and over real DDS: a missing file is a
clear error and a retry (the node stays up); once the file appears it streams; loop=true restarts the
file, loop=false idles at its end; an HTTP stream that ends is reconnected, and one whose server is
gone is retried with backoff."""

from __future__ import annotations

import functools
import http.server
import os
import threading
from pathlib import Path

import cv2
import numpy as np
import pytest
from busutil import Recorder, wait_for

from go2vlm.bus import QOS_SENSOR, Node, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.image import to_bgr
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.perception.color import detect_color
from go2vlm.sources.video_source_node import parse_source

FRAMES = 12


class _Sink(Node):
    name = "video_sink"


def _write_video(path: Path) -> None:
    tmp = path.with_suffix(".part.avi")
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"MJPG"), 20.0, (160, 120))
    assert writer.isOpened()
    for i in range(FRAMES):
        frame = np.zeros((120, 160, 3), np.uint8)
        cv2.circle(frame, (40 + 5 * i, 60), 20, (0, 0, 255), -1)
        writer.write(frame)
    writer.release()
    os.replace(tmp, path)  # appear atomically: the node must never see half a file


def test_missing_file_retries_then_streams_and_loops(tmp_path, capsys) -> None:
    path = tmp_path / "clip.avi"
    node = make_node(
        "video_source", params={"source": str(path), "rate_hz": 50.0, "loop": True, "reconnect_max_s": 0.4}
    )
    sink = _Sink()
    rec = Recorder()
    sink.create_subscription(Image, "/camera/image_raw", rec, QOS_SENSOR)
    with running(node, sink):
        assert wait_for(lambda: node.counters.get("open_failures", 0) >= 2, 5.0)
        assert node.state == "retrying" and len(rec) == 0
        _write_video(path)
        assert wait_for(lambda: len(rec) >= FRAMES + 5, 10.0), f"got {len(rec)} frames"  # looped past the end
        assert node.state == "streaming"
    msg = rec.msgs()[-1]
    assert (msg.width, msg.height, msg.encoding, msg.header.frame_id) == (160, 120, "bgr8", "camera")
    det = detect_color(to_bgr(msg), "red")
    assert det is not None and det.radius > 15
    assert "does not exist" in capsys.readouterr().err


def test_file_without_loop_idles_at_its_end(tmp_path) -> None:
    path = tmp_path / "once.avi"
    _write_video(path)
    node = make_node("video_source", params={"source": str(path), "rate_hz": 100.0})
    sink = _Sink()
    rec = Recorder()
    sink.create_subscription(Image, "/camera/image_raw", rec, QOS_SENSOR)
    with running(node, sink):
        assert wait_for(lambda: node.state == "ended", 10.0)
        assert node.frames == FRAMES
        assert node.running


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args: object) -> None:
        pass


def test_http_stream_reconnects_and_survives_its_server(tmp_path, capsys) -> None:
    _write_video(tmp_path / "live.avi")
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(_QuietHandler, directory=tmp_path))
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    url = f"http://127.0.0.1:{srv.server_address[1]}/live.avi"
    node = make_node(
        "video_source", params={"source": url, "rate_hz": 100.0, "reconnect_min_s": 0.1, "reconnect_max_s": 0.4}
    )
    sink = _Sink()
    rec = Recorder()
    sink.create_subscription(Image, "/camera/image_raw", rec, QOS_SENSOR)
    with running(node, sink):
        assert node.kind == "url"
        # Each HTTP download "ends" after FRAMES frames: a lost stream, reconnected.
        assert wait_for(lambda: node.counters.get("stream_lost", 0) >= 2 and len(rec) > FRAMES, 15.0)
        srv.shutdown()
        srv.server_close()
        assert wait_for(lambda: node.counters.get("open_failures", 0) >= 2, 15.0)
        assert node.running and node.state == "retrying"
    err = capsys.readouterr().err
    assert "reconnecting" in err and "cannot open url" in err


def test_video_source_parsing() -> None:
    assert parse_source("0") == ("device", 0)
    assert parse_source("/dev/video2") == ("device", 2)
    assert parse_source("rtsp://192.168.123.161:8554/cam") == ("url", "rtsp://192.168.123.161:8554/cam")
    assert parse_source("clip.mp4") == ("file", "clip.mp4")
    with pytest.raises(ValueError):
        parse_source("  ")
