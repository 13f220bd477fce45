"""Replay an episode's recorded scans into the occupancy map, the returns' rays from the lidar and from
the base, and measure how much of the walls the map has seen it still holds.

    python scripts/replay_map.py runs/houses-002/episodes/houses-002/bag --house 1002

The bag is an eval episode's (`go2vlm eval ... --bag`): /scan and /odom. Each scan is integrated
(world/occupancy.py) at the /odom pose nearest its stamp, once with `Beams.sensor` the lidar's
place (as the map node does) and once with none (the rays from the base origin, as before). A wall of
the house (sim/houses) is seen where the map holds free floor 0.2 and 0.35 m in front of one of its
faces; it is held where the map holds an occupied cell across its thickness (and 5 cm past either
face). Printed: the share held, and the longest runs of seen wall not held (5 cm steps): a gap the
planner may take for a door. docs/benchmarks.md has the figures.
"""

from __future__ import annotations

import argparse
import bisect
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader

from go2vlm.geometry.rotations import quat_yaw
from go2vlm.sim.houses import generate
from go2vlm.world.map_node import LIDAR_XY
from go2vlm.world.occupancy import Beams, OccupancyMap
from go2vlm.world.poses import Pose2D

STEP = 0.05  # m along a wall
Odom = list[tuple[float, float, float, float]]  # stamp, x, y, yaw
Scans = list[tuple[float, np.ndarray, tuple[float, ...]]]  # stamp, ranges, (angle_min, increment, range_min, max)


def read(bag: Path) -> tuple[Odom, Scans]:
    odom: Odom = []
    scans: Scans = []
    with AnyReader([bag]) as r:
        for c, _, raw in r.messages(connections=[c for c in r.connections if c.topic in ("/scan", "/odom")]):
            m = r.deserialize(raw, c.msgtype)
            s = float(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9)
            if c.topic == "/odom":
                q, p = m.pose.pose.orientation, m.pose.pose.position
                odom.append((s, p.x, p.y, quat_yaw(q.w, q.x, q.y, q.z)))
            else:
                geo = (m.angle_min, m.angle_increment, m.range_min, m.range_max)
                scans.append((s, np.asarray(m.ranges, dtype=np.float32), geo))
    return odom, scans


def build(odom: Odom, scans: Scans, sensor: tuple[float, float] | None) -> OccupancyMap:
    t_odom = [o[0] for o in odom]
    grid = OccupancyMap()
    for s, ranges, (a0, inc, r0, r1) in scans:
        _, x, y, yaw = odom[min(bisect.bisect_left(t_odom, s), len(odom) - 1)]
        grid.integrate(Beams(ranges, a0, inc, r0, r1, sensor=sensor), Pose2D(x, y, yaw))
    return grid


def walls_held(grid: OccupancyMap, seed: int) -> tuple[int, int, list[int]]:
    """(seen, held, the longest runs of seen wall not held) over the house's walls, in STEP steps."""
    values = grid.values()

    def at(x: float, y: float) -> int:
        r, c = grid.cell_of(x, y)
        return int(values[r, c]) if 0 <= r < values.shape[0] and 0 <= c < values.shape[1] else -1

    seen = held = 0
    runs: list[int] = []
    for w in generate(seed).house.walls:
        along_x = w.hx >= w.hy
        half, thick = (w.hx, w.hy) if along_x else (w.hy, w.hx)
        run = 0
        for s in np.arange(-half + 0.1, half - 0.1, STEP):
            # a point s along the wall's length and t across it, from its middle
            centre, along, across = np.array([w.x, w.y]), np.array([1.0, 0.0]), np.array([0.0, 1.0])
            if not along_x:
                along, across = across, along

            def point(t: float, s: float = float(s), c: np.ndarray = centre, a: np.ndarray = along,
                      n: np.ndarray = across) -> tuple[float, float]:  # fmt: skip
                x, y = c + s * a + t * n
                return float(x), float(y)

            front = any(at(*point(k * (thick + 0.2))) == 0 and at(*point(k * (thick + 0.35))) == 0 for k in (-1, 1))
            if not front:
                runs.append(run)
                run = 0
                continue
            seen += 1
            if any(at(*point(t)) >= 50 for t in np.arange(-thick - 0.05, thick + 0.051, 0.025)):
                held += 1
                runs.append(run)
                run = 0
            else:
                run += 1
        runs.append(run)
    return seen, held, sorted(runs)[-4:]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("bag", type=Path)
    ap.add_argument("--house", type=int, required=True, help="the house's seed (its world is house:SEED)")
    a = ap.parse_args()
    odom, scans = read(a.bag)
    for name, sensor in (("from the base", None), ("from the lidar", LIDAR_XY)):
        seen, held, runs = walls_held(build(odom, scans, sensor), a.house)
        print(f"rays {name}: {held} of {seen} seen wall steps held ({held / max(seen, 1):.3f}); "
              f"longest unheld runs {runs} x {STEP:g} m")  # fmt: skip


if __name__ == "__main__":
    main()
