"""Files a node keeps between runs, by kind, each kind in its own folder of go2vlm's state directory:
nobody on the network makes a go2vlm node read or write anywhere else, nor write a file of another
kind, nor fill the disk.

    MEMORY = FileKind("memory file", "objects", ".json")        # declared beside its format
    path = state_file("home", MEMORY)                           # $XDG_STATE_HOME/go2vlm/objects/home.json
    data = read_bounded(path, 16 * 2**20)                       # bytes, or StateFileError
    quota = Quota(MEMORY, max_files=64, max_bytes=256 * 2**20)
    write_atomic(path, data, overwrite=False, quota=quota)      # StateFileError if it exists or is over quota
    quota.usage()                                               # {"files": 3, "bytes": 5120, ..., "full": False}

Kinds: a kind is a folder under `<state>/go2vlm/` and the suffix its files end with (the object
memory's files: objects/*.json; the maps beside them: objects/*.map.npz; the e-stop latch:
estop/*.json, the gate's alone: no service takes the latch kind). `<state>` is $XDG_STATE_HOME, or
~/.local/state without it.

The rule (`state_file`): a bare name ("home", "home.json": letters, digits, `._-`, not starting with
a dot, at most 128 characters) is a file in the kind's folder, with the kind's suffix added when it
does not end with it; a path must name a file directly in the kind's folder (written from ~ or from
the state directory, symlinks in it or not). Everything else (an absolute path elsewhere, another
kind's folder, a subfolder, `..`, an empty or over-long name) is refused with the reason, and nothing
is touched: the rule is on the text alone, so no name makes it fail with an OSError.

Opening (`read_bounded`, `write_atomic`): by directory descriptor, one step at a time from the state
root (`$XDG_STATE_HOME`, the user's own): `go2vlm`, then the kind's folder, each opened with
O_DIRECTORY | O_NOFOLLOW (made with mkdir relative to its parent where missing), then the file relative
to its folder with O_NOFOLLOW. A symlink swapped in at any level, at any time, is refused, never
followed. A path outside the state directory (a secret file, the gate's configured latch file) has its
folder opened as given and only the file's own step checked.

Reading: only a regular file (a FIFO, a device or a directory is refused without blocking: the open
never waits for a writer), at most max_bytes read: the size is checked before anything is parsed.
Writing: a new temporary file in the same folder (created relative to the folder's descriptor, O_EXCL,
mode 0600), fsync'd, then renamed over the target (overwrite=True) or linked to its name only if none
exists (overwrite=False: never replaces a file), then the folder fsync'd. With a quota, a write that
would take the kind past `max_files` files or `max_bytes` bytes in its folder is refused with the
figures (a file replaced counts once, at its new size).
"""

from __future__ import annotations

import errno
import os
import re
import secrets
import stat
from dataclasses import dataclass
from pathlib import Path

from go2vlm.declare import param
from go2vlm.errors import ConfigError

__all__ = ["FileCaps", "FileKind", "Quota", "StateFileError", "read_bounded", "state_dir", "state_file", "write_atomic"]

_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,127}")
_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | getattr(os, "O_CLOEXEC", 0)
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


class StateFileError(ConfigError):
    """A state file refused; the message is one line that says why."""


@dataclass(frozen=True)
class FileKind:
    """One kind of state file: what people call it, its folder under <state>/go2vlm/, its suffix."""

    what: str
    folder: str
    suffix: str


