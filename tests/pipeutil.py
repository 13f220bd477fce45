"""Helpers for the follow-pipeline tests (the VLM article's test pattern, section 3.3, into the follow
article's colour detector and follower, sections 5.2/5.3, behind the safety gate): an in-process probe
node on the real bus, and the pipeline's nodes started as real `go2vlm run` processes."""

from __future__ import annotations

import math
import subprocess
from pathlib import Path
from typing import Any

from busutil import Procs, Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node
from go2vlm.msgs.geometry_msgs import PointStamped, Twist
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.std_msgs import Bool, String

EXPECTED_WZ = -0.8 * (450 - 320) / 320  # the follow article's follower on the VLM article's test pattern: -0.325

# Per-node arguments for the follow pipeline in tests: a fast camera so the loop settles quickly.
PIPELINE: dict[str, list[str]] = {
    "test_pattern": ["run", "test_pattern", "--param", "period_s=0.1"],
    "color_detector": ["run", "color_detector"],
    "follower": ["run", "follower"],
    "safety": ["run", "safety"],
}


class Probe(Node):
    """Records /cmd_vel, /safety/status, /detected_target and images; publishes e-stop and release."""

    name = "pipeline_probe"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.cmd = Recorder()
        self.status = Recorder()
        self.targets = Recorder()
        self.images = Recorder()
        self.follower_cmd = Recorder()
        self.create_subscription(Twist, "/cmd_vel", self.cmd, QOS_DEFAULT)
        self.create_subscription(String, "/safety/status", self.status, QOS_LATCHED)
        self.targets_sub = self.create_subscription(PointStamped, "/detected_target", self.targets, QOS_DEFAULT)
        self.create_subscription(Image, "/camera/image_raw", self.images, QOS_SENSOR)
        self.follower_sub = self.create_subscription(Twist, "/follower/cmd_vel", self.follower_cmd, QOS_DEFAULT)
        self.estop_pub = self.create_publisher(Bool, "/emergency_stop", QOS_LATCHED)
        self.release_pub = self.create_publisher(String, "/emergency_stop/release", QOS_DEFAULT)

    def items_after(self, t: float) -> list[tuple[float, Twist]]:
        with self.cmd.lock:
            return [(ts, m) for ts, m in self.cmd.items if ts >= t]

    def settled(self, wz: float = EXPECTED_WZ, tol: float = 0.02, n: int = 10) -> bool:
        """The last n /cmd_vel messages all turn at `wz` (+-tol) without moving forward."""
        msgs = self.cmd.msgs()[-n:]
        return len(msgs) == n and all(abs(m.angular.z - wz) <= tol and m.linear.x == 0.0 for m in msgs)

    def first_zero_after(self, t: float) -> float | None:
        """Seconds from `t` to the first all-zero /cmd_vel received after it."""
        for ts, m in self.items_after(t):
            if is_zero(m):
                return ts - t
        return None


def is_zero(m: Twist) -> bool:
    return all(v == 0.0 for v in (m.linear.x, m.linear.y, m.linear.z, m.angular.x, m.angular.y, m.angular.z))


def finite(m: Twist) -> bool:
    return all(math.isfinite(v) for v in (m.linear.x, m.linear.y, m.linear.z, m.angular.x, m.angular.y, m.angular.z))


def start(procs: Procs, kind: str, logs: Path, *extra: str) -> subprocess.Popen[str]:
    """A pipeline node as a real process; its log goes to a file (a full pipe would block it)."""
    log = open(logs / f"{kind}.log", "w")  # noqa: SIM115 - closed when the process ends
    return procs.start(*PIPELINE[kind], *extra, stdout=log, stderr=subprocess.STDOUT)


def wait_settled(probe: Probe, timeout: float = 25.0) -> None:
    ok = wait_for(probe.settled, timeout)
    last = probe.cmd.msgs()[-3:]
    assert ok, f"/cmd_vel did not settle at angular.z={EXPECTED_WZ:.3f}; last: {last}"


def logs_tail(logs: Path) -> str:
    return "\n".join(f"--- {p.name}\n{p.read_text()[-1500:]}" for p in sorted(logs.glob("*.log")))


def wait_up(pred: Any, what: str, timeout: float = 20.0) -> None:
    assert wait_for(pred, timeout), f"{what} did not come up within {timeout} s"
