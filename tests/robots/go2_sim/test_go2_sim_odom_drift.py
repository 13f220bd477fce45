"""The sim node's `odom_drift`, over real DDS from a real process: walking, /odom and rt/sportmodestate
report one drifting pose, away from the true one (/sim/ground_truth), and the same seed drifts alike."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator

import pytest
from busutil import Procs, Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_UNITREE_READER, Node, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.tf2_msgs import TFMessage
from go2vlm.msgs.unitree import SportModeState
from go2vlm.robots.go2 import protocol as p

pytestmark = pytest.mark.slow  # a sim process walks for a few seconds

GAIN = 5.0  # five times a Go2's drift: plain to see after a few metres


class Probe(Node):
    name = "drift_probe"


@pytest.fixture(scope="module")
def drifting() -> Iterator[tuple[Probe, dict[str, Recorder]]]:
    procs = Procs()
    procs.start(
        "run", "sim",
        *("--param", "mode=kinematic", "--param", "world=empty", "--param", "unitree=true"),
        *("--param", "camera=false", "--param", "world_camera=false"),
        *("--param", f"odom_drift={GAIN}", "--param", "seed=3"),
    )  # fmt: skip
    probe = Probe()
    recs = {k: Recorder() for k in ("odom", "gt", "sport", "status")}
    probe.create_subscription(Odometry, "/odom", recs["odom"], QOS_DEFAULT)
    probe.create_subscription(TFMessage, "/sim/ground_truth", recs["gt"], QOS_DEFAULT)
    probe.create_subscription(SportModeState, p.SPORT_STATE_TOPIC, recs["sport"], QOS_UNITREE_READER)
    probe.create_subscription(String, "/sim/status", recs["status"], QOS_LATCHED)
    probe.start()
    try:
        assert wait_for(lambda: all(len(r) for r in recs.values()), 60), {k: len(r) for k, r in recs.items()}
        yield probe, recs
    finally:
        probe.shutdown()
        procs.stop_all()


def _true_xy(recs: dict[str, Recorder]) -> tuple[float, float]:
    t = next(t for t in recs["gt"].msgs()[-1].transforms if t.child_frame_id == "gt/go2").transform.translation
    return t.x, t.y


def _odom_xy(recs: dict[str, Recorder]) -> tuple[float, float]:
    q = recs["odom"].msgs()[-1].pose.pose.position
    return q.x, q.y


def test_walking_drifts_odom_and_the_unitree_state_alike(drifting: tuple[Probe, dict[str, Recorder]]) -> None:
    probe, recs = drifting
    assert json.loads(recs["status"].msgs()[-1].data)["odom_drift"] == GAIN
    assert math.dist(_true_xy(recs), _odom_xy(recs)) < 0.01, "standing: no drift yet"
    start = _true_xy(recs)
    gate = make_node("safety", params={"max_vx_forward": 0.5})
    pub = probe.create_publisher(Twist, "/teleop/cmd_vel", QOS_DEFAULT)
    with running(gate):

        def walked(d: float) -> bool:
            pub.publish(Twist(linear=Vector3(0.5, 0.0, 0.0)))
            return math.dist(_true_xy(recs), start) > d

        assert wait_for(lambda: walked(3.0), 90), "the robot never walked 3 m"
    # Stopped (the gate is gone): the drift is what it was, and both outputs say the same.
    assert wait_for(lambda: json.loads(recs["status"].msgs()[-1].data)["cmd_timed_out"] is True, 30)
    n = len(recs["odom"])
    assert wait_for(lambda: len(recs["odom"]) > n + 20, 30)
    off = math.dist(_true_xy(recs), _odom_xy(recs))
    assert 0.1 < off < 2.0, f"odom is {off:.3f} m from the truth after ~3 m at gain {GAIN}"
    sport = recs["sport"].msgs()[-1]
    assert math.dist((sport.position[0], sport.position[1]), _odom_xy(recs)) < 0.02
    q = recs["odom"].msgs()[-1].pose.pose.orientation
    yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y**2 + q.z**2))
    assert abs(math.remainder(sport.imu_state.rpy[2] - yaw, 2 * math.pi)) < 0.01
