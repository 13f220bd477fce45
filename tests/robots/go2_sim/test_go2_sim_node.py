"""The `sim` node as a real process over real DDS: every documented topic with sane content, /cmd_vel
moves the robot, its timeout stops it, bad commands move nothing."""

from __future__ import annotations

import json
import math
import subprocess
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from busutil import GO2VLM, Procs, Recorder, env, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.image import image_to_numpy
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.sensor_msgs import CameraInfo, Image, Imu, JointState, LaserScan, PointCloud2
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.tf2_msgs import TFMessage

# Slow: the sim runs in real time for the whole module.
pytestmark = pytest.mark.slow

HEAD = (320, 240)  # not the default, so that the parameters are seen to apply

TOPICS: dict[str, tuple[type, Any]] = {
    "/camera/image_raw": (Image, QOS_SENSOR),
    "/camera/camera_info": (CameraInfo, QOS_LATCHED),
    "/world_camera/image_raw": (Image, QOS_SENSOR),
    "/world_camera/camera_info": (CameraInfo, QOS_LATCHED),
    "/odom": (Odometry, QOS_DEFAULT),
    "/imu": (Imu, QOS_DEFAULT),
    "/joint_states": (JointState, QOS_DEFAULT),
    "/tf": (TFMessage, QOS_DEFAULT),
    "/tf_static": (TFMessage, QOS_LATCHED),
    "/clock": (Clock, QOS_DEFAULT),
    "/sim/ground_truth": (TFMessage, QOS_DEFAULT),
    "/sim/status": (String, QOS_LATCHED),
    "/utlidar/cloud": (PointCloud2, QOS_SENSOR),
    "/scan": (LaserScan, QOS_SENSOR),
}


class Probe(Node):
    name = "sim_probe"


@pytest.fixture(scope="module")
def sim() -> Iterator[tuple[Probe, dict[str, Recorder]]]:
    procs = Procs()
    proc = procs.start(
        "run", "sim",
        "--param", "mode=kinematic",
        "--param", "world=follow_ball",
        "--param", f"camera_width={HEAD[0]}",
        "--param", f"camera_height={HEAD[1]}",
        "--param", "world_camera_rate_hz=5",
    )  # fmt: skip
    probe = Probe()
    recs = {topic: Recorder() for topic in TOPICS}
    for topic, (cls, qos) in TOPICS.items():
        probe.create_subscription(cls, topic, recs[topic], qos)
    probe.start()
    try:
        ok = wait_for(lambda: all(len(r) for r in recs.values()), timeout=60)
        missing = [t for t, r in recs.items() if not len(r)]
        if not ok:
            procs.stop(proc)
            out = proc.stdout.read() if proc.stdout else ""
            pytest.fail(f"no message on {missing}; sim output:\n{out[-3000:]}")
        yield probe, recs
    finally:
        probe.shutdown()
        procs.stop_all()


def last(rec: Recorder) -> Any:
    return rec.msgs()[-1]


def test_every_topic_has_sane_content(sim: tuple[Probe, dict[str, Recorder]]) -> None:
    _, recs = sim
    img = last(recs["/camera/image_raw"])
    arr = image_to_numpy(img)
    assert img.encoding == "rgb8" and arr.shape == (HEAD[1], HEAD[0], 3)
    assert img.header.frame_id == "camera_optical_frame"
    assert abs(img.header.stamp.to_sec() - time.time()) < 10, "stamps are wall-clock time"
    assert arr.std() > 5, "a rendered scene, not a blank frame"
    red = (arr[:, :, 0] > 120) & (arr[:, :, 1] < 80) & (arr[:, :, 2] < 80)
    assert red.sum() > 50, "the red ball is in front of the robot at the start of follow_ball"

    info = last(recs["/camera/camera_info"])
    assert (info.width, info.height) == HEAD and info.header.frame_id == "camera_optical_frame"
    assert info.k[0] > 0 and info.k[4] > 0 and info.k[8] == 1.0
    wimg, winfo = last(recs["/world_camera/image_raw"]), last(recs["/world_camera/camera_info"])
    assert (wimg.width, wimg.height) == (winfo.width, winfo.height) == (640, 480)

    odom = last(recs["/odom"])
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
    assert 0.2 < odom.pose.pose.position.z < 0.45
    imu = last(recs["/imu"])
    assert abs(imu.linear_acceleration.z - 9.81) < 0.5
    q = imu.orientation
    assert abs(q.x**2 + q.y**2 + q.z**2 + q.w**2 - 1) < 1e-6
    js = last(recs["/joint_states"])
    assert len(js.name) == len(js.position) == len(js.velocity) == len(js.effort) == 12
    assert all(math.isfinite(v) for v in js.position)
    tf = last(recs["/tf"]).transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id) == ("odom", "base_link")
    static = {t.child_frame_id: t.header.frame_id for t in last(recs["/tf_static"]).transforms}
    assert static["camera_optical_frame"] == "base_link" and static["camera_link"] == "base_link"
    assert static["odom"] == "world" and static["utlidar_lidar"] == "base_link"
    assert last(recs["/utlidar/cloud"]).header.frame_id == "utlidar_lidar" and last(recs["/utlidar/cloud"]).width > 0
    assert last(recs["/scan"]).header.frame_id == "base_link" and len(last(recs["/scan"]).ranges) == 180
    gt = {t.child_frame_id: t for t in last(recs["/sim/ground_truth"]).transforms}
    assert {"gt/go2", "gt/red_ball"} <= set(gt) and all(t.header.frame_id == "world" for t in gt.values())
    assert abs(gt["gt/go2"].transform.translation.x - odom.pose.pose.position.x) < 0.1

    assert wait_for(lambda: len(recs["/clock"]) > 10, timeout=10)
    clocks = [m.clock.to_sec() for m in recs["/clock"].msgs()]
    assert len(clocks) > 10 and bool(np.all(np.diff(clocks) > 0)), f"sim time advances: {clocks[:20]}"
    status = json.loads(last(recs["/sim/status"]).data)
    for key in ("sim_time", "rtf", "mode", "physics", "fell"):
        assert key in status
    assert status["physics"] == "kinematic" and status["fell"] is False and status["sim_time"] > 0


