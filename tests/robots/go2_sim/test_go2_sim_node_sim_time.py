"""The sim node with use_sim_time, as a real process: it is the clock (/clock after every 10 ms
physics chunk) and every header it publishes carries the sim time of the state it describes."""

from __future__ import annotations

import json

from busutil import Procs, Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.sensor_msgs import CameraInfo, Image
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.tf2_msgs import TFMessage


class Probe(Node):
    name = "sim_time_sim_probe"

    def __init__(self) -> None:
        super().__init__()
        self.rec = {t: Recorder() for t in ("clock", "odom", "image", "info", "gt", "status", "tf_static")}
        self.create_subscription(Clock, "/clock", self.rec["clock"], QOS_DEFAULT)
        self.create_subscription(Odometry, "/odom", self.rec["odom"], QOS_DEFAULT)
        self.create_subscription(Image, "/camera/image_raw", self.rec["image"], QOS_SENSOR)
        self.create_subscription(CameraInfo, "/camera/camera_info", self.rec["info"], QOS_DEFAULT)
        self.create_subscription(TFMessage, "/sim/ground_truth", self.rec["gt"], QOS_DEFAULT)
        self.create_subscription(String, "/sim/status", self.rec["status"], QOS_LATCHED)
        self.create_subscription(TFMessage, "/tf_static", self.rec["tf_static"], QOS_LATCHED)


def _sec(stamp: object) -> float:
    return round(stamp.to_sec(), 6)  # type: ignore[attr-defined]


def _on_grid(ts: list[float], step: float) -> bool:
    """All of `ts` are whole multiples of `step` (sim times of physics chunks, not wall times)."""
    return all(abs(t / step - round(t / step)) < 1e-6 for t in ts)


def test_sim_with_use_sim_time_stamps_sim_time_and_publishes_clock_every_chunk(procs: Procs) -> None:
    probe = Probe().start()
    try:
        procs.start(
            "run", "sim", "--param", "use_sim_time=true", "--param", "mode=kinematic", "--param", "world_camera=false",
            "--param", "camera_width=64", "--param", "camera_height=48", "--param", "rtf=2",
        )  # fmt: skip
        r = probe.rec
        assert wait_for(lambda: len(r["image"]) >= 5 and len(r["odom"]) >= 50 and len(r["gt"]) >= 5, 90.0), {
            k: len(v) for k, v in r.items()
        }
        clock = [_sec(m.clock) for m in r["clock"].msgs()]
        assert clock == sorted(clock) and clock[-1] < 1000.0, "sim time, not the epoch"
        steps = [round(b - a, 6) for a, b in zip(clock, clock[1:], strict=False)]
        assert 0.01 in steps and _on_grid(steps, 0.01), f"/clock after every 10 ms chunk: {sorted(set(steps))}"
        # Every header is the sim time of its state (on the chunk grid), not wall time.
        odom = [_sec(m.header.stamp) for m in r["odom"].msgs()]
        assert odom == sorted(odom) and _on_grid(odom, 0.02), f"50 Hz of sim time: {odom[:10]}"
        images = [_sec(m.header.stamp) for m in r["image"].msgs()]
        assert _on_grid(images, 0.1), f"10 Hz of sim time: {images}"
        infos = {_sec(m.header.stamp) for m in r["info"].msgs()}
        assert set(images) <= infos, "camera_info carries its image's stamp"
        gt = [_sec(m.transforms[0].header.stamp) for m in r["gt"].msgs()]
        assert _on_grid(gt, 0.05) and max(gt) < 1000.0, f"20 Hz of sim time: {gt[:5]}"
        assert all(_sec(tf.header.stamp) == 0.0 for tf in r["tf_static"].msgs()[-1].transforms), "at start-up"
        status = json.loads(r["status"].msgs()[-1].data)
        assert status["use_sim_time"] is True and status["wall_time"] > 1e9, "status keeps wall time beside sim time"
    finally:
        probe.shutdown()
