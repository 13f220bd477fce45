"""The occupancy map on disk, beside the object memory's file: NAME.json (the objects) and
NAME.map.npz (the map), saved and loaded together, all or nothing.

    path = map_file_for(Path("home.json"))                      # home.map.npz, in the same folder
    data = dumps(grid, world="my_flat", frame_id="odom", saved_at=stamp)
    grid = loads(data, world="my_flat", frame_id="odom", params=GridParams())   # or MapFileError

A NumPy .npz (a zip, read with allow_pickle=False) of three arrays: `meta` (one JSON string: format
"go2vlm-occupancy-map", version 1, world, frame_id, saved_at, resolution_m, rows, cols), `offset`
(the lattice index of cell (0, 0): its outer corner is at offset * resolution m) and `logodds`
(float32, [rows = y, cols = x]). A file is read all or nothing: one that is no zip, not this format,
of a newer version, of another world or frame, of another resolution, larger than the cap the map
holds, with its arrays not as `meta` says, or with a log-odds that is not finite or out of range is
refused with one line saying why (MapFileError, a ConfigError), and nothing is replaced. Its members
are checked for size before anything is decompressed. A map file is its own kind of state file
(MAP_KIND: objects/*.map.npz, statefiles.py): the map writes nothing else.
"""

from __future__ import annotations

import io
import json
import math
import tokenize
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from go2vlm.errors import ConfigError
from go2vlm.statefiles import FileKind, state_file
from go2vlm.world.memory_file import STATE_KIND
from go2vlm.world.occupancy import GridParams, OccupancyMap

__all__ = [
    "FORMAT", "MAP_KIND", "MAX_FILE_BYTES", "VERSION", "MapFileError", "dumps", "loads", "map_file_for", "map_path",
]  # fmt: skip

FORMAT = "go2vlm-occupancy-map"
VERSION = 1
MAX_FILE_BYTES = 64 * 1024 * 1024
_MEMBERS = {"meta.npy", "offset.npy", "logodds.npy"}
MAP_KIND = FileKind("map file", STATE_KIND.folder, ".map.npz")  # beside the memory files


class MapFileError(ConfigError):
    """A map file that cannot be loaded; the message is one line."""


def map_path(memory_name_or_path: str) -> Path:
    """The map file beside a memory file named as the memory's service takes it (a name, or a path
    under the state directory: statefiles.state_file); StateFileError for anything else."""
    return map_file_for(state_file(memory_name_or_path, STATE_KIND))


def map_file_for(memory_file: Path) -> Path:
    """The map file beside a memory file: home.json -> home.map.npz (any suffix is replaced)."""
    return memory_file.with_name(memory_file.stem + ".map.npz")


def dumps(grid: OccupancyMap, world: str, frame_id: str, saved_at: float) -> bytes:
    rows, cols = grid.shape
    meta = {"format": FORMAT, "version": VERSION, "world": world, "frame_id": frame_id, "saved_at": saved_at,
            "resolution_m": grid.resolution, "rows": rows, "cols": cols}  # fmt: skip
    buf = io.BytesIO()
    np.savez_compressed(buf, meta=np.array(json.dumps(meta)), offset=np.array(grid.offset, dtype=np.int64),
                        logodds=grid.logodds.astype(np.float32))  # fmt: skip
    return buf.getvalue()


def loads(data: bytes, world: str | None, frame_id: str | None, params: GridParams) -> OccupancyMap:
    """The map in `data`, checked whole (module docstring); `world` / `frame_id` None: any."""
    if len(data) > MAX_FILE_BYTES:
        raise MapFileError(f"the file is {len(data)} bytes, more than {MAX_FILE_BYTES}")
    arrays = _members(data)
    meta = _meta(arrays["meta"])
    if meta.get("format") != FORMAT:
        raise MapFileError(f"not a go2vlm map file (format {str(meta.get('format'))[:40]!r})")
    version = meta.get("version")
    if not isinstance(version, int) or not 1 <= version <= VERSION:
        raise MapFileError(f"version {str(version)[:20]} is not one this go2vlm reads (1..{VERSION})")
    if world is not None and meta.get("world") != world:
        raise MapFileError(f"a map of world {str(meta.get('world'))[:60]!r}, not {world!r}")
    if frame_id is not None and meta.get("frame_id") != frame_id:
        raise MapFileError(f"a map in frame {str(meta.get('frame_id'))[:60]!r}, not {frame_id!r}")
    res = meta.get("resolution_m")
    if not isinstance(res, float | int) or not math.isclose(res, params.resolution_m, rel_tol=1e-6):
        raise MapFileError(f"a map at {res} m a cell, not {params.resolution_m:g}")
    rows, cols = meta.get("rows"), meta.get("cols")
    if not (isinstance(rows, int) and isinstance(cols, int) and (rows > 0 and cols > 0 or rows == cols == 0)):
        raise MapFileError(f"rows and cols {rows!r}, {cols!r} are no grid size")
    cap = params.max_cells
    if rows > cap or cols > cap:
        raise MapFileError(f"a map of {cols} x {rows} cells, more than the {cap} x {cap} this map holds")
    lo, off = arrays["logodds"], arrays["offset"]
    if lo.dtype != np.float32 or lo.shape != (rows, cols):
        raise MapFileError(f"log-odds of {lo.dtype} {lo.shape}, not float32 ({rows}, {cols}) as its header says")
    if off.shape != (2,) or off.dtype.kind != "i" or not (np.abs(off) < 10**7).all():
        raise MapFileError(f"offset {off.tolist()!r:.60} is no cell index")
    if lo.size and (not np.isfinite(lo).all() or lo.min() < params.min_logodds - 1e-3
                    or lo.max() > params.max_logodds + 1e-3):  # fmt: skip
        raise MapFileError(f"log-odds outside [{params.min_logodds:g}, {params.max_logodds:g}] or not finite")
    grid = OccupancyMap(params)
    grid.logodds = np.ascontiguousarray(lo)
    grid.offset = (int(off[0]), int(off[1]))
    return grid


def _members(data: bytes) -> dict[str, np.ndarray]:
    """The three arrays, their sizes checked before they are decompressed."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            infos = z.infolist()
            names = {i.filename for i in infos}
            if names != _MEMBERS:
                raise MapFileError(f"members {sorted(names)[:5]!r}, not {sorted(_MEMBERS)!r}")
            if sum(i.file_size for i in infos) > 4 * MAX_FILE_BYTES:
                raise MapFileError("its arrays would take more than the largest map holds")
            out = {}
            for i in infos:
                with z.open(i) as f:
                    out[i.filename.removesuffix(".npy")] = np.load(f, allow_pickle=False)
            return out
    except MapFileError:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, ValueError, OSError, EOFError, KeyError,
            NotImplementedError, SyntaxError, tokenize.TokenError) as exc:  # fmt: skip
        # (the last two: numpy parses a damaged .npy header with tokenize)
        raise MapFileError(f"not a map file: {' '.join(str(exc).split())[:120]}") from None


def _meta(arr: np.ndarray) -> dict[str, Any]:
    if arr.shape != () or arr.dtype.kind != "U":
        raise MapFileError("its meta is not one JSON string")
    try:
        meta = json.loads(str(arr))
    except (json.JSONDecodeError, RecursionError) as exc:
        raise MapFileError(f"its meta is not JSON: {exc}") from None
    if not isinstance(meta, dict):
        raise MapFileError("its meta is not a JSON object")
    return meta