def odom_xy(rec: Recorder) -> np.ndarray:
    p = last(rec).pose.pose.position
    return np.array([p.x, p.y])


def test_cmd_vel_moves_and_its_timeout_stops(sim: tuple[Probe, dict[str, Recorder]]) -> None:
    """/cmd_vel from the safety gate (the only writer the sim obeys) moves it; silence stops it."""
    probe, recs = sim
    gate = make_node("safety", params={"max_vx_forward": 0.5})
    pub = probe.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)
    with running(gate):
        assert wait_for(lambda: pub.matched > 0 and json.loads(last(recs["/sim/status"]).data)["commander"]["ok"], 10)
        start = odom_xy(recs["/odom"])

        def driven(distance: float) -> bool:
            pub.publish(Twist(linear=Vector3(0.5, 0.0, 0.0)))
            return bool(np.linalg.norm(odom_xy(recs["/odom"]) - start) > distance)

        assert wait_for(lambda: driven(0.5), 60), "the robot never went 0.5 m at 0.5 m/s"
        top = max(m.twist.twist.linear.x for m in recs["/odom"].msgs())
        assert top == pytest.approx(0.5, abs=0.05), "it walked at the commanded 0.5 m/s"

    # Silence (the gate is gone): after cmd_timeout_s the sim stops the robot by itself.
    assert wait_for(lambda: json.loads(last(recs["/sim/status"]).data)["cmd_timed_out"] is True, 30)
    n, a = len(recs["/odom"]), odom_xy(recs["/odom"])
    assert wait_for(lambda: len(recs["/odom"]) > n + 50, 30)  # a second of sim time standing
    assert np.linalg.norm(odom_xy(recs["/odom"]) - a) < 0.01


def test_bad_cmd_vel_and_push_move_nothing(sim: tuple[Probe, dict[str, Recorder]]) -> None:
    """Bad values on /cmd_vel (from a writer that is not even the gate) and /sim/push move nothing."""
    probe, recs = sim
    pub = probe.create_publisher(Twist, "/cmd_vel", QOS_DEFAULT)
    assert wait_for(lambda: pub.matched > 0, timeout=10)
    start = odom_xy(recs["/odom"])
    n_status = len(recs["/sim/status"])
    push = probe.create_publisher(Twist, "/sim/push", QOS_DEFAULT)
    assert wait_for(lambda: push.matched > 0, timeout=10)
    for _ in range(20):
        pub.publish(Twist(linear=Vector3(float("nan"), 0.0, 0.0), angular=Vector3(0.0, 0.0, float("inf"))))
        push.publish(Twist(linear=Vector3(float("nan"), 0.0, 0.0)))
        push.publish(Twist(linear=Vector3(500.0, 0.0, 0.0)))  # absurd: rejected, not clamped
        time.sleep(0.05)
    time.sleep(0.5)
    assert np.linalg.norm(odom_xy(recs["/odom"]) - start) < 0.01
    assert wait_for(lambda: len(recs["/sim/status"]) > n_status + 1, timeout=5), "the node keeps running"


def test_sim_cli_runs_headless_and_reports_rtf() -> None:
    out = subprocess.run(
        [*GO2VLM, "sim", "--mode", "kinematic", "--duration", "3", "--param", "world_camera=false"],
        capture_output=True, text=True, timeout=120, env=env(),
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    assert "real-time factor" in out.stderr and "stopped at sim time" in out.stderr


def test_bad_parameter_is_a_clear_error() -> None:
    out = subprocess.run(
        [*GO2VLM, "run", "sim", "--param", "mode=flying", "--duration", "1"],
        capture_output=True, text=True, timeout=60, env=env(),
    )  # fmt: skip
    assert out.returncode == 2
    assert "mode" in out.stderr and "flying" in out.stderr
