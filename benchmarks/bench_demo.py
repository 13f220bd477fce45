"""Demo benchmark: the real-time factor of `go2vlm demo` (dynamic trot, head camera 640x480 at 10 Hz)
and where the CPU goes, thread by thread.

    .venv/bin/python benchmarks/bench_demo.py                    # 60 s at rtf 1, then 20 s --fast
    .venv/bin/python benchmarks/bench_demo.py --duration 30 --no-fast --json out.json
    .venv/bin/python benchmarks/bench_demo.py --world household --mode kinematic   # another world or physics

Runs the demo in this process exactly as `go2vlm demo` does (sim + color_detector + follower +
safety gate + the recorder, video on: it is rendered after the run, so it is not in the CPU per sim
second), on a private DDS domain on loopback. Reports:
- the achieved real-time factor at target 1.0 (must stay >= 1.0 on the 2-core reference machine),
- the CPU seconds per thread per sim second (physics, render + Mesa's llvmpipe workers, nodes),
- with --fast, the highest real-time factor this machine reaches (the headroom).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import sys
import tempfile
from pathlib import Path
from typing import Any

os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(20, 220)))
os.environ.setdefault("GO2VLM_IFACE", "lo")

from go2vlm.apps.episodes import Episode, RunOptions, run_episode  # noqa: E402


def group(cpu: dict[str, float]) -> dict[str, float]:
    """Thread names -> the parts of the demo."""
    out: dict[str, float] = {}
    for name, s in cpu.items():
        if name == "sim:physics":
            key = "sim physics (MuJoCo + trot controller + state topics)"
        elif name == "sim:render" or "llvmpipe" in name:
            key = "head camera rendering (render thread + llvmpipe)"
        elif name == "node:color_detector":
            key = "color_detector"
        elif name in ("node:follower", "node:safety"):
            key = "follower + safety gate"
        elif name == "node:episode_recorder":
            key = "episode recorder (video: rendered after the run)"
        else:
            key = "other (DDS, main thread, sim executor)"
        out[key] = out.get(key, 0.0) + s
    return out


def run(duration: float, fast: bool, video: bool, world: str = "follow_ball", mode: str = "dynamic") -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        # the follow article's loop; in a world whose red ball stands still it walks to it and stays there
        ep = Episode(world=world, duration_s=duration, mode=mode)
        m = run_episode(ep, RunOptions(fast=fast, out=Path(tmp), video=video, cpu=True)).metrics
    sim_s = max(m["duration_s"], 1e-9)
    groups = group(m["cpu_s_by_thread"])
    return {
        "mode": "fast" if fast else "rtf 1.0",
        "world": world,
        "physics": mode,
        "sim_s": m["duration_s"],
        "wall_s": m["wall_s"],
        "real_time_factor": m["real_time_factor"],
        "target_visible_fraction": m["target_visible_fraction"],
        "fell": m["fell"],
        "frames": m["frames"],
        "cpu_s_per_sim_s": {k: round(v / sim_s, 3) for k, v in sorted(groups.items(), key=lambda kv: -kv[1])},
        "real_time_factor_with_startup": m["real_time_factor_with_startup"],
        "cpu_cores_busy": round(m["cpu_s_process"] / max(m["wall_s"], 1e-9), 2),
        "loadavg_1min_after": round(os.getloadavg()[0], 2),
        "threads": m["cpu_s_by_thread"],
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=60.0, help="sim seconds of the real-time run")
    ap.add_argument("--fast-duration", type=float, default=20.0, help="sim seconds of the --fast run")
    ap.add_argument("--no-fast", dest="fast", action="store_false", help="skip the --fast run")
    ap.add_argument("--no-video", dest="video", action="store_false", help="without the MP4 encoder")
    ap.add_argument("--world", default="follow_ball", help="the world (the demo's: follow_ball)")
    ap.add_argument("--mode", choices=("dynamic", "kinematic"), default="dynamic", help="the sim's physics")
    ap.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = ap.parse_args()

    results = [run(args.duration, False, args.video, args.world, args.mode)]
    if args.fast:
        results.append(run(args.fast_duration, True, args.video, args.world, args.mode))
    info = {"cpus": os.cpu_count(), "machine": platform.machine(), "python": platform.python_version(),
            "MUJOCO_GL": os.environ.get("MUJOCO_GL")}  # fmt: skip
    for r in results:
        print(
            f"\n{r['world']}, {r['physics']}, {r['mode']}: {r['sim_s']:.1f} sim s in {r['wall_s']:.1f} wall s "
            f"-> real-time factor {r['real_time_factor']:.2f}; "
            f"ball in view {100 * r['target_visible_fraction']:.1f} %, "
            f"fell={r['fell']}; CPU {r['cpu_cores_busy']:.2f} of {info['cpus']} cores "
            f"(machine load average {r['loadavg_1min_after']:.2f})"
        )
        print("  CPU seconds per sim second:")
        for k, v in r["cpu_s_per_sim_s"].items():
            print(f"    {v:6.3f}  {k}")
    if args.json:
        args.json.write_text(json.dumps({"machine": info, "results": results}, indent=2) + "\n")
    return 0 if all(not r["fell"] for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
