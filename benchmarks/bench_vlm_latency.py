"""How slow may the VLM be? Follow the moving ball and run "go to" episodes while perfect grounding
answers arrive L seconds late, for L in 0.1, 1, 2.5, 5 and 10 s (the VLM article's 3B took 2-3 s a frame;
an onboard Jetson is slower).

    .venv/bin/python benchmarks/bench_vlm_latency.py --json runs/vlm_latency.json --plot docs/img/vlm_latency.png

Latency is isolated from accuracy: the answers are the sim's ground-truth boxes of the head frames
(/sim/detections), delivered as a VLM delivers them by the `answer_delay` node (perception/answer_delay.py):
one frame at a time, the newest when it is free, each answer L sim seconds after its frame, with its
frame's stamp. They reach the real target_tracker on /vlm/detections, and the real commander, follower
and safety gate drive the sim; everything runs on sim time, so L is exact whatever the host's speed.
The graph is launch/episode_vlm.yaml's with answer_delay in the vlm node's place (the commander's
search_yaw_rate 0.25), and the object memory (world/) placing every answer at the pose of its frame;
`--no-memory` runs it without the memory (the commander as it was before it: it turns on at 0.25 rad/s
whatever the latency).

Episodes (kinematic physics):
- follow: "follow the red ball" in follow_ball, the ball at 0.3 m/s on its closed path, --follow-s sim
  seconds; reported: the ball inside the head camera's field of view (ground truth), the fraction of
  the time the commander saw it confirmed, and whether the follow succeeded (metrics.py).
- go to: the first --goto go-to episodes of the `goals` suite (seeded random spawns anywhere in the
  8 x 8 m square, any heading; goals/000, 001, 002, 006, ...): success and time to goal. Each episode's
  timeout is the suite's 40 s plus --timeout-per-latency (20) seconds per second of latency: a search
  that waits for each answer needs time in proportion to it (and --follow-s is the follow's length).
Targets: follow keeps the ball in view >= 90 % of the time at 2.5 s; go to succeeds >= 90 % at 5 s and
at 10 s, within 5 points of 0.1 s.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import random
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(20, 220)))
os.environ.setdefault("GO2VLM_IFACE", "lo")

from go2vlm.apps.episodes import Episode, RunOptions, run_episode  # noqa: E402
from go2vlm.apps.episodes.episode import TIMEOUT_PER_LATENCY_S  # noqa: E402
from go2vlm.apps.episodes.suites import load_suite  # noqa: E402
from go2vlm.bus import ShutdownRequested  # noqa: E402
from go2vlm.cli.args import node_params  # noqa: E402

LATENCIES = (0.1, 1.0, 2.5, 5.0, 10.0)


def graph_yaml(memory: bool = True) -> str:
    """episode_vlm.yaml with the answer_delay node in the vlm node's place, with or without the memory."""
    mem = "- node: object_memory\n  params: {use_sim_time: true, answers_cover: all}\n" if memory else ""
    return f"""# episode_vlm.yaml with answer_delay in the vlm node's place (benchmarks/bench_vlm_latency.py)
- node: sim
  params: {{use_sim_time: true, world: vision_test, world_camera: false, detections: true}}
- node: answer_delay
  params: {{use_sim_time: true, input_topic: /sim/detections, output_topic: /vlm/detections}}
- node: target_tracker
  params: {{use_sim_time: true, grounding: vlm}}
{mem}- node: commander
  params: {{use_sim_time: true, search_yaw_rate: 0.25}}
- node: follower
  params: {{use_sim_time: true}}
- node: safety
  params: {{use_sim_time: true}}
"""


GRAPH = graph_yaml()


def episodes(follow_s: float, n_goto: int) -> list[Episode]:
    out = [Episode(world="follow_ball", goal="follow the red ball", perception="vlm", mode="kinematic",
                   ball_speed=0.3, duration_s=follow_s, id="follow")]  # fmt: skip
    suite = load_suite("goals")
    k = 0
    while sum(ep.kind == "go_to" for ep in out) < n_goto:
        ep = suite.episode(k, "vlm")
        if ep.kind == "go_to":
            out.append(ep)
        k += 1
    return out


def run_one(
    ep: Episode,
    latency: float,
    graph: Path,
    rtf: float,
    fast: bool,
    extra: dict[str, dict[str, Any]] | None = None,
    timeout_per_latency: float = 0.0,
) -> dict[str, Any]:
    params = {**ep.params, **(extra or {})}
    params["answer_delay"] = {**params.get("answer_delay", {}), "latency_s": latency}
    duration = ep.duration_s + (timeout_per_latency * latency if ep.kind != "follow" else 0.0)  # latency_timeout's rule
    ep = dataclasses.replace(ep, graph=str(graph), params=params, duration_s=duration)
    m = run_episode(ep, RunOptions(rtf=rtf, fast=fast, video=False), ShutdownRequested()).metrics
    keep = ("episode", "kind", "goal", "success", "time_to_goal_s", "target_in_view_fraction", "collisions",
            "real_time_factor", "tracked_fraction", "final_state", "spawn")  # fmt: skip
    row = {k: m.get(k) for k in keep}
    row["latency_s"] = latency
    row["timeout_s"] = duration
    row["tracker"] = m["tracker"]
    row["memory"] = m.get("memory")
    row["result_age_s_mean"] = (m["grounding"] or {}).get("result_age_s_mean")
    return row


