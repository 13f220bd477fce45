"""statefiles.py: a name or a path resolves under go2vlm's state directory or is refused (nothing
created); reads are bounded, regular files only, never blocking; writes are fsync-then-rename and never
replace a file unless asked."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from go2vlm.statefiles import StateFileError, read_bounded, state_dir, state_file, write_atomic


@pytest.fixture
def root(tmp_path: Path) -> Path:
    return (tmp_path / "state" / "go2vlm").resolve()  # conftest: XDG_STATE_HOME = tmp_path/state


def _inside(p: Path, root: Path) -> bool:
    return root in p.parents


def test_a_name_is_a_file_in_the_kinds_folder(root: Path) -> None:
    assert state_dir().resolve() == root
    assert state_file("home", "objects") == root / "objects" / "home.json"
    assert state_file("home.json", "objects") == root / "objects" / "home.json"
    assert state_file(str(root / "objects" / "x.json"), "objects") == root / "objects" / "x.json"
    assert state_file(str(root / "maps" / "x.json"), "objects") == root / "maps" / "x.json"


@pytest.mark.parametrize("bad", ["/etc/passwd", "~/.bashrc", "../../x", "a/../../../x", "", ".", "..", "/", "a\0b"])
def test_escapes_are_refused_and_nothing_is_created(bad: str, root: Path, tmp_path: Path) -> None:
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(StateFileError):
        state_file(bad, "objects")
    assert sorted(tmp_path.rglob("*")) == before


def test_a_symlink_leading_out_is_refused(root: Path, tmp_path: Path) -> None:
    (root / "objects").mkdir(parents=True)
    (root / "objects" / "evil.json").symlink_to(tmp_path / "outside.json")
    (root / "objects" / "dir").symlink_to(tmp_path)
    for name in ("evil", str(root / "objects" / "dir" / "x.json")):
        with pytest.raises(StateFileError, match="outside"):
            state_file(name, "objects")


@given(st.text(max_size=60))
@example("~0")  # a home this machine has no user for
def test_whatever_the_text_the_file_is_inside_or_refused(text: str) -> None:
    root = state_dir().resolve()
    try:
        p = state_file(text, "objects")
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
    p = state_file("home", "objects")
    write_atomic(p, b"one")
    with pytest.raises(StateFileError, match="overwrite=true"):
        write_atomic(p, b"two")
    assert p.read_bytes() == b"one"
    write_atomic(p, b"three", overwrite=True)
    assert p.read_bytes() == b"three"
    assert sorted(x.name for x in p.parent.iterdir()) == ["home.json"]
