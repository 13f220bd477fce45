"""How far the sim's leg odometry drifts (sim/odometry_drift.py, the sim node's `odom_drift`) over a
100 m walk: the uncorrected baseline a scan matcher is measured against.

    .venv/bin/python benchmarks/bench_odom_drift.py --seeds 200

Two 100 m walks sampled as the sim node samples /odom (50 Hz at 0.5 m/s: 1 cm steps): straight ahead,
and four laps of a 15 x 10 m loop (the apartment's size) that turns left at every corner. Per gain:
the final position error (metres and % of the distance) and heading error over the seeds, median and
90th percentile. Pure model, no sim: the same figures the node gives, since it feeds the model the
true poses it publishes.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from go2vlm.sim.odometry_drift import OdometryDrift

STEP = 0.01  # m: 0.5 m/s at the sim node's 50 Hz /odom


def straight(length: float = 100.0) -> list[tuple[float, float, float]]:
    n = int(round(length / STEP))
    return [(k * STEP, 0.0, 0.0) for k in range(n + 1)]


def loop(width: float = 15.0, height: float = 10.0, laps: int = 2) -> list[tuple[float, float, float]]:
    """Laps of a width x height rectangle, turning left on the spot at each corner (2 laps = 100 m)."""
    out: list[tuple[float, float, float]] = []
    x = y = yaw = 0.0
    for _ in range(laps):
        for side in (width, height, width, height):
            for _ in range(int(round(side / STEP))):
                out.append((x, y, yaw))
                x, y = x + STEP * math.cos(yaw), y + STEP * math.sin(yaw)
            for _ in range(20):  # the turn, in 20 steps of 4.5 deg
                out.append((x, y, yaw))
                yaw = math.atan2(math.sin(yaw + math.pi / 40), math.cos(yaw + math.pi / 40))
    out.append((x, y, yaw))
    return out


def errors(path: list[tuple[float, float, float]], gain: float, seeds: int) -> dict[str, float]:
    pos, head = [], []
    for seed in range(seeds):
        drift = OdometryDrift(gain, seed)
        est = (0.0, 0.0, 0.0)
        for p in path:
            est = drift.update(*p)
        tx, ty, tyaw = path[-1]
        pos.append(math.hypot(est[0] - tx, est[1] - ty))
        head.append(abs(math.degrees(math.remainder(est[2] - tyaw, 2 * math.pi))))
    dist = sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(path, path[1:], strict=False))
    return {
        "distance_m": round(dist, 1),
        "position_error_m_median": round(float(np.median(pos)), 2),
        "position_error_m_p90": round(float(np.percentile(pos, 90)), 2),
        "position_error_pct_median": round(100 * float(np.median(pos)) / dist, 2),
        "heading_error_deg_median": round(float(np.median(head)), 2),
        "heading_error_deg_p90": round(float(np.percentile(head, 90)), 2),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--gains", default="1,2")
    ap.add_argument("--json", default=None, help="also write the figures here")
    args = ap.parse_args()
    rows = []
    for gain in (float(g) for g in args.gains.split(",")):
        for name, path in (("straight 100 m", straight()), ("loop 2 x 15 x 10 m", loop())):
            row = {"walk": name, "gain": gain, "seeds": args.seeds, **errors(path, gain, args.seeds)}
            print(json.dumps(row), flush=True)
            rows.append(row)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
