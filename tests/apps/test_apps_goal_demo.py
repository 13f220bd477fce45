"""Each goal type in the MuJoCo sim (kinematic physics, 2x real time): sim, target_tracker, commander,
follower and the safety gate in one process, talking over real DDS; success judged from the sim's
ground truth."""

from __future__ import annotations

import json
import math
import threading
import time

import pytest

pytest.importorskip("mujoco")

from busutil import wait_for  # noqa: E402

from go2vlm.apps.episodes import RunOptions, run_episode  # noqa: E402
from go2vlm.apps.episodes.demo import goal_episode  # noqa: E402
from go2vlm.behavior.navigate import NavParams  # noqa: E402
from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node, ShutdownRequested, running  # noqa: E402
from go2vlm.launch.registry import make_node  # noqa: E402
from go2vlm.msgs.geometry_msgs import Twist  # noqa: E402
from go2vlm.msgs.std_msgs import String  # noqa: E402
from go2vlm.msgs.tf2_msgs import TFMessage  # noqa: E402
from go2vlm.safety.limits import Limits  # noqa: E402

# Slow: every test is a goal-demo run in the MuJoCo sim.
pytestmark = pytest.mark.slow

RTF = 2.0


def run(goal: str, **kw) -> dict:
    """`go2vlm demo --goal` as a function: the episode runner, nothing written."""
    ep = goal_episode(goal, mode="kinematic", **kw)
    return run_episode(ep, RunOptions(rtf=RTF, video=False), ShutdownRequested()).metrics


def test_go_to_the_blue_cylinder_stops_within_a_metre_without_collision() -> None:
    m = run("go to the blue cylinder", duration_s=40.0)
    assert m["final_state"] == "reached", m
    assert m["states"][0] == "searching" and "approaching" in m["states"]  # it starts out of view
    assert m["goal_reached"]
    assert 0.5 <= m["final_distance_m"] <= 1.0  # base centre -> cylinder surface (centre distance - 0.3)
    assert m["collisions"] == 0 and m["min_clearance_m"] > 0.2
    assert m["final_cmd"] == [0.0, 0.0]  # and it stays stopped
    # the navigator's top speed, past 0.5 m/s only where the guard's stopping envelope holds
    assert m["max_abs_cmd_vx"] <= min(NavParams().max_speed, Limits().vx_forward) + 1e-6
    assert m["time_to_goal_s"] is not None


def test_look_for_the_green_box_in_chinese() -> None:
    m = run("找一下绿色盒子", duration_s=30.0)
    assert m["final_state"] == "found", m
    assert m["goal_reached"] and m["target_in_view_at_end"]
    assert m["robot_distance_travelled_m"] < 0.1  # looking means turning in place
    assert m["max_abs_cmd_vx"] == 0.0


def test_follow_the_moving_red_ball() -> None:
    m = run("follow the red ball", duration_s=16.0)
    assert m["world"] == "follow_ball" and m["target_body"] == "red_ball"
    assert m["tracked_fraction"] >= 0.8, m
    assert m["within_follow_distance_fraction"] >= 0.8, m
    assert m["robot_distance_travelled_m"] > 1.5  # it went after the ball
    assert m["collisions"] == 0


class _Probe(Node):
    name = "goal_probe"

    def __init__(self, **kw) -> None:
        super().__init__(**kw)
        self.lock = threading.Lock()
        self.status: list[dict] = []
        self.cmd: list[tuple[float, float, float]] = []  # monotonic, vx, wz on /cmd_vel
        self.go2: list[str] = []
        self.robot: tuple[float, float] | None = None
        self.goal_pub = self.create_publisher(String, "/goal", QOS_DEFAULT)
        self.create_subscription(String, "/commander/status", self._on_status, QOS_LATCHED)
        self.create_subscription(Twist, "/cmd_vel", self._on_cmd, QOS_DEFAULT)
        self.create_subscription(String, "/go2/command", lambda m: self.go2.append(m.data), QOS_DEFAULT)
        self.create_subscription(TFMessage, "/sim/ground_truth", self._on_gt, QOS_DEFAULT)

    def _on_status(self, msg: String) -> None:
        with self.lock:
            self.status.append(json.loads(msg.data))

    def _on_cmd(self, msg: Twist) -> None:
        with self.lock:
            self.cmd.append((time.monotonic(), msg.linear.x, msg.angular.z))

    def _on_gt(self, msg: TFMessage) -> None:
        for tf in msg.transforms:
            if tf.child_frame_id == "gt/go2":
                self.robot = (tf.transform.translation.x, tf.transform.translation.y)

    def state(self) -> dict:
        with self.lock:
            return self.status[-1] if self.status else {}

    def send(self, text: str) -> None:
        self.goal_pub.publish(String(data=text))


def test_stop_and_unparseable_goals_interrupt_motion_and_sit_stand_are_forwarded() -> None:
    sim = make_node("sim", params={"world": "vision_test", "mode": "kinematic", "rtf": RTF, "world_camera": False})
    tracker = make_node("target_tracker")
    commander = make_node("commander", params={"goal": "go to the blue cylinder"})
    gate = make_node("safety")
    probe = _Probe()
    with running(probe, sim, tracker, commander, gate):
        assert wait_for(lambda: probe.goal_pub.matched >= 1, 10)
        assert wait_for(lambda: probe.state().get("state") == "approaching", 30), probe.state()
        assert wait_for(lambda: probe.cmd and probe.cmd[-1][1] > 0.05, 10)  # walking

        def still_after(text: str, state: str) -> None:
            probe.send(text)
            assert wait_for(lambda: probe.state().get("state") == state, 5), probe.state()
            t_sent = time.monotonic()
            # /cmd_vel goes to exactly zero and the robot stops moving
            assert wait_for(lambda: probe.cmd[-1][1:] == (0.0, 0.0), 2)
            assert all(c[1:] == (0.0, 0.0) for c in probe.cmd if c[0] > t_sent + 0.3)
            time.sleep(0.3)
            p0 = probe.robot
            time.sleep(1.0)
            assert math.dist(p0, probe.robot) < 0.02, "the robot kept moving"

        still_after("xyzzy plugh", "rejected")
        st = probe.state()
        assert st["reason"].startswith("cannot understand") and st["goal"] == "xyzzy plugh"
        probe.send("go to the blue cylinder")
        assert wait_for(lambda: probe.state().get("state") == "approaching", 30), probe.state()
        still_after("停下", "stopped")
        probe.send("sit")
        assert wait_for(lambda: probe.go2 == ["sit"], 5)
        probe.send("站起来")
        assert wait_for(lambda: probe.go2 == ["sit", "stand"], 5)
        assert probe.state()["state"] == "done"


def test_look_for_something_absent_gives_up_and_stays_still() -> None:
    # Where it stands: exploring the house for it is tests/apps/test_apps_cross_room.py's.
    m = run("find the yellow ball", duration_s=20.0, params={"commander": {"search_timeout_s": 2.0, "explore": False}})
    assert m["final_state"] == "not_found" and not m["goal_reached"], m
    assert m["states"] == ["searching", "not_found"]
    assert m["final_cmd"] == [0.0, 0.0] and m["robot_distance_travelled_m"] < 0.1
