"""What a world costs the sim: the Go2 trotting (dynamic physics, trot controller) with the head camera
rendered at 10 Hz of sim time, 640x480, as the sim node runs it, for the household world against the
demo's follow_ball world.

    .venv/bin/python benchmarks/bench_worlds.py --worlds follow_ball,household --seconds 20

Per world: wall seconds and CPU seconds (this process, every thread: physics, controller, llvmpipe's
render threads) per sim second, and the mean head-camera render time. A world holds a real-time factor
of 1 where its CPU per sim second stays under the cores the sim gets (the sim node also publishes and
the other nodes share the machine: the demo's 0.39 cores at rtf 1 are in docs/benchmarks.md). CPU
figures are the steady ones on a loaded machine; wall figures depend on the load (printed).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import go2vlm.sim  # noqa: F401 - picks the headless GL backend before mujoco loads
from go2vlm.sim import Go2Sim, SimConfig


def measure(world: str, seconds: float, camera_hz: float = 10.0) -> dict[str, float | str]:
    sim = Go2Sim(SimConfig(world=world, mode="dynamic", seed=1))
    sim.set_command(0.4, 0.0, 0.3)  # trotting on a curve: the controller's full cost
    sim.advance(1.0)
    sim.render_head()  # GL context and scene built before timing
    period = 1.0 / camera_hz
    renders: list[float] = []
    cpu0, wall0 = os.times(), time.perf_counter()
    t = 0.0
    while t < seconds:
        sim.advance(period)
        t += period
        r0 = time.perf_counter()
        sim.render_head()
        renders.append(time.perf_counter() - r0)
    wall = time.perf_counter() - wall0
    cpu1 = os.times()
    cpu = (cpu1.user + cpu1.system) - (cpu0.user + cpu0.system)
    fell = sim.fell
    sim.close()
    return {
        "world": world,
        "sim_s": round(seconds, 1),
        "wall_s_per_sim_s": round(wall / seconds, 3),
        "cpu_s_per_sim_s": round(cpu / seconds, 3),
        "render_ms_mean": round(1000 * sum(renders) / len(renders), 1),
        "fell": bool(fell),
        "load_avg": " ".join(f"{v:.1f}" for v in os.getloadavg()),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worlds", default="follow_ball,household")
    ap.add_argument("--seconds", type=float, default=20.0, help="sim seconds per world")
    ap.add_argument("--json", default=None, help="also write the figures here")
    args = ap.parse_args()
    rows = [measure(w, args.seconds) for w in args.worlds.split(",")]
    for r in rows:
        print(json.dumps(r))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
