"""Files a node keeps between runs, confined to go2vlm's state directory: nobody on the network makes
a go2vlm node read or write anywhere else.

    path = state_file("home", "objects")                 # $XDG_STATE_HOME/go2vlm/objects/home.json
    path = state_file("~/.local/state/go2vlm/objects/home.json", "objects")   # a path under it: fine
    data = read_bounded(path, 16 * 2**20)                # bytes, or StateFileError
    write_atomic(path, data, overwrite=False)            # fsync, then rename; StateFileError if it exists

The rule (`state_file`): a bare name ("home", "home.json": letters, digits, `._-`, not starting with
a dot) is a file in the kind's folder, `<state>/go2vlm/<kind>/`, with `.json` added when it has no
suffix; anything else is a path that must resolve, symlinks followed, under `<state>/go2vlm/`.
`<state>` is $XDG_STATE_HOME, or ~/.local/state without it. Everything else (an absolute path
elsewhere, `..`, a symlink leading out, an empty name) is refused with the reason, and nothing is
created.

Reading (`read_bounded`): only a regular file (a FIFO, a device or a directory is refused without
blocking: the open never waits for a writer), its final component not a symlink, at most max_bytes
read: the size is checked before anything is parsed. Writing (`write_atomic`): a temporary file in
the same folder, fsync'd, then renamed over the target (overwrite=True) or linked to its name only
if none exists (overwrite=False: never replaces a file), then the folder fsync'd. Any node's files
(the object memory's, a map beside it) use these three.
"""

from __future__ import annotations

import os
import re
import stat
import tempfile
from pathlib import Path

from go2vlm.errors import ConfigError

__all__ = ["StateFileError", "read_bounded", "state_dir", "state_file", "write_atomic"]

_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,127}")


class StateFileError(ConfigError):
    """A state file refused; the message is one line that says why."""


def state_dir() -> Path:
    """go2vlm's state directory: $XDG_STATE_HOME/go2vlm (default ~/.local/state/go2vlm)."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(base) / "go2vlm"


def state_file(name_or_path: str, kind: str, suffix: str = ".json") -> Path:
    """The file a name or a path stands for, confined to the state directory (module docstring)."""
    text = str(name_or_path)
    if not text or "\0" in text or len(text) > 4096:
        raise StateFileError(f"{text[:80]!r} is no file name")
    root = state_dir().resolve()
    if _NAME.fullmatch(text) and ".." not in text:
        path = root / kind / (text if Path(text).suffix else text + suffix)
    else:
        try:
            p = Path(text).expanduser()
        except RuntimeError:  # "~user" for a user this machine does not have
            raise StateFileError(f"{text[:200]!r}: no such home; give a name, or a path under {root}") from None
        if ".." in p.parts:
            raise StateFileError(f"{text[:200]!r}: '..' is not allowed; give a name, or a path under {root}")
        path = p if p.is_absolute() else root / kind / p
    real = Path(os.path.realpath(path))  # symlinks followed, the file itself need not exist
    if real != root and root not in real.parents:
        raise StateFileError(
            f"{text[:200]!r} resolves to {str(real)[:200]}, outside go2vlm's state directory {root}: give a name "
            f"(saved as {root / kind}/<name>{suffix}) or a path under {root}"
        )
    if real in (root, root / kind) or real.is_dir():
        raise StateFileError(f"{str(real)[:200]} is a directory, not a file")
    return real


def read_bounded(path: Path, max_bytes: int) -> bytes:
    """A regular file's bytes, at most max_bytes (StateFileError otherwise; FileNotFoundError if absent)."""
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise StateFileError(f"cannot open {path}: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise StateFileError(f"{path} is not a regular file")
        if st.st_size > max_bytes:
            raise StateFileError(f"{path} is {st.st_size} bytes, more than {max_bytes}")
        chunks, left = [], max_bytes + 1
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
        data = b"".join(chunks)
        if len(data) > max_bytes:
            raise StateFileError(f"{path} grew past {max_bytes} bytes while it was read")
        return data
    finally:
        os.close(fd)


def write_atomic(path: Path, data: bytes, *, overwrite: bool = False) -> None:
    """Write `data` to `path` (already confined: `state_file`) all at once: fsync, then rename (or link
    when overwrite is False, which never replaces an existing file)."""
    if not overwrite and os.path.lexists(path):
        raise StateFileError(f"{path} exists; pass overwrite=true to replace it")
    if os.path.lexists(path) and not os.path.isfile(path):
        raise StateFileError(f"{path} exists and is not a regular file")
    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        if overwrite:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path)  # fails if the name exists, even if it appeared just now
            except FileExistsError:
                raise StateFileError(f"{path} exists; pass overwrite=true to replace it") from None
            os.unlink(tmp)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    dfd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dfd)
    finally:
        os.close(dfd)
