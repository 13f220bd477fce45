"""Benchmark the go2vlm MuJoCo simulation: physics rate, controller cost, render cost.

Usage: python benchmarks/bench_sim.py [--seconds 5] [--frames 30] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import mujoco
import numpy as np

from go2vlm.sim import Go2Sim, SimConfig

REPEATS = 3  # best of N: the machine is shared, the minimum time is the least disturbed


def _rate(fn, n: int, clock=time.perf_counter) -> float:
    """Calls per second, best of REPEATS.  ``clock=time.thread_time`` counts only this thread's
    CPU time: steadier than wall time on a loaded machine (single-threaded work only)."""
    best = float("inf")
    for _ in range(REPEATS):
        t0 = clock()
        for _ in range(n):
            fn()
        best = min(best, clock() - t0)
    return n / best


def _ms(fn, n: int) -> float:
    return 1e3 / _rate(fn, n)


def bench_physics(seconds: float) -> dict[str, float]:
    out: dict[str, float] = {}
    sim = Go2Sim(SimConfig(world="follow_ball", control_decimation=1))
    sim.advance(0.2)
    sim.set_command(0.8, 0.0, 0.3)
    sim.advance(0.5)
    n = int(seconds / sim.dt)
    out["dynamic_500hz_ctrl_steps_per_s"] = _rate(sim.step, n)  # controller every physics step
    out["dynamic_500hz_ctrl_steps_per_cpu_s"] = _rate(sim.step, n, time.thread_time)
    sim250 = Go2Sim(SimConfig(world="follow_ball", control_decimation=2))  # the default
    sim250.advance(0.2)
    sim250.set_command(0.8, 0.0, 0.3)
    sim250.advance(0.5)
    out["dynamic_250hz_ctrl_steps_per_s"] = _rate(sim250.step, n)
    out["dynamic_250hz_ctrl_steps_per_cpu_s"] = _rate(sim250.step, n, time.thread_time)
    m, d = sim.model, sim.data
    out["physics_only_steps_per_s"] = _rate(lambda: mujoco.mj_step(m, d), n)
    out["physics_only_steps_per_cpu_s"] = _rate(lambda: mujoco.mj_step(m, d), n, time.thread_time)
    out["physics_only_realtime_factor"] = out["physics_only_steps_per_s"] * sim.dt  # torques held, no controller
    x = sim._robot_input()
    ctrl = sim.controller
    out["controller_ms_per_tick_walking"] = _ms(lambda: ctrl.compute(x), 2000)
    out["controller_cpu_ms_per_tick_walking"] = 1e3 / _rate(lambda: ctrl.compute(x), 2000, time.thread_time)
    sim_k = Go2Sim(SimConfig(world="follow_ball", mode="kinematic"))
    sim_k.set_command(0.8, 0.0, 0.3)
    out["kinematic_steps_per_s"] = _rate(sim_k.step, n)
    out["kinematic_steps_per_cpu_s"] = _rate(sim_k.step, n, time.thread_time)
    out["dynamic_500hz_ctrl_realtime_factor"] = out["dynamic_500hz_ctrl_steps_per_s"] * sim.dt
    out["dynamic_250hz_ctrl_realtime_factor"] = out["dynamic_250hz_ctrl_steps_per_s"] * sim.dt
    out["kinematic_realtime_factor"] = out["kinematic_steps_per_s"] * sim.dt
    return out


def bench_render(frames: int) -> dict[str, float]:
    out: dict[str, float] = {}
    sim = Go2Sim(SimConfig(world="follow_ball", mode="kinematic"))
    sim.set_command(0.5, 0.0, 0.0)
    for w, h in ((320, 240), (640, 480), (1280, 720)):
        sim.render_head(w, h)  # context creation and warm-up excluded
        out[f"render_head_ms_{w}x{h}"] = _ms(lambda w=w, h=h: sim.render_head(w, h), frames)
    sim.render_world_camera()
    out["render_world_camera_ms_640x480"] = _ms(sim.render_world_camera, frames)
    sim.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per physics measurement")
    ap.add_argument("--frames", type=int, default=30, help="frames per render measurement")
    ap.add_argument("--no-render", action="store_true")
    ap.add_argument("--json", type=str, default=None, help="write the results to this JSON file")
    args = ap.parse_args()
    results: dict[str, float | str] = {
        "mujoco": mujoco.__version__,
        "cpu_count": str(os.cpu_count()),
        "machine": platform.processor() or platform.machine(),
    }
    results.update(bench_physics(args.seconds))
    if not args.no_render:
        results.update(bench_render(args.frames))
    results["MUJOCO_GL"] = os.environ.get("MUJOCO_GL", "")
    width = max(len(k) for k in results)
    print(f"{'metric':<{width}}  value")
    for k, v in results.items():
        print(f"{k:<{width}}  {v:.3f}" if isinstance(v, float) else f"{k:<{width}}  {v}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
