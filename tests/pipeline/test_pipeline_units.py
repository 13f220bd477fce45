"""Pure parts of the seed pipeline: colour detection, the follower's control law, the test pattern,
launch-file parsing and the video source's source parsing."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from go2vlm.behavior.follower_node import FollowerConfig, follow_command
from go2vlm.bus import ParamError, build_config
from go2vlm.launch.launcher import LaunchError, available, parse_entries, resolve
from go2vlm.perception.color import PRESETS, annotate, detect_color, resolve_ranges
from go2vlm.perception.color_detector_node import ColorDetectorConfig
from go2vlm.safety.gate_node import SafetyGateConfig
from go2vlm.sources.test_pattern_node import draw_pattern
from go2vlm.sources.video_source_node import parse_source


def test_detects_the_seed_red_circle() -> None:
    det = detect_color(draw_pattern(0), "red")
    assert det is not None
    assert (det.cx, det.cy) == pytest.approx((450, 150), abs=1.0)
    assert det.radius == pytest.approx(80, abs=1.0)
    assert det.bbox == pytest.approx((370, 70, 161, 161), abs=2)
    assert det.area == pytest.approx(np.pi * 80**2, rel=0.03)
    x, y, z = det.normalized()
    assert (x, y, z) == pytest.approx((130 / 320, -90 / 240, 80 / 320), abs=0.005)


def test_green_preset_finds_the_rectangle_and_blue_finds_nothing() -> None:
    det = detect_color(draw_pattern(3), "green")
    assert det is not None and (det.cx, det.cy) == pytest.approx((200, 300), abs=1.5)
    assert detect_color(draw_pattern(3), "blue") is None
    assert detect_color(np.zeros((480, 640, 3), np.uint8), "red") is None


def test_red_wraps_around_hue_zero() -> None:
    img = np.zeros((200, 200, 3), np.uint8)
    hsv_hi = np.uint8([[[175, 255, 255]]])  # hue 175: only the upper red range sees it
    bgr = cv2.cvtColor(hsv_hi, cv2.COLOR_HSV2BGR)[0, 0].tolist()
    cv2.circle(img, (100, 100), 30, bgr, -1)
    det = detect_color(img, "red")
    assert det is not None and det.cx == pytest.approx(100, abs=1)
    assert detect_color(img, [((0, 120, 70), (10, 255, 255))]) is None


def test_small_blobs_are_ignored_and_largest_wins() -> None:
    img = np.zeros((240, 320, 3), np.uint8)
    cv2.circle(img, (40, 40), 6, (0, 0, 255), -1)  # radius <= 10 after erode/dilate: noise
    assert detect_color(img, "red") is None
    cv2.circle(img, (200, 120), 30, (0, 0, 255), -1)
    cv2.circle(img, (60, 180), 15, (0, 0, 255), -1)
    det = detect_color(img, "red")
    assert det is not None and (det.cx, det.cy) == pytest.approx((200, 120), abs=1)
    out = annotate(img, det)
    assert out.shape == img.shape and not np.array_equal(out, img)


def test_custom_ranges_and_their_errors() -> None:
    assert resolve_ranges([[0, 120, 70, 10, 255, 255]]) == (((0, 120, 70), (10, 255, 255)),)
    assert resolve_ranges("RED") == PRESETS["red"]
    for bad in ("purple", [[0, 0, 0]], [[10, 0, 0, 5, 255, 255]], [[0, 0, 0, 300, 255, 255]], []):
        with pytest.raises(ValueError):
            resolve_ranges(bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        detect_color(np.zeros((10, 10), np.uint8), "red")
    cfg = build_config(ColorDetectorConfig, {"color": "custom", "hsv_ranges": "[[100,120,60,130,255,255]]"})
    assert cfg.ranges() == (((100, 120, 60), (130, 255, 255)),)
    with pytest.raises(ParamError):
        build_config(ColorDetectorConfig, {"color": "custom"})


def test_follower_law_is_the_seeds() -> None:
    cfg = FollowerConfig()
    assert follow_command(0.40625, 0.25, cfg) == pytest.approx((0.0, -0.325))  # not aligned: turn only
    assert follow_command(0.1, 0.25, cfg) == pytest.approx((0.3 * 0.75, -0.08))  # aligned: walk
    assert follow_command(0.0, 1.5, cfg) == (0.0, 0.0)  # very close: never backwards
    assert follow_command(-0.9, 0.1, cfg) == pytest.approx((0.0, 0.72))
    assert follow_command(-2.0, 0.1, cfg)[1] == 1.0  # clamped to max_angular
    big = build_config(FollowerConfig, {"kp_linear": 5.0})
    assert follow_command(0.0, 0.0, big)[0] == 0.5  # clamped to max_linear
    damped = build_config(FollowerConfig, {"kd_angular": 0.5})
    assert follow_command(0.3, 0.2, damped, dx_dt=0.4)[1] == pytest.approx(-0.24 - 0.2)


def test_test_pattern_matches_the_seed() -> None:
    img = draw_pattern(7)
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    assert img[300, 200].tolist() == [0, 255, 0]
    assert img[150, 450].tolist() == [0, 0, 255]
    assert img[470, 630].tolist() == [0, 0, 0]
    assert img[20:60, 50:200].max() == 255  # the white "Frame 7" text
    assert not np.array_equal(img, draw_pattern(8))


def test_safety_params_can_only_lower_the_go2_ceilings() -> None:
    cfg = build_config(SafetyGateConfig, {"max_vx_forward": 3.8, "max_vyaw": 4.0})
    assert cfg.max_vx_forward == 3.8
    for name, value in (("max_vx_forward", 3.9), ("max_vx_backward", 2.6), ("max_vy", 1.1), ("max_vyaw", 4.5)):
        with pytest.raises(ParamError, match="above the maximum"):
            build_config(SafetyGateConfig, {name: value})
    with pytest.raises(ParamError):
        build_config(SafetyGateConfig, {"rate_hz": 10})
    with pytest.raises(ParamError, match="timeout_s"):
        build_config(SafetyGateConfig, {"inputs": [{"topic": "/a", "priority": 1, "timeout_s": 0}]})
    with pytest.raises(ParamError, match="output"):
        build_config(SafetyGateConfig, {"inputs": [{"topic": "/cmd_vel", "priority": 1}]})
    ok = build_config(SafetyGateConfig, {"inputs": "[{topic: /joy/cmd_vel, priority: 5}]"})
    assert ok.inputs == [{"topic": "/joy/cmd_vel", "priority": 5}]


def test_launch_files_parse_and_resolve() -> None:
    assert "follow_test_pattern" in available()
    assert resolve("follow_test_pattern").name == "follow_test_pattern.yaml"
    entries = parse_entries(
        [{"node": "follower", "params": {"kp_angular": 0.5}, "remap": {"detected_target": "/ball"}}, {"node": "safety"}]
    )
    assert [e.name for e in entries] == ["follower", "safety"]
    assert entries[0].remap == {"/detected_target": "/ball"}
    assert parse_entries({"nodes": [{"node": "safety"}]})[0].kind == "safety"
    for bad in (
        [],
        [{"node": "nope"}],
        [{"node": "safety", "extra": 1}],
        [{"node": "safety"}, {"node": "safety"}],
        [{"node": "safety", "params": [1]}],
        [{"node": "safety", "name": "a b"}],
    ):
        with pytest.raises(LaunchError):
            parse_entries(bad)
    with pytest.raises(LaunchError, match="not found"):
        resolve("no_such_launch_file")


def test_video_source_parsing() -> None:
    assert parse_source("0") == ("device", 0)
    assert parse_source("/dev/video2") == ("device", 2)
    assert parse_source("rtsp://192.168.123.161:8554/cam") == ("url", "rtsp://192.168.123.161:8554/cam")
    assert parse_source("clip.mp4") == ("file", "clip.mp4")
    with pytest.raises(ValueError):
        parse_source("  ")
