"""Attack: a peer on the bus asks the object memory to write or read a file where it should not
(docs/safety.md, the attack table). The object_memory node runs as a real process and is asked over
its real /object_memory/memory_file service, as any DDS peer can.

- Path escapes: an absolute path elsewhere (~/.bashrc), `..`, and a symlink inside the state directory
  that leads out: refused with the reason, nothing written, the file outside untouched.
- A FIFO and an oversized (and growing) file to load: refused at once (the node never blocks), and the
  memory keeps what it had.
- A deeply nested JSON file and one with an id `ball_²`: refused, nothing half-loaded.
- An existing file is never replaced without overwrite=true.
- The gate's e-stop latch file, the memory files' folder swapped for a symlink, and the quota on the
  memory files' count and bytes (each checked against a broken build: the test's docstring).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import pytest
from busutil import Procs, wait_for

from go2vlm.bus.service import ServiceClient
from go2vlm.msgs.go2vlm_msgs import MemoryFile


def _call(client: ServiceClient, command: str, path: str, overwrite: bool = False) -> tuple[object, float]:
    t0 = time.monotonic()
    rep = client.call(MemoryFile.Request(command=command, path=path, overwrite=overwrite), 30)
    return rep, time.monotonic() - t0


def test_memory_file_escapes_fifos_and_bombs_are_refused(
    procs: Procs, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    home = tmp_path / "home"
    home.mkdir()
    bashrc = home / ".bashrc"
    bashrc.write_text("# mine\n")
    state = tmp_path / "state" / "go2vlm"  # conftest: XDG_STATE_HOME = tmp_path/state
    folder = state / "objects"
    folder.mkdir(parents=True)
    (folder / "out.json").symlink_to(bashrc)
    (folder / "dir").symlink_to(home)
    os.mkfifo(folder / "fifo.json")
    with open(folder / "big.json", "wb") as f:
        f.truncate(64 << 20)  # sparse: 64 MiB of zeros, over the 16 MiB bound
    (folder / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    doc = {"format": "go2vlm-object-memory", "version": 1, "world": "", "frame_id": "odom", "saved_at": 1.0,
           "objects": [{"id": "ball_\u00b2", "label": "red ball", "x": 1.0, "y": 0.0, "z": 0.1,
                        "cov": [0.01, 0.0, 0.01], "size": [0.2, 0.2, 0.2], "logodds": 2.0, "seen": 3,
                        "refused": 0, "missed": 0, "first_seen": 0.5, "last_seen": 0.9}]}  # fmt: skip
    (folder / "id.json").write_text(json.dumps(doc))
    monkeypatch.setenv("HOME", str(home))  # the node's ~ (and ~/.bashrc) is this one
    p = procs.start("run", "object_memory", "--param", "image_topic=", "--param", "scan_topic=")
    found: dict[str, float] = {}
    with ServiceClient(MemoryFile, "/object_memory/memory_file") as client:
        assert client.wait_for_service(60), "no object memory"
        rep, _ = _call(client, "save", "first")
        assert rep.success, rep.message  # type: ignore[attr-defined]
        before = sorted(str(x) for x in tmp_path.rglob("*"))
        for name, path in (("absolute", str(bashrc)), ("tilde", "~/.bashrc"), ("dotdot", "../../../home/.bashrc"),
                           ("symlink", "out.json"), ("symlink dir", str(folder / "dir" / ".bashrc"))):  # fmt: skip
            for command in ("save", "load"):
                rep, spent = _call(client, command, path, overwrite=True)
                assert not rep.success and "refused" in rep.message, (name, command, rep)  # type: ignore[attr-defined]
                found[f"{name} {command}"] = spent
        assert bashrc.read_text() == "# mine\n"
        assert sorted(str(x) for x in tmp_path.rglob("*")) == before, "a refused request created a file"
        for name, says in (("fifo", "not a regular file"), ("big", "more than"), ("deep", "not JSON"),
                           ("id", "ball_")):  # fmt: skip
            rep, spent = _call(client, "load", name)
            assert not rep.success and says in rep.message, (name, rep)  # type: ignore[attr-defined]
            found[f"load {name}"] = spent
        rep, _ = _call(client, "save", "first")
        assert not rep.success and "overwrite=true" in rep.message  # type: ignore[attr-defined]
        rep, _ = _call(client, "load", "first")
        assert rep.success, rep.message  # type: ignore[attr-defined]  # the node kept serving throughout
    print("memory_file attacks refused (wall s per request): " + ", ".join(f"{k} {v:.3f}" for k, v in found.items()))
    assert p.poll() is None, "the object memory died"


def test_map_file_escapes_are_refused(procs: Procs, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The map node's /map/map_file takes the memory file's name under the same rule: no escape writes or
    reads outside the memory files' folder, and a map-file symlink planted beside a memory file is
    refused, never written through nor replaced."""
    home = tmp_path / "home"
    home.mkdir()
    bashrc = home / ".bashrc"
    bashrc.write_text("# mine\n")
    folder = tmp_path / "state" / "go2vlm" / "objects"  # conftest: XDG_STATE_HOME = tmp_path/state
    folder.mkdir(parents=True)
    (folder / "out.json").symlink_to(bashrc)
    (folder / "planted.map.npz").symlink_to(bashrc)
    monkeypatch.setenv("HOME", str(home))
    p = procs.start("run", "map", "--param", "world=home")
    with ServiceClient(MemoryFile, "/map/map_file") as client:
        assert client.wait_for_service(60), "no map node"
        before = sorted(str(x) for x in tmp_path.rglob("*"))
        for name, path in (("absolute", str(home / "x.json")), ("tilde", "~/.bashrc"),
                           ("dotdot", "../../../home/.bashrc"),
                           ("latch folder", str(folder.parent / "estop" / "sim-domain0.json"))):  # fmt: skip
            for command in ("save", "load", "check"):
                rep, _ = _call(client, command, path, overwrite=True)
                assert not rep.success and "refused" in rep.message, (name, command, rep)  # type: ignore[attr-defined]
        assert sorted(str(x) for x in tmp_path.rglob("*")) == before, "a refused request created a file"
        rep, _ = _call(client, "load", "planted")
        assert not rep.success, rep  # type: ignore[attr-defined]  # a symlink is no map file to read
        rep, _ = _call(client, "save", "planted")
        assert not rep.success and "overwrite=true" in rep.message, rep  # type: ignore[attr-defined]
        rep, _ = _call(client, "save", "planted", overwrite=True)
        assert not rep.success and "not a regular file" in rep.message, rep  # type: ignore[attr-defined]
        assert (folder / "planted.map.npz").is_symlink()
    assert bashrc.read_text() == "# mine\n"
    assert p.poll() is None, "the map node died"


