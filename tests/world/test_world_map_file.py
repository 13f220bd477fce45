"""The map on disk (world/map_file.py): what is saved loads back cell for cell, and a file that is
corrupt, of another world, frame or resolution, oversized, or whose arrays disagree with its header
is refused with one line, whatever bytes it holds."""

from __future__ import annotations

import io
import json
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from maputil import room_scan

from go2vlm.world.map_file import MapFileError, dumps, loads, map_file_for
from go2vlm.world.occupancy import GridParams, OccupancyMap
from go2vlm.world.poses import Pose2D

PARAMS = GridParams()


def mapped() -> OccupancyMap:
    grid = OccupancyMap(PARAMS)
    for p in (Pose2D(0, 0, 0), Pose2D(1.0, 0.5, 2.0)):
        grid.integrate(room_scan(p), p)
    return grid


def npz(meta: dict, offset: object = (3, -4), logodds: object = None) -> bytes:
    buf = io.BytesIO()
    lo = np.zeros((meta.get("rows", 2), meta.get("cols", 3)), np.float32) if logodds is None else logodds
    np.savez_compressed(buf, meta=np.array(json.dumps(meta)), offset=np.asarray(offset), logodds=lo)
    return buf.getvalue()


META = {"format": "go2vlm-occupancy-map", "version": 1, "world": "home", "frame_id": "odom", "saved_at": 1.0,
        "resolution_m": 0.05, "rows": 2, "cols": 3}  # fmt: skip


def test_a_saved_map_loads_back_cell_for_cell() -> None:
    grid = mapped()
    back = loads(dumps(grid, "home", "odom", 12.5), "home", "odom", PARAMS)
    assert back.offset == grid.offset and np.array_equal(back.logodds, grid.logodds)
    assert np.array_equal(back.values(), grid.values())
    assert loads(dumps(grid, "home", "odom", 1.0), None, None, PARAMS).shape == grid.shape
    assert map_file_for(Path("/s/objects/home.json")) == Path("/s/objects/home.map.npz")
    empty = loads(dumps(OccupancyMap(PARAMS), "home", "odom", 0.0), "home", "odom", PARAMS)  # nothing seen yet
    assert empty.empty


@pytest.mark.parametrize(
    ("data", "says"),
    [
        (b"", "not a map file"),
        (b"PK\x03\x04 not really a zip", "not a map file"),
        (npz({**META, "world": "office"}), "world 'office'"),
        (npz({**META, "frame_id": "map"}), "frame 'map'"),
        (npz({**META, "resolution_m": 0.1}), "0.1 m a cell"),
        (npz({**META, "version": 7}), "version 7"),
        (npz({**META, "format": "something"}), "not a go2vlm map file"),
        (npz({**META, "rows": 5000, "cols": 2}, logodds=np.zeros((1, 1), np.float32)), "more than the 1200"),
        (npz(META, logodds=np.zeros((3, 2), np.float32)), "not float32 (2, 3)"),
        (npz(META, logodds=np.zeros((2, 3), np.float64)), "not float32"),
        (npz(META, logodds=np.full((2, 3), np.nan, np.float32)), "not finite"),
        (npz(META, logodds=np.full((2, 3), 50.0, np.float32)), "outside"),
        (npz(META, offset=(1, 2, 3)), "no cell index"),
        (npz(META, offset=(1.5, 2.0)), "no cell index"),
        (npz({**META, "rows": -1}, logodds=np.zeros((1, 3), np.float32)), "no grid size"),
    ],
)
def test_a_bad_file_is_refused_with_one_line(data: bytes, says: str) -> None:
    with pytest.raises(MapFileError) as exc:
        loads(data, "home", "odom", PARAMS)
    assert says in str(exc.value) and "\n" not in str(exc.value), str(exc.value)


def test_extra_or_missing_members_are_refused() -> None:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("meta.npy", b"x")
        z.writestr("evil.npy", b"y")
    with pytest.raises(MapFileError, match="members"):
        loads(buf.getvalue(), None, None, PARAMS)


def test_a_damaged_array_header_is_refused() -> None:
    """numpy reads a .npy header with Python's tokenizer: an unterminated string in it raised
    tokenize.TokenError, not a MapFileError (found by the damage test below)."""
    hdr = b"{'descr': '''<f4, 'fortran_order': False, 'shape': (3,), }"
    hdr += b" " * (64 - 10 - len(hdr) - 1) + b"\n"
    npy = b"\x93NUMPY\x01\x00" + len(hdr).to_bytes(2, "little") + hdr + bytes(12)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name in ("meta.npy", "offset.npy", "logodds.npy"):
            z.writestr(name, npy)
    with pytest.raises(MapFileError, match="not a map file"):
        loads(buf.getvalue(), None, None, PARAMS)


@settings(max_examples=60, deadline=None)
@given(cut=st.integers(0, 10_000), flip=st.integers(0, 10_000), byte=st.integers(0, 255))
def test_any_damage_is_refused_or_loads_a_whole_valid_map(cut: int, flip: int, byte: int) -> None:
    """Truncated or with a byte changed, a file is refused (MapFileError), or (a change zip's checks
    cannot see) it loads as a whole map within the cap: never an exception of another kind."""
    data = bytearray(dumps(mapped(), "home", "odom", 1.0))
    data = data[: max(1, len(data) - cut % len(data))] if cut % 2 else data
    if data:
        data[flip % len(data)] = byte
    try:
        grid = loads(bytes(data), "home", "odom", PARAMS)
    except MapFileError:
        return
    assert grid.shape[0] <= PARAMS.max_cells and grid.shape[1] <= PARAMS.max_cells
    assert np.isfinite(grid.logodds).all() and not math.isnan(float(grid.logodds.sum()))
