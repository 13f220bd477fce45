"""`go2vlm objects --save/--load` with a map node running (real processes over real DDS): the map is
saved beside the memory's file and loaded with it; a bad map file beside a good memory file loads
nothing, the memory neither."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from busutil import GO2VLM, env, wait_for

from go2vlm.bus import Node, running
from go2vlm.bus.topics import MAP_STATUS, OBJECT_MEMORY_STATUS
from go2vlm.statefiles import state_dir


def objects(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*GO2VLM, "objects", *args], capture_output=True, text=True, timeout=timeout, env=env())


def test_the_map_goes_with_the_memory(procs, tmp_path: Path) -> None:
    files_dir = state_dir() / "objects"  # the files must be under the state directory (statefiles.py)
    files_dir.mkdir(parents=True, exist_ok=True)
    procs.start("run", "object_memory", "--param", "world=home", "--param", "image_topic=", "--param", "scan_topic=")
    procs.start("run", "map", "--param", "world=home")
    watcher = Node(node_name="watcher")
    statuses: dict[str, dict] = {}
    MAP_STATUS.subscription(watcher, lambda m: statuses.__setitem__("map", json.loads(m.data)))
    OBJECT_MEMORY_STATUS.subscription(watcher, lambda m: statuses.__setitem__("memory", json.loads(m.data)))
    with running(watcher):
        assert wait_for(lambda: {"map", "memory"} <= set(statuses), 30)
        rep = objects("--save", str(files_dir / "home.json"))
        assert rep.returncode == 0, rep
        assert "saved 0 object" in rep.stdout and "saved the map" in rep.stdout, rep.stdout
        assert (files_dir / "home.json").exists() and (files_dir / "home.map.npz").exists()
        # A map file of another world beside a good memory file: nothing is loaded.
        doc = json.loads((files_dir / "home.json").read_text())
        doc["objects"] = [{"id": "red_ball_1", "label": "red ball", "x": 1.0, "y": 0.0, "z": 0.1,
                           "cov": [0.01, 0.0, 0.01], "size": [0.2, 0.2, 0.2], "logodds": 2.0, "seen": 3,
                           "refused": 0, "missed": 0, "first_seen": 1.0, "last_seen": 2.0}]  # fmt: skip
        (files_dir / "office.json").write_text(json.dumps(doc))
        (files_dir / "office.map.npz").write_bytes(b"not a map")
        rep = objects("--load", str(files_dir / "office.json"))
        assert rep.returncode == 2 and "nothing loaded" in rep.stderr and "not a map file" in rep.stderr, rep
        assert len(rep.stderr.strip().splitlines()) == 1
        assert wait_for(lambda: statuses["memory"]["objects"] == 0, 5)
        # The good pair loads, both.
        (files_dir / "office.map.npz").write_bytes((files_dir / "home.map.npz").read_bytes())
        rep = objects("--load", str(files_dir / "office.json"))
        assert rep.returncode == 0 and "loaded 1 object" in rep.stdout and "loaded the map" in rep.stdout, rep
        assert wait_for(lambda: statuses["memory"]["objects"] == 1, 10)
