"""statefiles.py: a name or a path resolves to a file in its kind's folder of go2vlm's state
directory or is refused (nothing created); folders are opened by descriptor, a symlink at any level
refused; reads are bounded, regular files only, never blocking; writes are fsync-then-rename, never
replace a file unless asked, and stay within the kind's quota."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from go2vlm.statefiles import FileKind, Quota, StateFileError, read_bounded, state_dir, state_file, write_atomic

KIND = FileKind("memory file", "objects", ".json")


@pytest.fixture
def root(tmp_path: Path) -> Path:
    return (tmp_path / "state" / "go2vlm").resolve()  # conftest: XDG_STATE_HOME = tmp_path/state


def _inside(p: Path, root: Path) -> bool:
    return root in p.parents


def test_a_name_is_a_file_in_the_kinds_folder(root: Path) -> None:
    assert state_dir().resolve() == root
    assert state_file("home", KIND) == root / "objects" / "home.json"
    assert state_file("home.json", KIND) == root / "objects" / "home.json"
    assert state_file(str(root / "objects" / "x.json"), KIND) == root / "objects" / "x.json"
    assert state_file(str(root / "objects" / "x"), KIND) == root / "objects" / "x.json"
    assert state_file("home.v2", KIND) == root / "objects" / "home.v2.json"  # always the kind's suffix


@pytest.mark.parametrize("other", ["maps/x.json", "../estop/sim-domain0.json", "sub/x.json", "a" * 300])
def test_another_folder_a_subfolder_or_a_long_name_is_refused(other: str, root: Path, tmp_path: Path) -> None:
    before = sorted(tmp_path.rglob("*"))
    for text in (other, str(root / other)):
        with pytest.raises(StateFileError):
            state_file(text, KIND)
    assert sorted(tmp_path.rglob("*")) == before


@pytest.mark.parametrize("bad", ["/etc/passwd", "~/.bashrc", "../../x", "a/../../../x", "", ".", "..", "/", "a\0b"])
def test_escapes_are_refused_and_nothing_is_created(bad: str, root: Path, tmp_path: Path) -> None:
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(StateFileError):
        state_file(bad, KIND)
    assert sorted(tmp_path.rglob("*")) == before


def test_a_symlink_at_any_level_is_refused(root: Path, tmp_path: Path) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "x.json").write_bytes(b"theirs")
    (root / "objects").mkdir(parents=True)
    (root / "objects" / "evil.json").symlink_to(outside / "x.json")
    with pytest.raises(StateFileError):
        read_bounded(state_file("evil", KIND), 100)
    with pytest.raises(StateFileError):
        write_atomic(state_file("evil", KIND), b"mine", overwrite=True)
    with pytest.raises(StateFileError):
        state_file(str(root / "objects" / "dir" / "x.json"), KIND)  # a subfolder: not the kind's folder
    (root / "objects" / "evil.json").unlink()
    (root / "objects").rmdir()
    (root / "objects").symlink_to(outside)  # the kind's folder swapped for a symlink
    for step in (lambda: read_bounded(state_file("x", KIND), 100), lambda: write_atomic(state_file("y", KIND), b"1")):
        with pytest.raises(StateFileError, match="symlink"):
            step()
    (root / "objects").unlink()
    os.rename(root, tmp_path / "real")
    root.symlink_to(tmp_path / "real")  # go2vlm/ itself
    with pytest.raises(StateFileError, match="symlink"):
        write_atomic(state_file("y", KIND), b"1")
    assert sorted(p.name for p in outside.iterdir()) == ["x.json"] and (outside / "x.json").read_bytes() == b"theirs"


@given(st.text(max_size=60))
@example("~0")  # a home this machine has no user for
def test_whatever_the_text_the_file_is_inside_or_refused(text: str) -> None:
    root = state_dir().resolve()
    try:
        p = state_file(text, KIND)
    except StateFileError:
        return
    assert _inside(p, root)


def test_reads_are_bounded_and_regular_files_only(root: Path) -> None:
    root.mkdir(parents=True)
    big = root / "big.json"
    big.write_bytes(b"x" * 1001)
    with pytest.raises(StateFileError, match="more than 1000"):
        read_bounded(big, 1000)
    fifo = root / "fifo.json"
    os.mkfifo(fifo)
    done = threading.Event()

    def read() -> None:
        with pytest.raises(StateFileError, match="not a regular file"):
            read_bounded(fifo, 1000)
        done.set()

    threading.Thread(target=read, daemon=True).start()
    assert done.wait(10), "reading a FIFO blocked"
    with pytest.raises(StateFileError, match="not a regular file"):
        read_bounded(Path("/dev/zero"), 1000)
    link = root / "link.json"
    link.symlink_to(big)
    with pytest.raises(StateFileError):
        read_bounded(link, 10_000)  # the final component is never followed
    with pytest.raises(FileNotFoundError):
        read_bounded(root / "none.json", 10)


def test_writes_never_replace_unasked_and_leave_no_temporary_files(root: Path) -> None:
    p = state_file("home", KIND)
    write_atomic(p, b"one")
    with pytest.raises(StateFileError, match="overwrite=true"):
        write_atomic(p, b"two")
    assert p.read_bytes() == b"one"
    write_atomic(p, b"three", overwrite=True)
    assert p.read_bytes() == b"three"
    assert sorted(x.name for x in p.parent.iterdir()) == ["home.json"]


def test_the_quota_caps_count_and_bytes(root: Path) -> None:
    quota = Quota(KIND, max_files=2, max_bytes=10)
    assert quota.usage() == {"files": 0, "bytes": 0, "max_files": 2, "max_bytes": 10, "full": False}
    write_atomic(state_file("a", KIND), b"12345", quota=quota)
    (root / "objects" / "other.map.npz").write_bytes(b"x" * 100)  # another kind: not counted
    with pytest.raises(StateFileError, match="quota"):
        write_atomic(state_file("b", KIND), b"123456", quota=quota)  # 11 bytes
    write_atomic(state_file("b", KIND), b"12345", quota=quota)
    assert quota.usage()["full"]
    with pytest.raises(StateFileError, match="3 files"):
        write_atomic(state_file("c", KIND), b"", quota=quota)
    write_atomic(state_file("a", KIND), b"1234", quota=quota, overwrite=True)  # a replacement counts once
    assert quota.usage() == {"files": 2, "bytes": 9, "max_files": 2, "max_bytes": 10, "full": True}
    assert sorted(p.name for p in (root / "objects").iterdir()) == ["a.json", "b.json", "other.map.npz"]