def test_the_latch_a_symlinked_folder_and_the_quota(procs: Procs, tmp_path: Path) -> None:
    """The memory writes memory files only, in their own folder, through no symlink, and within its
    quota (statefiles.py). Three rows, each checked against its own broken build:

    - the gate's e-stop latch file, by its absolute path, by its name without suffix, and by `..`:
      refused, the latch unchanged (broken: `state_file` without its folder check: the save with
      overwrite replaces the latch, and the gate would start latched);
    - the memory files' folder swapped for a symlink to a folder outside: save and load refused as a
      symlink, nothing written outside (broken: `_open_folder` without O_NOFOLLOW: the save lands
      outside);
    - the quota (3 files, 1 MiB): a fourth file refused, a replacement of one that would pass 1 MiB
      refused, the status's `files` says full (broken: `Quota.check` a no-op: the fourth is saved).
    """
    from go2vlm.bus import Node
    from go2vlm.bus.topics import OBJECT_MEMORY_STATUS
    from go2vlm.safety.estop import LatchFile
    from go2vlm.statefiles import state_dir

    state = state_dir()
    latch = LatchFile(state / "estop" / "sim-domain0.json")
    latch.save(False, "safety")
    latch_bytes = latch.path.read_bytes()
    outside = tmp_path / "outside"
    outside.mkdir()
    statuses: list[dict] = []
    probe = Node(node_name="files_probe", parameter_services=False)
    OBJECT_MEMORY_STATUS.subscription(probe, lambda m: statuses.append(json.loads(m.data)))
    probe.start()
    p = procs.start("run", "object_memory", "--param", "image_topic=", "--param", "scan_topic=",
                    "--param", "max_files=3", "--param", "max_files_mib=1")  # fmt: skip
    spent: dict[str, float] = {}
    try:
        with ServiceClient(MemoryFile, "/object_memory/memory_file") as client:
            assert client.wait_for_service(60), "no object memory"
            rep, _ = _call(client, "save", "first")
            assert rep.success, rep  # type: ignore[attr-defined]
            for name, path, says in (("latch", str(latch.path), "is not in"),
                                     ("latch unsuffixed", str(latch.path.with_suffix("")), "is not in"),
                                     ("latch dotdot", "../estop/sim-domain0.json", "'..'")):  # fmt: skip
                for command in ("save", "load"):
                    rep, spent[f"{name} {command}"] = _call(client, command, path, overwrite=True)
                    assert not rep.success and says in rep.message, (name, command, rep)  # type: ignore[attr-defined]
            assert latch.path.read_bytes() == latch_bytes and sorted(latch.path.parent.iterdir()) == [latch.path]
            assert latch.read() is not None and not latch.read().engaged  # type: ignore[union-attr]

            folder = state / "objects"
            folder.rename(tmp_path / "objects.real")
            folder.symlink_to(outside)
            for command in ("save", "load"):
                rep, spent[f"symlinked folder {command}"] = _call(client, command, "first", overwrite=True)
                assert not rep.success and "symlink" in rep.message, (command, rep)  # type: ignore[attr-defined]
            assert list(outside.iterdir()) == [], "written through a symlinked folder"
            folder.unlink()
            (tmp_path / "objects.real").rename(folder)

            for name in ("second", "third"):
                rep, _ = _call(client, "save", name)
                assert rep.success, rep  # type: ignore[attr-defined]
            rep, spent["quota: a fourth file"] = _call(client, "save", "fourth")
            assert not rep.success and "quota reached" in rep.message and "4 files" in rep.message, rep  # type: ignore[attr-defined]
            (folder / "second.json").write_bytes(b" " * (2**20 - 100))  # the bytes, nearly all taken
            rep, spent["quota: bytes"] = _call(client, "save", "third", overwrite=True)
            assert not rep.success and "quota reached" in rep.message, rep  # type: ignore[attr-defined]
            assert not (folder / "fourth.json").exists()
            full = lambda: bool(statuses) and statuses[-1]["files"]["full"] and statuses[-1]["files"]["files"] == 3  # noqa: E731
            assert wait_for(full, 30), statuses[-1:] or "no status"
            print(f"memory files: {statuses[-1]['files']}")
    finally:
        probe.shutdown()
    print("latch, symlinked folder, quota refused (wall s per request): "
          + ", ".join(f"{k} {v:.3f}" for k, v in spent.items()))  # fmt: skip
    assert p.poll() is None, "the object memory died"
