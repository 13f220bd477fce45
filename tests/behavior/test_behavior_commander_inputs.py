"""The commander at its new boundary, over real DDS: it publishes its goal's object on /target/query,
drives only on the target_tracker's confirmed target (a real tracker on synthetic frames), stops the
moment the tracker says lost, drives follow goals itself (no /detected_target), ignores bad tracker
reports, steers round a box on /scan and ignores a bad scan, and answers a goal it cannot parse
(given as a CLI parameter) with zero motion through the real gate; a goal with a lease stops when
its owner stops renewing it, and a go to beyond max_go_to_m is refused. Perception itself (grounding,
catching up late VLM answers, bad images and boxes) is tested at the target_tracker:
tests/perception/test_perception_tracker_node.py."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest
from busutil import echo_json, wait_for
from targetutil import Cam, det

from go2vlm.behavior.lease import LeaseKeys
from go2vlm.bus import QOS_DEFAULT, QOS_SENSOR, ParamError, running
from go2vlm.geometry.scan import ScanSpec
from go2vlm.launch.registry import make_node
from go2vlm.msgs.go2vlm_msgs import TRACKING, TrackedTarget
from go2vlm.msgs.sensor_msgs import LaserScan
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.vision_msgs import BoundingBox2D, Detection2DArray, Point2D, Pose2D


def test_go_to_drives_on_the_trackers_confirmed_target_only() -> None:
    commander = make_node("commander", params={"goal": "go to the blue cylinder"})
    tracker = make_node("target_tracker", params={"grounding": "vlm"})
    cam = Cam()
    with running(cam, tracker, commander):
        assert wait_for(lambda: cam.dets.matched >= 1 and len(cam.headers) > 12, 10)
        # The goal's object goes to the tracker (latched), which searches: the commander turns in place.
        assert wait_for(lambda: cam.last() is not None and cam.last().label == "blue cylinder", 5)
        assert wait_for(lambda: cam.cstate().get("state") == "searching" and cam.cstate().get("tracker"), 5)
        assert wait_for(lambda: cam.last_cmd() is not None and cam.last_cmd()[1] > 0.1, 5)
        assert all(vx == 0.0 for vx, _ in cam.cmds)
        # A VLM answer about a frame 1 s old grounds it: the commander approaches.
        old = cam.header_back(10)
        cam.dets.publish(Detection2DArray(header=old, detections=[det("blue cylinder", 370, 150, 430, 400, old)]))
        assert wait_for(lambda: cam.cstate().get("state") == "approaching", 5), cam.cstate()
        st = cam.cstate()
        assert st["seen"] and abs(st["x"] - (400 - 320) / 320) < 0.05 and st["tracker"] == "tracking"
        assert 1.0 < st["distance_m"] < 3.0  # base -> surface: the tracker's camera distance + 0.327 m
        cam.cx = 330  # the tracker follows it; centred, the commander walks
        assert wait_for(lambda: abs(cam.cstate().get("x") or 1) < 0.05, 5), cam.cstate()
        assert wait_for(lambda: cam.last_cmd()[0] > 0.05, 5)
        assert not cam.targets  # go to drives itself; /detected_target is for follow goals only
        # Gone: the tracker says lost, the commander stops at once, then searches towards where it was.
        cam.cx = None
        assert wait_for(lambda: cam.cstate().get("state") == "lost", 3), cam.cstate()
        assert wait_for(lambda: cam.last_cmd() == (0.0, 0.0), 1)
        assert wait_for(lambda: cam.cstate().get("state") == "searching", 5), cam.cstate()
        assert wait_for(lambda: cam.last_cmd()[1] < -0.1, 1)  # turning right, where it was last seen
        with cam.lock:
            after = cam.commander.index(next(s for s in cam.commander if s.get("state") == "lost"))
        assert all(not s["seen"] for s in cam.commander[after:])


def test_follow_drives_on_the_trackers_confirmed_target_itself() -> None:
    commander = make_node("commander", params={"goal": "follow the blue cylinder"})
    tracker = make_node("target_tracker")  # colour-shape grounding: no model
    cam = Cam()
    with running(cam, tracker, commander):
        assert wait_for(lambda: cam.cstate().get("state") == "tracking", 10), cam.cstate()
        st = cam.cstate()
        assert st["seen"] and abs(st["x"] - (400 - 320) / 320) < 0.05  # the box converted once, here
        # One law, one set of gains: the commander turns towards it (right) on /behavior/cmd_vel.
        assert wait_for(lambda: cam.last_cmd() is not None and cam.last_cmd()[1] < -0.1, 5), cam.cmds[-5:]
        assert not cam.targets  # no /detected_target: no follower in the goal graph
        cam.cx = None
        assert wait_for(lambda: cam.cstate().get("state") == "lost", 3)
        assert wait_for(lambda: cam.last_cmd() == (0.0, 0.0), 1)  # it stops at once
        n, k = len(cam.cmds), len(cam.tracked)
        assert wait_for(lambda: len(cam.tracked) > k + 5, 5)  # half a second more of frames
        assert cam.last().state != TRACKING
        with cam.lock:
            assert all(vx == 0.0 for vx, _ in cam.cmds[n:])  # no forward speed once lost
        assert not cam.targets


class _FakeTracker(Cam):
    """Publishes hand-made /target/tracked reports (the commander cannot tell them from a tracker's)."""

    name = "fake_tracker"

    def __init__(self, **kw) -> None:
        super().__init__(**kw)
        self.pub = self.create_publisher(TrackedTarget, "/target/tracked", QOS_DEFAULT)

    def report(self, label: str, cx: float, size: float, distance: float, w: int = 640, h: int = 480) -> None:
        bbox = BoundingBox2D(center=Pose2D(position=Point2D(x=cx, y=240.0)), size_x=size, size_y=size)
        self.pub.publish(TrackedTarget(header=self.header("camera"), label=label, state=TRACKING, bbox=bbox,
                                       image_width=w, image_height=h, confidence=1.0, distance_m=distance,
                                       range_method="bottom", grounding_age_s=0.1))  # fmt: skip


def test_bad_tracker_reports_and_other_labels_move_nothing() -> None:
    commander = make_node("commander", params={"goal": "go to the blue cylinder"})
    fake = _FakeTracker()
    with running(fake, commander):
        assert wait_for(lambda: fake.pub.matched >= 1 and fake.cstate().get("state") == "searching", 10)

        def bad_round() -> bool:
            fake.report("red ball", 320.0, 50.0, 2.0)  # another object
            fake.report("blue cylinder", math.nan, 50.0, 2.0)  # NaN box
            fake.report("blue cylinder", 320.0, 50.0, 2.0, w=0, h=0)  # no image size
            c = fake.cstate().get("counters", {})
            return c.get("bad_tracked", 0) >= 6 and c.get("sightings_ignored", 0) >= 3

        assert wait_for(bad_round, 10, period=0.2), fake.cstate()
        assert fake.cstate()["state"] == "searching"
        assert all(vx == 0.0 for vx, _ in fake.cmds)
        fake.report("blue cylinder", 320.0, 50.0, math.inf)  # confirmed, but no distance: turn only
        assert wait_for(lambda: fake.cstate().get("state") == "approaching", 5)
        assert fake.cstate()["distance_m"] is None and all(vx == 0.0 for vx, _ in fake.cmds)


def test_a_scan_with_a_box_ahead_makes_it_detour_and_a_bad_scan_is_ignored() -> None:
    commander = make_node("commander", params={"goal": "go to the blue cylinder"})
    fake = _FakeTracker()
    scans = fake.create_publisher(LaserScan, "/scan", QOS_SENSOR)
    sp = ScanSpec()

    def scan(ranges: np.ndarray, frame: str = "base_link") -> LaserScan:
        return LaserScan(header=fake.header(frame), angle_min=sp.angle_min, angle_max=sp.angle_max,
                         angle_increment=sp.angle_increment, range_min=sp.range_min, range_max=sp.range_max,
                         ranges=[float(r) for r in ranges])  # fmt: skip

    box = np.full(sp.bins, np.inf)
    box[sp.bins // 2 - 4 : sp.bins // 2 + 5] = 1.4  # 1.4 m straight ahead, +-8 degrees
    bad = box.copy()
    bad[3] = math.nan
    with running(fake, commander):
        assert wait_for(lambda: fake.pub.matched >= 1 and scans.matched >= 1, 10)

        def seen_with(msg: LaserScan) -> dict:
            fake.report("blue cylinder", 320.0, 80.0, 3.0)
            scans.publish(msg)
            return fake.cstate()

        assert wait_for(lambda: seen_with(scan(box)).get("state") == "detouring", 10, period=0.1), fake.cstate()
        assert fake.cstate()["planner"].startswith("steering")
        assert wait_for(lambda: fake.last_cmd() is not None and fake.last_cmd()[0] > 0.0, 5)
        # Garbage scans (a NaN range, another frame): counted, dropped; no planning on them.
        assert wait_for(
            lambda: seen_with(scan(bad)).get("counters", {}).get("bad_scan", 0) >= 3 and seen_with(scan(box, "odom")),
            10,
            period=0.1,
        )
        assert wait_for(lambda: seen_with(scan(bad)).get("state") == "approaching", 5), fake.cstate()


def test_unparseable_goal_parameter_gets_a_reply_and_no_motion(procs) -> None:
    procs.start("run", "commander", "--param", "goal=please do a backflip")
    procs.start("run", "safety")
    status = echo_json("/commander/status", count=1, timeout=30)[0]
    data = json.loads(status["data"])
    assert data["state"] == "rejected" and data["goal"] == "please do a backflip"
    assert "cannot understand" in data["reason"] and "accepted goals" in data["reason"]
    cmds = echo_json("/cmd_vel", count=10, timeout=30)
    assert all(c["linear"]["x"] == 0.0 and c["angular"]["z"] == 0.0 for c in cmds)


def test_bad_parameters_are_clear_errors() -> None:
    with pytest.raises(ParamError, match="max_turn_deg"):
        make_node("commander", params={"max_turn_deg": 45})
    with pytest.raises(ParamError, match="follow_control"):  # one follow law: the commander's own
        make_node("commander", params={"follow_control": "follower"})
    with pytest.raises(ParamError, match="grounding"):  # grounding is the target_tracker's now
        make_node("commander", params={"grounding": "vlm"})


def test_a_leased_goal_stops_when_its_owner_stops_renewing_it() -> None:
    """behavior/lease.py in the commander: renewed by its sender, the goal runs; a plain re-send keeps
    its lease; a stranger's renewal and a replayed one change nothing; unrenewed, it stops by itself;
    the status shows what is left, never the key; a bad goal message is rejected with the reason; a go
    to farther than max_go_to_m is refused."""
    commander = make_node("commander", params={"max_go_to_m": 5.0})
    fake = _FakeTracker()
    lease = fake.create_publisher(String, "/goal/lease", QOS_DEFAULT)
    keys, stranger = LeaseKeys(), LeaseKeys()
    with running(fake, commander):
        assert wait_for(lambda: fake.goal.matched >= 1 and lease.matched >= 1 and fake.cstate(), 10)
        goal = json.dumps({"goal": "look for the red ball", "lease": {"key": keys.key, "s": 1.0}})
        fake.goal.publish(String(data=goal))
        assert wait_for(lambda: fake.cstate().get("state") == "searching", 5), fake.cstate()
        st = fake.cstate()
        assert st["goal"] == "look for the red ball" and set(st["lease"]) == {"left_s", "renewals"}, st
        assert keys.key not in json.dumps(fake.cstate())
        fake.goal.publish(String(data="look for the red ball"))  # a plain re-send: the lease stays
        seen = ""
        for _ in range(20):  # 2 s of renewals (each for 3 s, so that a busy machine's stall does not end it)
            seen = keys.renewal(3.0)
            lease.publish(String(data=seen))
            lease.publish(String(data=stranger.renewal(60.0)))  # not this goal's sender
            time.sleep(0.1)  # the renewal rate, not synchronisation
        lease.publish(String(data=seen.replace('"s": 3.0', '"s": 60.0')))  # the last one seen, replayed
        assert fake.cstate()["state"] == "searching", fake.cstate()
        assert wait_for(lambda: (fake.cstate().get("lease") or {}).get("renewals") == 20, 3), fake.cstate()
        assert wait_for(lambda: fake.cstate().get("state") == "stopped", 10), fake.cstate()  # renewals stopped
        st = fake.cstate()
        assert "lease expired" in st["reason"] and st["lease"] is None, st
        assert st["counters"]["lease_not_ours"] == 21, st["counters"]
        assert wait_for(lambda: fake.last_cmd() == (0.0, 0.0), 2)
        fake.goal.publish(String(data=json.dumps({"goal": "look for the red ball", "lease": {"key": "t 2", "s": 1.0}})))
        assert wait_for(lambda: fake.cstate().get("state") == "rejected", 5), fake.cstate()
        assert "a bad goal message" in fake.cstate()["reason"] and "64 lower-case hex" in fake.cstate()["reason"]
        fake.goal.publish(String(data="go to the blue cylinder"))
        assert wait_for(lambda: fake.cstate().get("state") == "searching", 5), fake.cstate()
        fake.report("blue cylinder", 320.0, 20.0, 8.0)  # confirmed 8 m away: beyond the 5 m cap
        assert wait_for(lambda: fake.cstate().get("state") == "rejected", 5), fake.cstate()
        assert "beyond max_go_to_m = 5 m" in fake.cstate()["reason"]
        assert all(vx == 0.0 for vx, _ in fake.cmds)


def test_a_goal_that_runs_past_max_goal_s_stops() -> None:
    commander = make_node("commander", params={"max_goal_s": 1.0, "search_timeout_s": 60.0})
    fake = _FakeTracker()
    with running(fake, commander):
        assert wait_for(lambda: fake.goal.matched >= 1 and fake.cstate(), 10)
        fake.goal.publish(String(data="follow the red ball"))  # a follow never ends by itself
        assert wait_for(lambda: fake.cstate().get("goal") == "follow the red ball", 5), fake.cstate()
        assert wait_for(lambda: fake.cstate().get("state") == "stopped", 5), fake.cstate()
        assert "max_goal_s = 1 s" in fake.cstate()["reason"]
