"""`go2vlm objects` against a running object_memory (a real process over real DDS): it lists what the
robot remembers, answers "where is X?", saves the memory and loads it back, refuses a corrupt file, a
file of another world and one of a newer version with one line (exit 2, nothing loaded), and reads a
saved file without a robot."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from busutil import GO2VLM, env, wait_for
from targetutil import det
from world.worldutil import CAM, CYL, Robot, cylinder_box

from go2vlm.bus import running
from go2vlm.msgs.image import camera_info
from go2vlm.msgs.vision_msgs import Detection2DArray
from go2vlm.world.poses import Pose2D


def objects(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*GO2VLM, "objects", *args], capture_output=True, text=True, timeout=timeout, env=env())


def test_list_where_save_load(procs, tmp_path: Path) -> None:
    mem = procs.start("run", "object_memory", "--param", "world=home", "--param", "image_topic=",
                      "--param", "scan_topic=")  # fmt: skip
    robot = Robot()
    with running(robot):
        assert wait_for(lambda: robot.answers.matched >= 1 and robot.info.matched >= 1, 30), mem
        robot.info.publish(camera_info(CAM))
        assert wait_for(robot.ready, 20)
        box = cylinder_box(Pose2D(0, 0, 0), CYL, 0.3, 1.5)
        assert box is not None
        for _ in range(3):  # three answers agree: a confident blue cylinder
            h = robot.header("camera_optical_frame", robot.now() - 0.1)
            robot.answers.publish(Detection2DArray(header=h, detections=[det("blue cylinder", *box, h)]))
            assert wait_for(lambda: robot.last_status().get("placed", 0) >= 1, 10)
        assert wait_for(lambda: next(iter(robot.memory().values())).confidence > 0.85, 10)

        listed = objects()
        assert listed.returncode == 0, listed.stderr
        line = next(ln for ln in listed.stdout.splitlines() if ln.startswith("blue_cylinder_1"))
        assert "blue cylinder" in line and "3.0" in line and "(odom)" in listed.stdout
        rows = json.loads(objects("--json").stdout)
        assert rows[0]["label"] == "blue cylinder" and abs(rows[0]["x"] - CYL[0]) < 0.05

        where = objects("--where", "the blue cylinder")
        assert where.returncode == 0 and where.stdout.startswith("blue cylinder at (3.0"), where
        assert objects("--where", "red ball").returncode == 1

        folder = tmp_path / "state" / "go2vlm" / "objects"  # the memory's files: its state directory only
        saved = folder / "home.json"
        rep = objects("--save", "home")
        assert rep.returncode == 0 and "saved 1 object" in rep.stdout, rep
        again = objects("--save", "home")
        assert again.returncode == 2 and "overwrite" in again.stderr, again
        assert objects("--save", str(saved), "--overwrite").returncode == 0
        outside = objects("--save", str(tmp_path / "elsewhere.json"))
        assert outside.returncode == 2 and "refused" in outside.stderr, outside
        assert "objects/<name>.json" in outside.stderr, outside  # where a memory file may go
        assert not (tmp_path / "elsewhere.json").exists()
        doc = json.loads(saved.read_text())
        bad = {"corrupt.json": '{"format": "go2vlm-object-memory", "ver',
               "office.json": json.dumps({**doc, "world": "office"}),
               "future.json": json.dumps({**doc, "version": 99})}  # fmt: skip
        for name, text in bad.items():
            (folder / name).write_text(text)
            rep = objects("--load", name)
            assert rep.returncode == 2 and len(rep.stderr.strip().splitlines()) == 1, (name, rep)
        assert "world 'office'" in objects("--load", "office").stderr
        assert "newer go2vlm" in objects("--load", str(folder / "future.json")).stderr
        assert set(robot.memory()) == {"blue_cylinder_1"}  # nothing half-loaded
        doc["objects"][0].update(id="red_ball_2", label="red ball", x=-1.5, y=0.5)
        saved.write_text(json.dumps(doc))
        rep = objects("--load", "home.json")
        assert rep.returncode == 0 and "loaded 1 object" in rep.stdout, rep
        assert wait_for(lambda: set(robot.memory()) == {"red_ball_2"}, 10)

    offline = objects("--file", str(saved))
    assert offline.returncode == 0 and "world 'home'" in offline.stdout and "red_ball_2" in offline.stdout
    assert objects("--file", str(saved), "--where", "ball").stdout.startswith("red ball at (-1.50, 0.50)")
    assert objects("--file", str(folder / "corrupt.json")).returncode == 2


def test_no_memory_running_is_a_clear_failure() -> None:
    rep = objects("--timeout", "1")
    assert rep.returncode == 1 and "no object memory publishes /objects" in rep.stderr
