"""Bad VLM answers in the closed loop, in the MuJoCo sim (the node-level version is
tests/perception/vlm/test_vlm_bad_answers.py): the target_tracker, the commander, the safety gate and
the sim, through the episode runner, judged from the sim's ground truth.

- A wrong box: a lying VLM labels the green box "blue cylinder" on every frame it is in view (the sim's
  ground-truth box of the green box, delivered on /vlm/detections with its frame's stamp, as the vlm
  node would). The robot starts facing the green box.
- A server that answers HTTP 500: the real vlm node (openai backend) gets no answer at all. The robot
  starts with the blue cylinder in plain view.
In both the robot may only search (turn in place): no forward motion, no distance covered, the tracker
never confirms anything, and every refusal or error is counted."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("mujoco")

from perception.vlm.test_vlm_bad_answers import _FailingServer  # noqa: E402

from go2vlm.apps.episodes import Episode, RunOptions, run_episode  # noqa: E402
from go2vlm.bus import QOS_DEFAULT, Node, ShutdownRequested, running  # noqa: E402
from go2vlm.msgs.vision_msgs import Detection2DArray, detection_array, detection_boxes  # noqa: E402

pytestmark = pytest.mark.slow

GOAL = "go to the blue cylinder"
# The VLM graph's nodes, but the answers come from the test's lying VLM on /vlm/detections.
LIAR_GRAPH = """
- node: sim
  params: {use_sim_time: true, world: vision_test, world_camera: false, detections: true}
- node: target_tracker
  params: {use_sim_time: true, grounding: vlm}
- node: commander
  params: {use_sim_time: true, search_yaw_rate: 0.25}
- node: follower
  params: {use_sim_time: true}
- node: safety
  params: {use_sim_time: true}
"""


class LyingVlm(Node):
    """Every frame's ground truth (/sim/detections) -> /vlm/detections with the green box's box labelled
    as the goal's object: a confident answer on the wrong object, about the right frame."""

    name = "lying_vlm"

    def __init__(self, **kw: Any) -> None:
        super().__init__(**kw)
        self.lies = 0
        self.pub = self.create_publisher(Detection2DArray, "/vlm/detections", QOS_DEFAULT)
        self.create_subscription(Detection2DArray, "/sim/detections", self.on_truth, QOS_DEFAULT)

    def on_truth(self, msg: Detection2DArray) -> None:
        boxes = [("blue cylinder", box, 0.99) for label, box, _ in detection_boxes(msg) if label == "green_box"]
        self.lies += bool(boxes)
        self.pub.publish(detection_array(msg.header, boxes))


def assert_only_searched(m: dict[str, Any]) -> None:
    brief = {k: m[k] for k in ("states", "tracker", "grounding", "vlm", "robot_distance_travelled_m", "max_abs_cmd_vx")}
    assert m["collisions"] == 0 and not m["fell"] and not m["success"], brief
    assert m["tracker"]["tracking_frames"] == 0, brief  # nothing confirmed
    assert m["tracker"]["forward_cmds"] == 0 and m["max_abs_cmd_vx"] == 0.0, brief  # never drove toward anything
    assert m["robot_distance_travelled_m"] < 0.1, brief  # turning in place only (ground truth)
    assert "approaching" not in m["states"] and m["states"][0] == "searching", brief
    assert m["max_abs_cmd_wz"] > 0.1, brief  # it did search


def test_a_box_on_the_wrong_object_is_never_approached(tmp_path: Path) -> None:
    graph = tmp_path / "liar.yaml"
    graph.write_text(LIAR_GRAPH)
    # Facing the green box at (0, 2) from 2.5 m; the blue cylinder at (-2, 0) is out of view.
    ep = Episode(world="vision_test", goal=GOAL, perception="vlm", spawn=(0.0, -0.5, math.pi / 2), duration_s=15.0,
                 graph=str(graph), mode="kinematic")  # fmt: skip
    liar = LyingVlm()
    with running(liar):
        m = run_episode(ep, RunOptions(rtf=1.0, video=False), ShutdownRequested()).metrics
    assert liar.lies >= 5
    g = m["grounding"]
    assert g["wrong_object"] >= 5 and g["hits"] == 0, g  # the metrics see the lie for what it is
    assert_only_searched(m)
    assert m["min_distance_m"] >= 1.5 - 0.05  # the green box's surface was 1.5 m away and stayed so


def test_a_server_answering_http_500_moves_nothing(tmp_path: Path) -> None:
    pytest.importorskip("openai")
    server = _FailingServer()
    try:
        # The blue cylinder at (-2, 0) in plain view, 2.7 m ahead.
        ep = Episode(world="vision_test", goal=GOAL, perception="vlm", spawn=(0.7, 0.0, math.pi), duration_s=12.0,
                     mode="kinematic",
                     params={"vlm": {"backend": "openai", "base_url": server.url, "model": "failing-test-server",
                                     "timeout_s": 1.0, "retries": 1, "period_s": 0.2}})  # fmt: skip
        m = run_episode(ep, RunOptions(rtf=1.0, video=False), ShutdownRequested()).metrics
    finally:
        server.close()
    assert server.requests >= 4
    assert m["grounding"] is None or m["grounding"]["answers"] == 0  # no answer ever came
    assert (m["vlm"]["errors"] or {}).get("backend_errors", 0) >= 2, m["vlm"]  # counted
    assert_only_searched(m)