def _base() -> Path:
    """The state root: $XDG_STATE_HOME, or ~/.local/state; the user's own, so its symlinks are followed."""
    return Path(os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state"))


def state_dir() -> Path:
    """go2vlm's state directory: $XDG_STATE_HOME/go2vlm (default ~/.local/state/go2vlm)."""
    return _base() / "go2vlm"


def _roots() -> tuple[Path, ...]:
    """The state directory as written and with the state root's own symlinks resolved."""
    base = _base()
    return (base / "go2vlm", Path(os.path.realpath(base)) / "go2vlm")


def state_file(name_or_path: str, kind: FileKind) -> Path:
    """The file a name or a path stands for, in `kind`'s folder (module docstring); StateFileError otherwise."""
    text = str(name_or_path)
    if not text or "\0" in text or len(text) > 4096:
        raise StateFileError(f"{text[:80]!r} is no file name")
    roots = _roots()
    folder = roots[1] / kind.folder
    where = f"give a name (saved as {folder}/<name>{kind.suffix}) or a path there"
    if _NAME.fullmatch(text):
        name = text
    else:
        try:
            p = Path(text).expanduser()
        except RuntimeError:  # "~user" for a user this machine does not have
            raise StateFileError(f"{text[:200]!r}: no such home; {where}") from None
        if ".." in p.parts:
            raise StateFileError(f"{text[:200]!r}: '..' is not allowed; {where}")
        parent = p.parent if p.is_absolute() else roots[1] / kind.folder / p.parent
        if os.path.normpath(parent) not in {os.path.normpath(r / kind.folder) for r in roots}:
            raise StateFileError(f"{text[:200]!r} is not in {folder}, where {kind.what}s live: {where}")
        name = p.name
        if not _NAME.fullmatch(name):
            raise StateFileError(
                f"{name[:80]!r} ({len(name)} characters) is no file name: letters, digits and ._- , at most "
                f"128, not starting with a dot"
            )
    if not name.endswith(kind.suffix):
        name += kind.suffix
    return folder / name


def _state_steps(folder: Path) -> tuple[Path, tuple[str, ...]] | None:
    """(state root, the folders from it down to `folder`) when `folder` is in the state directory."""
    for root in _roots():
        try:
            rel = Path(os.path.normpath(folder)).relative_to(os.path.normpath(root))
        except ValueError:
            continue
        return root.parent, ("go2vlm", *rel.parts)
    return None


def _open_folder(folder: Path, *, create: bool) -> int:
    """A descriptor of `folder`: stepwise with O_NOFOLLOW from the state root when it is in the state
    directory (module docstring), as given otherwise. FileNotFoundError when missing and not `create`."""
    steps = _state_steps(folder)
    if steps is None:
        if create:
            folder.mkdir(parents=True, exist_ok=True)
        return os.open(folder, _DIR_FLAGS)
    root, parts = steps
    if create:
        root.mkdir(parents=True, exist_ok=True, mode=0o700)
    fd = os.open(root, _DIR_FLAGS)
    try:
        for part in parts:
            try:
                nxt = os.open(part, _DIR_FLAGS | _NOFOLLOW, dir_fd=fd)
            except FileNotFoundError:
                if not create:
                    raise
                try:
                    os.mkdir(part, 0o700, dir_fd=fd)
                except FileExistsError:
                    pass  # made meanwhile: opened (and checked) below
                nxt = os.open(part, _DIR_FLAGS | _NOFOLLOW, dir_fd=fd)
            os.close(fd)
            fd = nxt
    except OSError as exc:
        os.close(fd)
        if isinstance(exc, FileNotFoundError):
            raise
        if exc.errno in (errno.ELOOP, errno.ENOTDIR):
            raise StateFileError(f"{folder}: {part!r} is a symlink or not a folder; refused, never followed") from None
        raise StateFileError(f"cannot open {folder}: {exc.strerror or exc}") from None
    return fd


def _folder_fd(path: Path, *, create: bool) -> int:
    try:
        return _open_folder(path.parent, create=create)
    except (FileNotFoundError, StateFileError):
        raise
    except OSError as exc:
        raise StateFileError(f"cannot open the folder of {path}: {exc.strerror or exc}") from None


def read_bounded(path: Path, max_bytes: int) -> bytes:
    """A regular file's bytes, at most max_bytes (StateFileError otherwise; FileNotFoundError if absent)."""
    dfd = _folder_fd(path, create=False)
    flags = os.O_RDONLY | os.O_NONBLOCK | _NOFOLLOW | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path.name, flags, dir_fd=dfd)
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise StateFileError(f"cannot open {path}: {exc.strerror or exc}") from None
    finally:
        os.close(dfd)
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