def summarise(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    table = []
    for lat in sorted({r["latency_s"] for r in rows}):
        f = next(r for r in rows if r["latency_s"] == lat and r["kind"] == "follow")
        goto = [r for r in rows if r["latency_s"] == lat and r["kind"] == "go_to"]
        times = [r["time_to_goal_s"] for r in goto if r["success"] and r["time_to_goal_s"] is not None]
        table.append(
            {
                "latency_s": lat,
                "follow_in_view": f["target_in_view_fraction"],
                "follow_confirmed": f["tracked_fraction"],
                "follow_success": f["success"],
                "follow_carried": f["tracker"]["carried_fraction"],
                "goto_success": sum(r["success"] for r in goto),
                "goto_episodes": len(goto),
                "goto_time_mean_s": round(sum(times) / len(times), 2) if times else None,
                "result_age_s_mean": f["result_age_s_mean"],
                "collisions": sum(r["collisions"] for r in rows if r["latency_s"] == lat),
                "forward_unconfirmed": sum((r["tracker"] or {}).get("forward_unconfirmed", 0) for r in goto),
                "goto_timeout_s": goto[0]["timeout_s"] if goto else None,
            }
        )
    return table


def plot(table: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lat = [r["latency_s"] for r in table]
    fig, ax = plt.subplots(1, 3, figsize=(12, 3.4))
    ax[0].plot(lat, [100 * r["follow_in_view"] for r in table], "o-", label="ball in view")
    ax[0].plot(lat, [100 * r["follow_confirmed"] for r in table], "s--", label="target confirmed")
    ax[0].axhline(90, color="grey", lw=0.8, ls=":")
    ax[0].set(title="follow the ball (0.3 m/s)", xlabel="answer latency (s)", ylabel="% of the time", ylim=(0, 105))
    ax[0].legend(loc="lower left")
    ax[1].plot(lat, [100 * r["goto_success"] / max(1, r["goto_episodes"]) for r in table], "o-")
    ax[1].set(title=f"go to: success ({table[0]['goto_episodes']} episodes)", xlabel="answer latency (s)",
              ylabel="%", ylim=(0, 105))  # fmt: skip
    ax[2].plot(lat, [r["goto_time_mean_s"] or float("nan") for r in table], "o-")
    ax[2].set(title="go to: time to goal (successes)", xlabel="answer latency (s)", ylabel="sim s")
    for a in ax:
        a.set_xscale("log")
        a.set_xticks(lat, [f"{v:g}" for v in lat])
        a.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--latencies", type=float, nargs="+", default=list(LATENCIES))
    ap.add_argument("--follow-s", type=float, default=40.0, help="sim seconds of the follow episode")
    ap.add_argument("--goto", type=int, default=12, help="go-to episodes per latency (the goals suite's first)")
    ap.add_argument(
        "--timeout-per-latency",
        type=float,
        default=TIMEOUT_PER_LATENCY_S,
        help="go to: timeout = the suite's + this many seconds per second of latency (the eval's rule)",
    )
    ap.add_argument("--no-memory", action="store_true", help="without the object memory (the commander before it)")
    ap.add_argument("--rtf", type=float, default=2.0, help="target real-time factor (sim time is what counts)")
    ap.add_argument("--fast", action="store_true")
    ap.add_argument(
        "--param", "-p", action="append", default=[], metavar="NODE.NAME=VALUE",
        help="a node parameter for every episode, e.g. target_tracker.max_answer_age_s=8",
    )  # fmt: skip
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--plot", type=Path, default=None)
    args = ap.parse_args()
    t0 = time.monotonic()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        graph = Path(tmp) / "episode_delayed.yaml"
        graph.write_text(graph_yaml(memory=not args.no_memory))
        for lat in args.latencies:
            for ep in episodes(args.follow_s, args.goto):
                row = run_one(ep, lat, graph, args.rtf, args.fast, node_params(args.param), args.timeout_per_latency)
                rows.append(row)
                print(json.dumps({k: row[k] for k in ("latency_s", "episode", "goal", "success",
                                                       "target_in_view_fraction", "time_to_goal_s")}),
                      file=sys.stderr, flush=True)  # fmt: skip
    table = summarise(rows)
    print("| latency | ball in view | target confirmed | follow success | go to success | time to goal | timeout "
          "| collisions | forward unconfirmed |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for r in table:
        t = "n/a" if r["goto_time_mean_s"] is None else f"{r['goto_time_mean_s']:.1f} s"
        print(
            f"| {r['latency_s']:g} s | {100 * r['follow_in_view']:.1f} % | {100 * r['follow_confirmed']:.1f} % | "
            f"{'yes' if r['follow_success'] else 'no'} | {r['goto_success']}/{r['goto_episodes']} | {t} | "
            f"{r['goto_timeout_s']:g} s | {r['collisions']} | {r['forward_unconfirmed']} |"
        )
    out = {
        "table": table,
        "rows": rows,
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "wall_s": round(time.monotonic() - t0, 1),
        "host": {"cpus": os.cpu_count(), "python": platform.python_version()},
    }
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=1))
    if args.plot:
        plot(table, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
