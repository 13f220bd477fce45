"""Replay an episode's recorded answers through the object memory's placement, with the body's pitch
and taken level, and measure each placed box against the house's true item places.

    python scripts/replay_placement.py runs/houses-002/episodes/houses-002/bag --house 1002
    python scripts/replay_placement.py BAG --house 1002 --scan     # with the recorded scan, as the node

The bag is an eval episode's (`go2vlm eval ... --bag`): /sim/detections (the oracle's boxes), /odom,
/camera/camera_info and, with --scan, /scan. Every `--every`-th box of a label the house holds is
placed (world/placement.py `place`) at the /odom pose and pitch nearest its stamp; the error is the
placed centre's distance from the item's. Printed by the robot's distance from the item, for boxes
ranged by their bottom edge (the ranging the pitch enters); docs/benchmarks.md has the figures.
"""

from __future__ import annotations

import argparse
import bisect
import math
import statistics
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader

from go2vlm.geometry.camera import PinholeCamera
from go2vlm.geometry.rotations import quat_pitch, quat_yaw
from go2vlm.perception.ranging import RangeEstimator
from go2vlm.sim.houses import generate
from go2vlm.vocabulary.words import parse_label
from go2vlm.world.labels import normalize_label
from go2vlm.world.placement import CameraMount, PlacementError, place
from go2vlm.world.poses import Pose2D

BANDS = ((0.0, 2.0), (2.0, 4.0), (4.0, 8.0))  # the robot's distance from the item (m)


def _stamp(header: object) -> float:
    t = header.stamp  # type: ignore[attr-defined]
    return float(t.sec + t.nanosec * 1e-9)


def read(bag: Path, scan: bool) -> tuple[list[tuple[float, ...]], list[tuple[float, str, tuple[float, ...]]],
                                         PinholeCamera, list[tuple[float, np.ndarray]]]:  # fmt: skip
    odom: list[tuple[float, ...]] = []
    boxes: list[tuple[float, str, tuple[float, ...]]] = []
    scans: list[tuple[float, np.ndarray]] = []
    cam: PinholeCamera | None = None
    topics = {"/odom", "/sim/detections", "/camera/camera_info"} | ({"/scan"} if scan else set())
    with AnyReader([bag]) as r:
        for c, _, raw in r.messages(connections=[c for c in r.connections if c.topic in topics]):
            m = r.deserialize(raw, c.msgtype)
            s = _stamp(m.header)
            if c.topic == "/odom":
                q, p = m.pose.pose.orientation, m.pose.pose.position
                odom.append((s, p.x, p.y, quat_yaw(q.w, q.x, q.y, q.z), quat_pitch(q.w, q.x, q.y, q.z)))
            elif c.topic == "/camera/camera_info" and cam is None:
                k = m.k
                cam = PinholeCamera(int(m.width), int(m.height), float(k[0]), float(k[4]), float(k[2]), float(k[5]))
            elif c.topic == "/sim/detections":
                for d in m.detections:
                    b, label = d.bbox, d.results[0].hypothesis.class_id if d.results else ""
                    cx, cy, w, h = b.center.position.x, b.center.position.y, b.size_x, b.size_y
                    boxes.append((s, label, (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)))
            elif c.topic == "/scan":
                a = m.angle_min + m.angle_increment * np.arange(len(m.ranges))
                rng = np.asarray(m.ranges, dtype=float)
                ok = np.isfinite(rng) & (rng <= m.range_max)
                scans.append((s, np.column_stack([rng[ok] * np.cos(a[ok]), rng[ok] * np.sin(a[ok])])))
    if cam is None:
        raise SystemExit(f"{bag}: no /camera/camera_info")
    return odom, boxes, cam, scans


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("bag", type=Path)
    ap.add_argument("--house", type=int, required=True, help="the house's seed (its world is house:SEED)")
    ap.add_argument("--scan", action="store_true", help="range with the recorded scan too, as the node does")
    ap.add_argument("--every", type=int, default=3, help="place every n-th box")
    a = ap.parse_args()
    items = {it.name.replace("_", " "): (it.cx, it.cy) for it in generate(a.house).house.items}
    odom, boxes, cam, scans = read(a.bag, a.scan)
    t_odom, t_scan = [o[0] for o in odom], [s[0] for s in scans]
    mount = CameraMount()
    for pitched in (False, True):
        rangers: dict[str, RangeEstimator] = {}
        errors: list[tuple[float, float]] = []  # (the robot's distance from the item, the error)
        for s, label, box in boxes[:: a.every]:
            name = normalize_label(label)
            if name not in items:
                continue
            _, x, y, yaw, pitch = odom[min(bisect.bisect_left(t_odom, s), len(odom) - 1)]
            ranger = rangers.setdefault(name, RangeEstimator(parse_label(name).shape, camera_height=mount.height_m))
            points = scans[min(bisect.bisect_left(t_scan, s), len(scans) - 1)][1] if scans else None
            try:
                p = place(name, box, s, Pose2D(x, y, yaw), cam, mount, ranger, points, None, pitch if pitched else 0.0)
            except PlacementError:
                continue
            if p.range_m is None or p.method != "bottom":
                continue
            tx, ty = items[name]
            errors.append((math.hypot(tx - x, ty - y), math.hypot(p.x - tx, p.y - ty)))
        for lo, hi in BANDS:
            band = [e for d, e in errors if lo <= d < hi]
            if band:
                print(f"{'pitch' if pitched else 'level'} {lo:g}-{hi:g} m: {len(band)} boxes, error median "
                      f"{statistics.median(band):.2f} m, mean {statistics.mean(band):.2f} m")  # fmt: skip


if __name__ == "__main__":
    main()