@dataclass(frozen=True)
class Quota:
    """At most `max_files` files of `kind`, `max_bytes` bytes together, in its folder."""

    kind: FileKind
    max_files: int
    max_bytes: int

    def _count(self, dfd: int) -> tuple[int, int, dict[str, int]]:
        """(files, bytes, name -> size) of this kind in the folder open as `dfd`."""
        sizes: dict[str, int] = {}
        with os.scandir(dfd) as it:
            for entry in it:
                if entry.name.startswith(".") or not entry.name.endswith(self.kind.suffix):
                    continue
                st = entry.stat(follow_symlinks=False)
                if stat.S_ISREG(st.st_mode):
                    sizes[entry.name] = st.st_size
        return len(sizes), sum(sizes.values()), sizes

    def check(self, dfd: int, name: str, size: int) -> None:
        """StateFileError when writing `size` bytes as `name` would take the kind over the quota."""
        files, total, sizes = self._count(dfd)
        old = sizes.get(name)
        files_after = files + (old is None)
        bytes_after = total - (old or 0) + size
        if files_after > self.max_files or bytes_after > self.max_bytes:
            raise StateFileError(
                f"quota reached: {self.kind.what}s would be {files_after} files, {bytes_after} bytes, over the "
                f"cap of {self.max_files} files, {self.max_bytes} bytes; delete some, or replace one with overwrite"
            )

    def usage(self) -> dict[str, int | bool | str]:
        """For a status: the kind's files and bytes now, the caps, and whether one is reached."""
        out: dict[str, int | bool | str] = {
            "files": 0, "bytes": 0, "max_files": self.max_files, "max_bytes": self.max_bytes,
        }  # fmt: skip
        try:
            dfd = _open_folder(state_dir() / self.kind.folder, create=False)
        except FileNotFoundError:
            return {**out, "full": False}
        except (OSError, StateFileError) as exc:
            return {**out, "full": True, "error": " ".join(str(exc).split())[:200]}
        try:
            files, total, _ = self._count(dfd)
        finally:
            os.close(dfd)
        return {**out, "files": files, "bytes": total, "full": files >= self.max_files or total >= self.max_bytes}


@dataclass(frozen=True)
class FileCaps:
    """The caps on the state files a node writes (its kind's quota), as the node declares them
    (`from_core(FileCaps, "max_files")`)."""

    max_files: int = param(
        64, help="state files of this node's kind kept at most: a save of a new one past it is refused", min=1,
        max=100_000,
    )  # fmt: skip
    max_files_mib: float = param(
        1024.0, help="those files' bytes together at most (MiB): a save past it is refused", min=1.0, max=1e6
    )

    def quota(self, kind: FileKind) -> Quota:
        return Quota(kind, self.max_files, int(self.max_files_mib * 2**20))


def write_atomic(path: Path, data: bytes, *, overwrite: bool = False, quota: Quota | None = None) -> None:
    """Write `data` to `path` (already confined: `state_file`) all at once: fsync, then rename (or link
    when overwrite is False, which never replaces an existing file); within `quota` if given."""
    dfd = _folder_fd(path, create=True)
    name, tmp = path.name, None
    try:
        try:
            st: os.stat_result | None = os.stat(name, dir_fd=dfd, follow_symlinks=False)
        except FileNotFoundError:
            st = None
        if st is not None and not overwrite:
            raise StateFileError(f"{path} exists; pass overwrite=true to replace it")
        if st is not None and not stat.S_ISREG(st.st_mode):
            raise StateFileError(f"{path} exists and is not a regular file")
        if quota is not None:
            quota.check(dfd, name, len(data))
        tmp = f".{name}.{secrets.token_hex(6)}"
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW | getattr(os, "O_CLOEXEC", 0)
        fd = os.open(tmp, flags, 0o600, dir_fd=dfd)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        if overwrite:
            os.replace(tmp, name, src_dir_fd=dfd, dst_dir_fd=dfd)
        else:
            try:
                os.link(tmp, name, src_dir_fd=dfd, dst_dir_fd=dfd, follow_symlinks=False)  # fails if the name exists
            except FileExistsError:
                raise StateFileError(f"{path} exists; pass overwrite=true to replace it") from None
            os.unlink(tmp, dir_fd=dfd)
        tmp = None
        os.fsync(dfd)  # the rename itself survives a power cut once the folder is synced
    except BaseException:
        if tmp is not None:
            try:
                os.unlink(tmp, dir_fd=dfd)
            except OSError:
                pass
        raise
    finally:
        os.close(dfd)
