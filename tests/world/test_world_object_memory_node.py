"""The object_memory node over real DDS: a late answer is placed at the pose of its frame although the
robot has turned since, /objects and the markers say so (latched), "where is X?" is answered on the
bus, the memory is saved and loaded all or nothing, and bad answers are refused with a reason."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from busutil import wait_for
from targetutil import det
from worldutil import CAM, CYL, Robot, cylinder_box

from go2vlm.bus import running
from go2vlm.bus.service import ServiceClient
from go2vlm.launch.registry import make_node
from go2vlm.msgs.go2vlm_msgs import MemoryFile, WhereIs
from go2vlm.msgs.image import camera_info
from go2vlm.msgs.std_msgs import Header
from go2vlm.msgs.vision_msgs import Detection2DArray
from go2vlm.world.poses import Pose2D


def test_a_late_answer_lands_where_the_object_is_and_bad_ones_are_refused(tmp_path: Path) -> None:
    mem = make_node("object_memory", params={"image_topic": "", "scan_topic": "", "world": "home", "history_s": 5.0})
    robot = Robot()
    with running(robot, mem):
        assert wait_for(lambda: robot.answers.matched >= 1 and robot.odom.matched >= 1, 10)
        assert wait_for(lambda: robot.last_status().get("poses_s", 0) > 0.5, 10)
        box = cylinder_box(Pose2D(0, 0, 0), CYL, 0.3, 1.5)
        assert box is not None
        t_frame = robot.now() - 0.2  # the robot faces +x; the frame is 0.2 s old
        h = robot.header("camera_optical_frame", t_frame)
        answer = Detection2DArray(header=h, detections=[det("blue cylinder", *box, h)])
        # No CameraInfo yet, no stamp, NaN and absurd boxes: refused with a reason.
        robot.answers.publish(answer)
        assert wait_for(lambda: robot.refused("no_camera_info") >= 1, 5)
        robot.info.publish(camera_info(CAM))
        assert wait_for(lambda: robot.last_status().get("camera_info"), 5)
        zero = Header(frame_id="camera_optical_frame")
        robot.answers.publish(Detection2DArray(header=zero, detections=[det("blue cylinder", *box, zero)]))
        bad = det("blue cylinder", *box, h)
        bad.bbox.size_x = math.nan
        absurd = det("red ball", -5000, -5000, 9000, 9000, h)
        robot.answers.publish(Detection2DArray(header=h, detections=[bad, absurd]))
        assert wait_for(lambda: robot.refused("no_stamp") >= 1 and robot.refused("bad_box") >= 2, 5)
        assert robot.memory() == {}
        # The robot turns fast after the frame; the answer comes 1.5 s late and lands on the cylinder.
        robot.wz = 1.5
        assert wait_for(lambda: robot.yaw > 2.0, 5)
        robot.answers.publish(answer)
        assert wait_for(lambda: len(robot.memory()) == 1, 5)
        (obj,) = robot.memory().values()
        assert obj.label == "blue cylinder" and obj.id == "blue_cylinder_1"
        assert math.hypot(obj.x - CYL[0], obj.y - CYL[1]) < 0.05, obj
        assert abs(obj.size[0] - 0.6) < 0.05 and abs(obj.size[2] - 1.5) < 0.1 and obj.confidence == 0.5
        assert abs(obj.last_seen - t_frame) < 1e-6
        with robot.lock:
            assert robot.objects[-1].header.frame_id == "odom"
            assert abs(robot.objects[-1].header.stamp.to_sec() - t_frame) < 1e-6
        assert wait_for(lambda: any(m.text.startswith("blue cylinder") for a in robot.markers for m in a.markers), 5)
        # An answer older than the pose history says so and is not placed.
        old = robot.header("camera_optical_frame", robot.now() - 8.0)
        robot.answers.publish(Detection2DArray(header=old, detections=[det("green box", *box, old)]))
        assert wait_for(lambda: robot.refused("older_than_history") >= 1, 5)
        assert set(robot.memory()) == {"blue_cylinder_1"}
        assert "older_than_history" in robot.last_status()["last_refusal"]

        # "Where is the blue cylinder?" on the bus.
        with ServiceClient(WhereIs, "/object_memory/where_is", robot.participant) as where:
            rep = where.call(WhereIs.Request(label="the blue cylinder"), 10)
            assert rep.found and "blue cylinder at (3.0" in rep.message and len(rep.objects) == 1
            assert rep.objects[0].id == "blue_cylinder_1"
            rep = where.call(WhereIs.Request(label="red ball"), 10)
            assert not rep.found and "blue cylinder" in rep.message and rep.objects == []

        # Saved, then a corrupt file and a file of another world are refused and change nothing.
        with ServiceClient(MemoryFile, "/object_memory/memory_file", robot.participant) as files:
            folder = tmp_path / "state" / "go2vlm" / "objects"  # a name is a file in the state directory
            path = folder / "home.json"
            rep = files.call(MemoryFile.Request(command="save", path="home"), 10)
            assert rep.success and rep.objects == 1 and json.loads(path.read_text())["world"] == "home"
            rep = files.call(MemoryFile.Request(command="save", path="home"), 10)
            assert not rep.success and "overwrite=true" in rep.message
            rep = files.call(MemoryFile.Request(command="save", path=str(path), overwrite=True), 10)
            assert rep.success, rep.message
            (folder / "bad.json").write_text('{"format": "go2vlm-object-memory", "version": 1, "world": "ho')
            other = json.loads(path.read_text())
            other["world"] = "office"
            (folder / "office.json").write_text(json.dumps(other))
            for name, says in (("bad.json", "not JSON"), ("office.json", "world 'office'"), ("none.json", "No such")):
                rep = files.call(MemoryFile.Request(command="load", path=name), 10)
                assert not rep.success and says in rep.message and "\n" not in rep.message
            assert set(robot.memory()) == {"blue_cylinder_1"}
            doc = json.loads(path.read_text())
            doc["objects"][0].update(id="red_ball_7", label="red ball", x=-1.0)
            path.write_text(json.dumps(doc))
            rep = files.call(MemoryFile.Request(command="load", path=str(path)), 10)
            assert rep.success and rep.objects == 1
            assert wait_for(lambda: set(robot.memory()) == {"red_ball_7"}, 5)


def test_a_flood_of_answers_cannot_grow_it() -> None:
    mem = make_node("object_memory", params={"image_topic": "", "scan_topic": "", "max_objects": 8})
    robot = Robot()
    rng = np.random.default_rng(0)
    with running(robot, mem):
        assert wait_for(lambda: robot.answers.matched >= 1 and robot.info.matched >= 1, 10)
        robot.info.publish(camera_info(CAM))
        assert wait_for(robot.ready, 10)
        sent = 0

        def flood() -> bool:
            """20 new things at a time (keep-last 10: not all arrive), until the memory has refused 10."""
            nonlocal sent
            for _ in range(20):
                h = robot.header("camera_optical_frame", robot.now() - 0.05)
                x1, y1 = rng.uniform(0, 600), rng.uniform(100, 400)
                robot.answers.publish(Detection2DArray(header=h, detections=[
                    det(f"thing {sent}", x1, y1, x1 + 30, y1 + 60, h)]))  # fmt: skip
                sent += 1
            assert len(robot.memory()) <= 8
            return robot.refused("memory_full") >= 10

        # Full, the memory refuses new things rather than grow.
        assert wait_for(flood, 60, 0.05), (sent, robot.last_status())
        assert robot.last_status()["objects"] == 8 and len(robot.memory()) <= 8
