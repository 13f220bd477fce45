"""The object memory on disk: one JSON file per place, for a robot that stays in one home.

    text = dumps(objects, world="my_flat", frame_id="odom", saved_at=stamp)
    objects = loads(text, world="my_flat", frame_id="odom", max_objects=64)   # or MemoryFileError

    {"format": "go2vlm-object-memory", "version": 1, "world": "my_flat", "frame_id": "odom",
     "saved_at": 1234.5, "objects": [{"id": "blue_cylinder_1", "label": "blue cylinder",
       "x": -2.01, "y": 0.03, "z": 0.75, "cov": [0.0025, 0.0, 0.0025], "size": [0.6, 0.6, 1.5],
       "logodds": 4.0, "seen": 41, "refused": 0, "missed": 2, "first_seen": 3.1, "last_seen": 38.2}]}

A file is read all or nothing: one that is not JSON (nested too deep included), not this format, of a
newer version, of another world or frame, with more objects than the memory holds, or with a single
bad object (an id that is not `<label words>_<number>`, a position beyond MAX_COORD_M, a field of the
wrong type) is refused with one line saying why (MemoryFileError, a ConfigError: exit 2 in the CLI),
and nothing is loaded: every object is checked before the caller replaces anything. ObjectMemory.load
clamps what it loads to what the memory allows (log-odds, the position's certainty). Where files may
live, and how they are read and written (bounded, fsync then rename, never overwritten unasked):
statefiles.py (STATE_KIND: objects/*.json, nothing else).
Positions are in `frame_id` (the odometry frame): a robot whose odometry starts again at its dock
each run finds its things where it left them only if it starts at the same dock.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable
from typing import Any

from go2vlm.errors import ConfigError
from go2vlm.statefiles import FileKind
from go2vlm.world.labels import MAX_LABEL, normalize_label
from go2vlm.world.memory import MemoryObject

__all__ = ["FORMAT", "STATE_KIND", "VERSION", "MemoryFileError", "dumps", "header", "loads"]

FORMAT = "go2vlm-object-memory"
VERSION = 1
MAX_FILE_BYTES = 16 * 1024 * 1024
# The memory files: $XDG_STATE_HOME/go2vlm/objects/*.json (the maps beside them are their own kind).
STATE_KIND = FileKind("memory file", "objects", ".json")
MAX_COORD_M = 1000.0  # an object farther from the odometry origin than this is no object in a home
_ID_NUMBER = re.compile(r"_([0-9]{1,9})\Z")


class MemoryFileError(ConfigError):
    """A memory file that cannot be loaded; the message is one line."""


def _obj_dict(o: MemoryObject) -> dict[str, Any]:
    return {
        "id": o.id, "label": o.label, "x": o.x, "y": o.y, "z": o.z, "cov": list(o.cov), "size": list(o.size),
        "logodds": o.logodds, "seen": o.seen, "refused": o.refused, "missed": o.missed,
        "first_seen": o.first_seen, "last_seen": o.last_seen,
    }  # fmt: skip


def dumps(objects: Iterable[MemoryObject], world: str, frame_id: str, saved_at: float) -> str:
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "world": world,
        "frame_id": frame_id,
        "saved_at": saved_at,
        "objects": [_obj_dict(o) for o in objects],
    }
    return json.dumps(doc, indent=1, ensure_ascii=False) + "\n"


def _num(d: dict[str, Any], key: str, where: str, lo: float = -1e6, hi: float = 1e6) -> float:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
        raise MemoryFileError(f"{where}: {key} = {v!r} is not a number in {lo:g}..{hi:g}")
    return float(v)


def _int(d: dict[str, Any], key: str, where: str) -> int:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 10**9:
        raise MemoryFileError(f"{where}: {key} = {v!r} is not a count")
    return v


def _triple(d: dict[str, Any], key: str, where: str) -> tuple[float, float, float]:
    v = d.get(key)
    if not isinstance(v, list) or len(v) != 3:
        raise MemoryFileError(f"{where}: {key} = {v!r} is not a list of three numbers")
    a, b, c = (_num({key: x}, key, where) for x in v)
    return a, b, c


def _object(d: Any, k: int) -> MemoryObject:
    where = f"object {k}"
    if not isinstance(d, dict):
        raise MemoryFileError(f"{where} is not a JSON object")
    oid, label = d.get("id"), d.get("label")
    if not isinstance(oid, str) or not oid or len(oid) > MAX_LABEL + 10:
        raise MemoryFileError(f"{where}: id {str(oid)[:80]!r} is not a short string")
    if not isinstance(label, str) or not normalize_label(label) or len(label) > MAX_LABEL:
        raise MemoryFileError(f"{where}: label {label[:80] if isinstance(label, str) else label!r} is not a label")
    number = _ID_NUMBER.search(oid)
    if number is None or not oid.isprintable():
        raise MemoryFileError(f"{where}: id {oid[:80]!r} is not <label words>_<number>")
    cov = _triple(d, "cov", where)
    if cov[0] <= 0 or cov[2] <= 0 or cov[0] * cov[2] - cov[1] ** 2 <= 0:
        raise MemoryFileError(f"{where}: cov {list(cov)} is not a covariance")
    size = _triple(d, "size", where)
    if min(size) < 0 or max(size) > 100:
        raise MemoryFileError(f"{where}: size {list(size)} is not a size in metres")
    return MemoryObject(
        oid, normalize_label(label), _num(d, "x", where, -MAX_COORD_M, MAX_COORD_M),
        _num(d, "y", where, -MAX_COORD_M, MAX_COORD_M), _num(d, "z", where, -100, 100),
        cov, size, _num(d, "logodds", where, -100, 100), _int(d, "seen", where),
        _int(d, "refused", where), _int(d, "missed", where), _num(d, "first_seen", where, 0, 1e12),
        _num(d, "last_seen", where, 0, 1e12),
    )  # fmt: skip


def loads(text: str | bytes, world: str | None, frame_id: str | None, max_objects: int) -> list[MemoryObject]:
    """The objects of a memory file, checked (module docstring); MemoryFileError otherwise. `world` or
    `frame_id` None: whatever the file says (reading a file without a memory to load it into)."""
    if len(text) > MAX_FILE_BYTES:
        raise MemoryFileError(f"the file is larger than {MAX_FILE_BYTES // 2**20} MiB")
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError) as exc:  # UnicodeDecodeError is a ValueError
        raise MemoryFileError(f"not a memory file: not JSON ({str(exc)[:200]})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise MemoryFileError(f"not a memory file: its format is not {FORMAT!r}")
    version = doc.get("version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise MemoryFileError(f"not a memory file: version {version!r}")
    if version > VERSION:
        raise MemoryFileError(
            f"written by a newer go2vlm (format version {version}; this one reads version {VERSION}): upgrade go2vlm"
        )
    if not isinstance(doc.get("world"), str) or not isinstance(doc.get("frame_id"), str):
        raise MemoryFileError("not a memory file: 'world' or 'frame_id' is not a string")
    if world is not None and doc["world"] != world:
        raise MemoryFileError(f"it remembers world {doc['world'][:80]!r}, and this memory is of world {world!r}")
    if frame_id is not None and doc["frame_id"] != frame_id:
        raise MemoryFileError(f"its positions are in frame {doc['frame_id'][:80]!r}, and this memory's in {frame_id!r}")
    objects = doc.get("objects")
    if not isinstance(objects, list):
        raise MemoryFileError("not a memory file: 'objects' is not a list")
    if len(objects) > max_objects:
        raise MemoryFileError(f"it holds {len(objects)} objects, and this memory holds at most {max_objects}")
    out = [_object(d, k) for k, d in enumerate(objects)]
    ids = [o.id for o in out]
    if len(set(ids)) != len(ids):
        raise MemoryFileError("two objects share an id")
    return out


def header(text: str | bytes) -> tuple[str, str]:
    """(world, frame_id) of a memory file that `loads` accepts with world and frame_id None."""
    doc = json.loads(text)
    return doc["world"], doc["frame_id"]
