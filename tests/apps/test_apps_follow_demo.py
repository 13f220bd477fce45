"""`go2vlm demo` end to end as a real process: the Go2 follows the red ball; metrics, plot and video
are written and say so."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import imageio_ffmpeg
import pytest
from busutil import GO2VLM, Procs, Recorder, env, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.std_msgs import String

# Slow: every test is a `go2vlm demo` run (the sim, nodes and recording, in real time).
pytestmark = pytest.mark.slow

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def run_demo(out: Path, *args: str, timeout: float = 180) -> dict[str, Any]:
    proc = subprocess.run(
        [*GO2VLM, "demo", "--out", str(out), "--no-progress", *args],
        capture_output=True, text=True, timeout=timeout, env=env(),
    )  # fmt: skip
    assert proc.returncode == 0, f"demo failed ({proc.returncode}):\n{proc.stdout[-2000:]}\n{proc.stderr[-4000:]}"
    assert "ball in view" in proc.stdout and "fell:              no" in proc.stdout
    return json.loads((out / "metrics.json").read_text())


def check_follows(m: dict[str, Any], duration: float, min_frames: float | None = None) -> None:
    assert m["fell"] is False
    assert m["duration_s"] >= duration - 0.2
    assert m["frames"] >= (5 * duration if min_frames is None else min_frames), "the head camera ran at ~10 Hz"
    assert m["target_visible_fraction"] >= 0.9, m
    assert m["mean_abs_x_error"] < 0.35, "the ball is kept near the centre of the image"
    # Follows: it walks after the ball and the gap stays bounded (the ball moves 0.3 m/s on a 2 m circle).
    assert m["robot_distance_travelled_m"] > 0.15 * duration
    assert m["min_distance_to_ball_m"] > 0.3 and m["max_distance_to_ball_m"] < 3.0, m
    assert m["cmd_rate_hz"] >= 15.0, "the safety gate streams /cmd_vel"


def check_files(out: Path, video: bool = True) -> None:
    assert (out / "plot.png").read_bytes()[:8] == PNG_MAGIC
    if video:
        data = (out / "video.mp4").read_bytes()
        assert data[4:8] == b"ftyp"
        frames, _secs = imageio_ffmpeg.count_frames_and_secs(str(out / "video.mp4"))
        assert frames >= 10


def test_demo_kinematic_follows_the_ball(tmp_path: Path) -> None:
    m = run_demo(tmp_path, "--mode", "kinematic", "--duration", "20", "--rtf", "2")
    check_follows(m, 20)
    check_files(tmp_path)
    assert m["mode"] == "kinematic" and m["robot"] == "sim"


def test_demo_dynamic_trot_follows_without_falling(tmp_path: Path) -> None:
    m = run_demo(tmp_path, "--mode", "dynamic", "--duration", "15", "--no-video")
    check_follows(m, 15)
    check_files(tmp_path, video=False)
    assert not (tmp_path / "video.mp4").exists()


def test_demo_through_the_unitree_protocol(tmp_path: Path) -> None:
    """--robot go2: the go2 driver drives the sim through the sport API and reads its videohub camera."""
    pytest.importorskip("go2vlm.robots.go2.driver_node")
    m = run_demo(tmp_path, "--robot", "go2", "--mode", "kinematic", "--duration", "15", "--rtf", "2")
    check_follows(m, 15, min_frames=4 * m["wall_s"] - 20)  # the driver polls the camera at 10 Hz of wall time
    check_files(tmp_path)
    assert m["robot"] == "go2"


def test_demo_through_webrtc(tmp_path: Path) -> None:
    """--robot go2 --transport webrtc: the driver reaches the sim as the Unitree app reaches a Go2
    (signalling, data channel, the head camera as a video track) and the robot follows the ball."""
    pytest.importorskip("aiortc", reason="the webrtc extra")
    m = run_demo(tmp_path, "--robot", "go2", "--transport", "webrtc", "--mode", "kinematic", "--duration", "15")
    check_follows(m, 15, min_frames=3 * 15)  # the video track carries the sim's 10 Hz camera
    assert m["robot"] == "go2 (webrtc)"


def test_demo_rejects_bad_options(tmp_path: Path) -> None:
    proc = subprocess.run(
        [*GO2VLM, "demo", "--out", str(tmp_path), "--duration", "-1"],
        capture_output=True, text=True, timeout=60, env=env(),
    )  # fmt: skip
    assert proc.returncode == 2 and "--duration" in proc.stderr
    proc = subprocess.run(
        [*GO2VLM, "demo", "--out", str(tmp_path), "--param", "follower.no_such_param=1", "--duration", "1"],
        capture_output=True, text=True, timeout=60, env=env(),
    )  # fmt: skip
    assert proc.returncode == 2 and "no_such_param" in proc.stderr
    proc = subprocess.run(
        [*GO2VLM, "demo", "--out", str(tmp_path), "--transport", "webrtc", "--duration", "1"],
        capture_output=True, text=True, timeout=60, env=env(),
    )  # fmt: skip
    assert proc.returncode == 2 and "--robot go2" in proc.stderr


def test_demo_says_so_and_fails_when_the_robot_falls(tmp_path: Path) -> None:
    """A hard sideways kick (/sim/push) knocks the trotting Go2 over: exit code 1 and a clear message."""
    procs = Procs()
    proc = procs.start("demo", "--out", str(tmp_path), "--no-progress", "--no-video", "--duration", "12")
    kicker = Node(node_name="kicker")
    status = Recorder()
    kicker.create_subscription(String, "/sim/status", status, QOS_LATCHED)
    push = kicker.create_publisher(Twist, "/sim/push", QOS_DEFAULT)
    kicker.start()
    try:

        def walking() -> bool:
            return any(json.loads(m.data)["sim_time"] > 3.0 for m in status.msgs())

        assert wait_for(walking, timeout=60) and wait_for(lambda: push.matched > 0, timeout=10)

        def fell() -> bool:
            return any(json.loads(m.data).get("fell") for m in status.msgs())

        # Airborne and rolling fast. Kick again until the sim reports the fall: a sample sent right
        # after matching can be lost while the sim's reader has not yet discovered this writer.
        for _ in range(6):
            push.publish(Twist(linear=Vector3(0.0, 5.0, 2.0), angular=Vector3(25.0, 0.0, 0.0)))
            if wait_for(fell, timeout=1.5):
                break
        out, _ = proc.communicate(timeout=120)
    finally:
        kicker.shutdown()
        procs.stop_all()
    assert proc.returncode == 1, out[-3000:]
    assert "the robot fell" in out and "fell:              YES" in out
    assert json.loads((tmp_path / "metrics.json").read_text())["fell"] is True
