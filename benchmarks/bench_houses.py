"""Generated houses (sim/houses): seeds in a row, each generated (plan, furniture, objects, the
check; a seed that fails is replaced by the next) and its world loaded in MuJoCo with the Go2 in it,
as the sim builds it (sim/worlds.py `build_world_xml`). Target: under 1 s per house, every seed.

    .venv/bin/python benchmarks/bench_houses.py --seeds 1000
    .venv/bin/python benchmarks/bench_houses.py --seeds 200 --first 0 --json houses.json

Reported: wall seconds per house (generate + check, MuJoCo load, both) and CPU seconds (this process:
what the house costs, whatever else loads the machine) as mean, p50, p95 and max; the
seeds whose house failed its check and were replaced (and the reasons, by kind); the houses by room
count, the door widths, the rooms that join only through a third; the MJCF's size (geoms, bodies).
Writes the figure of the time per house (--png) and the JSON (--json).
"""

from __future__ import annotations

import argparse
import collections
import itertools
import json
import os
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

from go2vlm.sim.houses import generate
from go2vlm.sim.worlds import build_world_xml


def run(first: int, seeds: int) -> dict[str, object]:
    gen_s, load_s, cpu_s = [], [], []
    replaced: collections.Counter[str] = collections.Counter()
    rooms: collections.Counter[int] = collections.Counter()
    widths: collections.Counter[float] = collections.Counter()
    through_third = geoms = bodies = failed = 0
    folder = Path(tempfile.mkdtemp(prefix="bench-houses-"))
    for seed in range(first, first + seeds):
        t0, c0 = time.perf_counter(), time.process_time()
        g = generate(seed)
        t1 = time.perf_counter()
        path = folder / "house.xml"
        path.write_text(g.mjcf, encoding="utf-8")
        model = mujoco.MjModel.from_xml_string(build_world_xml(str(path))[0])
        t2 = time.perf_counter()
        cpu_s.append(time.process_time() - c0)
        gen_s.append(t1 - t0)
        load_s.append(t2 - t1)
        failed += bool(g.skipped)
        for _, why in g.skipped:
            replaced[why.split(" (+")[0].split(" in the ")[0]] += 1
        h = g.house
        rooms[len(h.rooms)] += 1
        widths.update(d.width for d in h.doors)
        joined = {frozenset((d.a, d.b)) for d in h.doors}
        names = [r.name for r in h.rooms]
        through_third += any(frozenset(p) not in joined for p in itertools.combinations(names, 2))
        geoms, bodies = geoms + model.ngeom, bodies + model.nbody
    total = np.asarray(gen_s) + np.asarray(load_s)

    def stats(x: list[float] | np.ndarray) -> dict[str, float]:
        a = np.asarray(x)
        pairs = (("mean", a.mean()), ("p50", np.percentile(a, 50)), ("p95", np.percentile(a, 95)), ("max", a.max()))
        return {k: round(float(v), 4) for k, v in pairs}

    return {
        "seeds": seeds,
        "first": first,
        "generate_s": stats(gen_s),
        "load_s": stats(load_s),
        "total_s": stats(total),
        "total_cpu_s": stats(cpu_s),
        "over_1s": int((total >= 1.0).sum()),
        "over_1s_cpu": int((np.asarray(cpu_s) >= 1.0).sum()),
        "seeds_replaced": sum(replaced.values()),
        "asked_seeds_that_failed": failed,
        "replaced_why": dict(replaced.most_common()),
        "rooms": {str(k): v for k, v in sorted(rooms.items())},
        "door_widths_m": {f"{k:.2f}": v for k, v in sorted(widths.items())},
        "houses_with_rooms_joined_only_through_a_third": through_third,
        "geoms_mean": round(geoms / seeds, 1),
        "bodies_mean": round(bodies / seeds, 1),
        "load_average": os.getloadavg()[0],
        "_total": total.tolist(),
    }


def figure(res: dict[str, object], png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    total = np.asarray(res["_total"])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.4))
    a1.plot(np.arange(len(total)) + int(str(res["first"])), total, ".", ms=2)
    a1.axhline(1.0, color="tab:red", lw=0.8, ls="--", label="target: 1 s")
    a1.set_xlabel("seed")
    a1.set_ylabel("generate + check + MuJoCo load (s)")
    a1.legend(fontsize=8)
    a2.hist(total, bins=40, color="tab:blue", alpha=0.8)
    a2.axvline(1.0, color="tab:red", lw=0.8, ls="--")
    a2.set_xlabel("seconds per house")
    a2.set_ylabel("houses")
    a1.set_title(f"{res['seeds']} seeds, load average {float(str(res['load_average'])):.1f}", fontsize=9)
    a2.set_title(f"p50 {np.percentile(total, 50):.2f} s, p95 {np.percentile(total, 95):.2f} s", fontsize=9)
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=1000)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--png", type=Path, default=None, help="the figure of the time per house")
    args = ap.parse_args()
    res = run(args.first, args.seeds)
    if args.png:
        figure(res, args.png)
    res.pop("_total")
    text = json.dumps(res, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
