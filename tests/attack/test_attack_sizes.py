"""Attack: grids that would take the commander's memory, or break it (docs/safety.md, the attack table).
The commander runs as a real process; a peer on the bus publishes on /map/costmap, as any DDS peer can:

- a 6000 x 6000 costmap with all its 36 MB of data (over the bytes a sample may take: refused before a
  byte of it is decoded into Python's 8 bytes a cell), and one that declares 30000 x 30000 cells
  (refused before anything is allocated for them);
- a grid of no cells, and one at an infinite resolution (which raised in the callback).

Each is dropped by the bus's one size check (msgs/sizes.py) before the callback, with its reason on
/commander/status (`refused_inputs`); the commander stays up, its peak memory short of what decoding the
36 MB grid would take. Checked against a broken build: bus/endpoints.py's
`Subscription.take` without its two checks (the bytes and `check_size`): nothing shows on the status
as refused, and the 36 MB grid is decoded (a 290 MB list) before the commander's own check drops it.
"""

from __future__ import annotations

import json
import math
import struct
import threading
from pathlib import Path
from typing import Any

from busutil import Procs, wait_for

from go2vlm.bus import Node
from go2vlm.bus.topics import COMMANDER_STATUS, MAP_COSTMAP
from go2vlm.msgs.nav_msgs import MapMetaData, OccupancyGrid
from go2vlm.msgs.std_msgs import Header, String

COSTMAP = MAP_COSTMAP.name


class _Peer(Node):
    name = "costmap_peer"

    def __init__(self) -> None:
        super().__init__(parameter_services=False)
        self.lock = threading.Lock()
        self.status: dict[str, Any] = {}
        self.pub = MAP_COSTMAP.publisher(self)
        COMMANDER_STATUS.subscription(self, self._on_status)

    def _on_status(self, msg: String) -> None:
        with self.lock:
            self.status = json.loads(msg.data)

    def refused(self) -> dict[str, Any]:
        with self.lock:
            return dict(self.status.get("refused_inputs", {}).get(COSTMAP, {"refused": 0, "last": ""}))


def _grid(width: int, height: int, data: list[int], resolution: float = 0.05) -> OccupancyGrid:
    return OccupancyGrid(header=Header(frame_id="odom"), data=data,
                         info=MapMetaData(resolution=resolution, width=width, height=height))  # fmt: skip


def _full_grid_bytes(side: int) -> bytes:
    """A side x side grid with all its cells, serialized (built from an empty one: no list of cells here)."""
    head = _grid(side, side, []).serialize()
    assert struct.unpack("<I", head[-4:])[0] == 0  # the data sequence's length comes last
    return head[:-4] + struct.pack("<I", side * side) + bytes(side * side)


def _peak_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmHWM")


def test_oversized_and_broken_costmaps_are_dropped_with_the_reason(procs: Procs) -> None:
    p = procs.start("run", "commander")
    peer = _Peer().start()
    try:
        assert wait_for(lambda: peer.pub.matched >= 1 and bool(peer.status), 60), "no commander"
        peak0 = _peak_mb(p.pid)
        rows: list[tuple[str, Any, str]] = [
            ("6000 x 6000, all its data", _full_grid_bytes(6000), "more than the 33554432 a sample may take"),
            ("30000 x 30000 declared", _grid(30000, 30000, [0] * 16), "30000 x 30000 cells, more than"),
            ("no cells", _grid(0, 0, []), "no cells"),
            ("infinite resolution", _grid(4, 4, [0] * 16, math.inf), "not a finite size"),
        ]
        for k, (name, msg, says) in enumerate(rows, 1):
            peer.pub.publish_raw(msg) if isinstance(msg, bytes) else peer.pub.publish(msg)
            assert wait_for(lambda k=k: peer.refused()["refused"] >= k, 60), (name, peer.status)
            assert says in peer.refused()["last"], (name, peer.refused())
        peak = _peak_mb(p.pid)
        peer.pub.publish(_grid(40, 40, [0] * 1600))  # a good one after them passes the check
        assert wait_for(lambda: peer.status.get("counters", {}).get("refused_size") == len(rows), 30), peer.status
        assert p.poll() is None, "the commander died"
        print(f"oversized costmaps: {len(rows)} dropped with the reason; the commander's peak memory "
              f"{peak0:.0f} MB before, {peak:.0f} MB after")  # fmt: skip
        # The 36 MB sample itself passes through DDS and into bytes (about 3 x 36 MB); decoded, its list of
        # cells alone would take 290 MB more.
        assert peak - peak0 < 200, (peak0, peak)
    finally:
        peer.shutdown()
