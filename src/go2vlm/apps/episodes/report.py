"""summary.json, report.md and the plots of an eval folder, from its results.jsonl.

Groups: one row per (suite, perception variant, model, added answer latency); a run with odometry
drift (`--drift`) is a suite of its own ("rooms (odometry drift 1)"). Confidence intervals, 95 %:
  rates (success, grounding precision and recall at IoU 0.5)  Wilson score interval;
  means (SPL, time to goal)                                   percentile bootstrap, 10,000 resamples
                                                              of the episodes, seeded (reproducible).
In generated houses (the `houses` suite) each group is also split by the number of doors between
the spawn and the object and by the narrowest of them (bins of DOOR_BINS): success, SPL and time to goal.
Precision and recall pool the answers of all episodes; answers within one episode are correlated
(consecutive frames), so their intervals are narrower than a per-episode analysis would give.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from go2vlm.apps.episodes.outputs import atomic, read_jsonl, write_json, write_text

__all__ = ["bootstrap_ci", "summarize", "wilson", "write_report"]

Z95 = 1.959963984540054
BOOTSTRAP = 10_000
DOOR_BINS = ((0.0, 0.8), (0.8, 0.9), (0.9, 9.9))  # narrowest door on the way, metres: [lo, hi)


def wilson(k: int, n: int, z: float = Z95) -> tuple[float, float] | None:
    """Wilson score interval of a proportion k/n; None for n = 0."""
    if n <= 0:
        return None
    p = k / n
    d = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / d
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(0.0, centre - half), min(1.0, centre + half)


def bootstrap_ci(values: list[float], seed: int = 0) -> tuple[float, float] | None:
    """Percentile bootstrap 95 % interval of the mean; None without values."""
    if not values:
        return None
    x = np.asarray(values, dtype=float)
    if len(x) == 1:
        return float(x[0]), float(x[0])
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, len(x), size=(BOOTSTRAP, len(x)))].mean(axis=1)
    return float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


def _r(v: float | None, n: int = 4) -> float | None:
    return None if v is None else round(v, n)


def _ci(ci: tuple[float, float] | None) -> list[float] | None:
    return None if ci is None else [round(ci[0], 4), round(ci[1], 4)]


def suite_label(suite: str, odom_drift: float | None) -> str:
    """The suite's name, with the odometry drift of a drift run (`go2vlm eval --drift`): a row of its own."""
    return suite if not odom_drift else f"{suite} (odometry drift {odom_drift:g})"


def group_key(line: dict[str, Any]) -> tuple[str, str, str, float]:
    """(suite with its drift, variant, model, added answer latency; -1: no latency axis)."""
    run = line["config"]
    lat = run.get("answer_latency_s")
    suite = suite_label(run["suite"], run.get("odom_drift"))
    return suite, run["perception"], run.get("model") or "", -1.0 if lat is None else float(lat)


def _num(v: object) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def _cell(ms: Sequence[Mapping[str, object]]) -> dict[str, object]:
    """Success, SPL and time to goal of some episodes."""
    wins = sum(bool(m["success"]) for m in ms)
    spl = [v for m in ms if (v := _num(m.get("spl"))) is not None]
    ttg = [v for m in ms if m.get("success") and (v := _num(m.get("time_to_goal_s"))) is not None]
    return {
        "episodes": len(ms),
        "success": wins,
        "success_rate": _r(wins / len(ms)) if ms else None,
        "success_rate_ci95": _ci(wilson(wins, len(ms))),
        "spl_mean": _r(float(np.mean(spl))) if spl else None,
        "time_to_goal_s_mean": _r(float(np.mean(ttg)), 2) if ttg else None,
    }


def by_house(ms: Sequence[Mapping[str, object]]) -> dict[str, object] | None:
    """A group's episodes in generated houses by number of doors and by narrowest door; None without any."""
    doors: dict[int, list[Mapping[str, object]]] = defaultdict(list)
    narrow: dict[str, list[Mapping[str, object]]] = defaultdict(list)
    seeds, replaced = set(), 0
    for m in ms:
        h = m.get("house")
        if not isinstance(h, dict) or h.get("doors") is None:
            continue
        doors[int(h["doors"])].append(m)
        seeds.add(h["seed"])
        replaced += h["seed"] != h["asked_seed"]
        w = _num(h.get("narrowest_door_m"))
        if w is not None:
            lo, hi = next(b for b in DOOR_BINS if b[0] <= w < b[1])
            narrow[f"< {hi:.2f}" if lo == 0 else f"{lo:.2f}-{hi:.2f}" if hi < 9 else f">= {lo:.2f}"].append(m)
    if not doors:
        return None
    return {
        "houses": len(seeds),
        "replaced_seeds": replaced,
        "by_doors": {str(n): _cell(v) for n, v in sorted(doors.items())},
        "by_narrowest_door_m": {k: _cell(v) for k, v in sorted(narrow.items())},
    }


def summarize(lines: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One summary per (suite, variant, model, latency)."""
    groups: dict[tuple[str, str, str, float], list[dict[str, Any]]] = defaultdict(list)
    for line in lines:
        groups[group_key(line)].append(line)
    out = []
    for (suite, perception, model, latency), rows in sorted(groups.items()):
        ms = [r["metrics"] for r in rows]
        n = len(ms)
        wins = sum(bool(m["success"]) for m in ms)
        spl = [m["spl"] for m in ms if m.get("spl") is not None]
        ttg = [m["time_to_goal_s"] for m in ms if m.get("success") and m.get("time_to_goal_s") is not None]
        g = [m["grounding"] for m in ms if m.get("grounding")]
        hits = sum(x["hits"] for x in g)
        boxed = sum(x["answers_with_box"] for x in g)
        visible = sum(x["answers_target_visible"] for x in g)
        ious = [v for x in g for v in x["iou"]]
        lat = [m["vlm"]["latency_ms_mean"] for m in ms if m.get("vlm") and m["vlm"].get("latency_ms_mean") is not None]
        mem = [m["memory"] for m in ms if m.get("memory")]  # the object memory at each episode's end
        remembered = sum(len(x["objects"]) for x in mem)
        errs = [o["error_m"] for x in mem for o in x["objects"] if not o["phantom"] and o["error_m"] is not None]
        by_kind: dict[str, list[bool]] = defaultdict(list)
        for m in ms:
            by_kind[m["kind"]].append(bool(m["success"]))
        sessions: dict[str, list[dict[str, Any]]] = defaultdict(list)
        for r in rows:
            sessions[r.get("session", "")].append(r)
        last = max(sessions.values(), key=lambda rs: max(x.get("finished_at", 0.0) for x in rs))
        span = max(x.get("finished_at", 0.0) for x in last) - min(x.get("session_started_at", 0.0) for x in last)
        cfg = rows[-1]["config"]
        out.append(
            {
                "suite": suite,
                "perception": perception,
                "model": model or None,
                "answer_latency_s": None if latency < 0 else latency,
                "odom_drift": cfg.get("odom_drift"),
                "episodes": n,
                "success": wins,
                "success_rate": _r(wins / n),
                "success_rate_ci95": _ci(wilson(wins, n)),
                "success_by_kind": {k: {"episodes": len(v), "success": sum(v)} for k, v in sorted(by_kind.items())},
                "spl_mean": _r(float(np.mean(spl))) if spl else None,
                "spl_ci95": _ci(bootstrap_ci(spl)),
                "spl_episodes": len(spl),
                "time_to_goal_s_mean": _r(float(np.mean(ttg)), 2) if ttg else None,
                "time_to_goal_s_ci95": _ci(bootstrap_ci(ttg)),
                "collisions": sum(m["collisions"] for m in ms),
                "episodes_with_collision": sum(1 for m in ms if m["collisions"]),
                "fell": sum(1 for m in ms if m["fell"]),
                "grounding_answers": sum(x["answers"] for x in g) if g else None,
                "grounding_precision_iou50": _r(hits / boxed) if boxed else None,
                "grounding_precision_ci95": _ci(wilson(hits, boxed)),
                "grounding_recall_iou50": _r(hits / visible) if visible else None,
                "grounding_recall_ci95": _ci(wilson(hits, visible)),
                "grounding_mean_iou": _r(float(np.mean(ious))) if ious else None,
                "wrong_object": sum(x["wrong_object"] for x in g) if g else None,
                "vlm_latency_ms_mean": _r(float(np.mean(lat)), 1) if lat else None,
                "memory_objects": remembered if mem else None,
                "memory_phantoms": sum(x["phantoms"] for x in mem) if mem else None,
                "memory_phantom_rate": _r(sum(x["phantoms"] for x in mem) / remembered) if remembered else None,
                "memory_mean_error_m": _r(float(np.mean(errs)), 3) if errs else None,
                "wall_s_per_episode": _r(float(np.mean([m["wall_s"] for m in ms])), 2),
                "episodes_per_hour_last_session": _r(3600 * len(last) / span, 1) if span > 0 else None,
                "workers_last_session": last[-1].get("workers"),
                "speed": "fast" if cfg.get("fast") else f"rtf {cfg.get('rtf')}",
                "git_commit": cfg.get("git", {}).get("commit"),
                "run_ids": sorted({r["config"]["run_id"] for r in rows}),
                "houses": by_house(ms),
            }
        )
    return out


def _pct(v: float | None) -> str:
    return "n/a" if v is None else f"{100 * v:.1f} %"


def _range(ci: list[float] | None, pct: bool = True) -> str:
    if ci is None:
        return ""
    return f" [{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]" if pct else f" [{ci[0]:.3f}, {ci[1]:.3f}]"


def write_report(out: Path) -> dict[str, Any]:
    """(Re)write summary.json, report.md and the plots of an eval folder; returns the summary."""
    lines = read_jsonl(out / "results.jsonl")
    rows = summarize(lines)
    configs = {}
    for line in lines:
        c = line["config"]
        configs[c["run_id"]] = c
    summary = {
        "groups": rows,
        "intervals": "95 %: Wilson score for rates; percentile bootstrap (10,000 resamples, seed 0) for means",
        "spl": "success * L / max(P, L); L = straight-line start-to-goal surface distance minus the stop distance",
        "runs": list(configs.values()),
    }
    write_json(out / "summary.json", summary)
    plots = _plots(out, rows, lines)
    md = [
        "# go2vlm eval report",
        "",
        "Every episode in `results.jsonl`, with its exact configuration; this page is rewritten by every run",
        "(`go2vlm eval --report --out DIR` rewrites it alone). 95 % intervals: Wilson for rates, percentile",
        "bootstrap for means. SPL: go-to episodes only, shortest path = straight-line distance from the start",
        "to the object's surface minus the commander's stop distance (0.8 m). Memory: the object memory at",
        "each episode's end, summed over the episodes: objects remembered, phantoms (no body of the label",
        "within 1 m), and the mean error of the others (apps/episodes/metrics.py).",
        "",
        "| suite | perception | model | added latency (s) | episodes | success [95 % CI] | SPL [95 % CI] | "
        "time to goal (s) | collisions | fell | grounding precision / recall @0.5 | mean IoU | VLM latency (ms) | "
        "memory: objects / phantoms / mean error (m) | episodes/h |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        spl = "n/a" if r["spl_mean"] is None else f"{r['spl_mean']:.3f}{_range(r['spl_ci95'], pct=False)}"
        ttg = "n/a" if r["time_to_goal_s_mean"] is None else f"{r['time_to_goal_s_mean']:.1f}"
        pr = (
            "n/a"
            if r["grounding_precision_iou50"] is None and r["grounding_recall_iou50"] is None
            else f"{_pct(r['grounding_precision_iou50'])} / {_pct(r['grounding_recall_iou50'])}"
        )
        iou = "n/a" if r["grounding_mean_iou"] is None else f"{r['grounding_mean_iou']:.3f}"
        lat = "n/a" if r["vlm_latency_ms_mean"] is None else f"{r['vlm_latency_ms_mean']:.0f}"
        eph = "n/a" if r["episodes_per_hour_last_session"] is None else f"{r['episodes_per_hour_last_session']:.0f}"
        added = "-" if r["answer_latency_s"] is None else f"{r['answer_latency_s']:g}"
        mem = "n/a" if r["memory_objects"] is None else (
            f"{r['memory_objects']} / {r['memory_phantoms']} ({_pct(r['memory_phantom_rate'])}) / "
            + ("n/a" if r["memory_mean_error_m"] is None else f"{r['memory_mean_error_m']:.2f}")
        )  # fmt: skip
        md.append(
            f"| {r['suite']} | {r['perception']} | {r['model'] or '-'} | {added} | {r['episodes']} | "
            f"{_pct(r['success_rate'])}{_range(r['success_rate_ci95'])} | {spl} | {ttg} | {r['collisions']} | "
            f"{r['fell']} | {pr} | {iou} | {lat} | {mem} | {eph} |"
        )
    md += ["", "By task kind (successes / episodes):", ""]
    for r in rows:
        kinds = ", ".join(f"{k} {v['success']}/{v['episodes']}" for k, v in r["success_by_kind"].items())
        lat = "" if r["answer_latency_s"] is None else f" / {r['answer_latency_s']:g} s late"
        md.append(f"- {r['suite']} / {r['perception']}{' / ' + r['model'] if r['model'] else ''}{lat}: {kinds}")
    for r in rows:  # generated houses: by number of doors and by narrowest door
        h = r.get("houses")
        if not h:
            continue
        md += ["", f"### {_label(r, ' / ')}: {h['houses']} generated houses ({h['replaced_seeds']} seeds replaced)", ""]
        for title, cells in (("doors between spawn and object", h["by_doors"]),
                             ("narrowest door on the way (m)", h["by_narrowest_door_m"])):  # fmt: skip
            md += [f"| {title} | episodes | success [95 % CI] | SPL | time to goal (s) |", "|---|---|---|---|---|"]
            for key, c in cells.items():
                spl = "n/a" if c["spl_mean"] is None else f"{c['spl_mean']:.3f}"
                ttg = "n/a" if c["time_to_goal_s_mean"] is None else f"{c['time_to_goal_s_mean']:.1f}"
                md.append(f"| {key} | {c['episodes']} | {_pct(c['success_rate'])}{_range(c['success_rate_ci95'])} "
                          f"| {spl} | {ttg} |")  # fmt: skip
            md.append("")
    md += ["", *[f"![{name}]({name})" for name in plots], ""]
    md += ["## Runs", ""]
    for c in configs.values():
        md.append(
            f"- `{c['run_id']}`: suite {c['suite']} ({c['suite_file']}, sha256 {c['suite_sha256'][:12]}), "
            f"perception {c['perception']}, model {c.get('model') or '-'}, seed {c['seed']}, "
            f"{'fast' if c['fast'] else 'rtf ' + str(c['rtf'])}, git {c['git'].get('commit', '?')[:12]}"
            f"{' (dirty)' if c['git'].get('dirty') else ''}, "
            f"{c['machine'].get('cpu', '?')} x{c['machine'].get('cores')}"
        )
    write_text(out / "report.md", "\n".join(md) + "\n")
    return summary


def _plots(out: Path, rows: list[dict[str, Any]], lines: list[dict[str, Any]]) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = []
    if rows:  # success by variant, with the Wilson interval
        fig, ax = plt.subplots(figsize=(max(5, 1.2 * len(rows) + 2), 3.6))
        labels = [_label(r, "\n") for r in rows]
        rates = [r["success_rate"] or 0.0 for r in rows]
        lo = [rate - (r["success_rate_ci95"] or [rate, rate])[0] for rate, r in zip(rates, rows, strict=True)]
        hi = [(r["success_rate_ci95"] or [rate, rate])[1] - rate for rate, r in zip(rates, rows, strict=True)]
        ax.bar(range(len(rows)), rates, yerr=[lo, hi], capsize=4, color="tab:blue", alpha=0.8)
        ax.set_xticks(range(len(rows)), labels, fontsize=7)
        ax.set_ylim(0, 1.05)
        ax.set_ylabel("success rate (95 % Wilson CI)")
        ax.set_title("success by perception variant", fontsize=9)
        names.append(_save(fig, out / "success_by_variant.png", plt))
    # IoU histogram of every scored answer, per variant
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    any_iou = False
    for r in rows:
        ious = [v for line in lines if group_key(line) == _key(r)
                for v in ((line["metrics"].get("grounding") or {}).get("iou") or [])]  # fmt: skip
        if ious:
            any_iou = True
            ax.hist(ious, bins=20, range=(0, 1), alpha=0.5, label=_label(r, "/"))
    ax.axvline(0.5, color="0.4", lw=0.8, ls="--")
    ax.set_xlabel("IoU of the answer with the ground-truth box of its frame")
    ax.set_ylabel("answers")
    ax.set_title("grounding IoU" if any_iou else "grounding IoU (no scored answers: color variant)", fontsize=9)
    if any_iou:
        ax.legend(fontsize=7)
    names.append(_save(fig, out / "iou_hist.png", plt))
    # success against VLM latency, one point per episode (jittered), and the rate per latency bin
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    pts = [
        (line["metrics"]["vlm"]["latency_ms_mean"], float(line["metrics"]["success"]))
        for line in lines
        if (line["metrics"].get("vlm") or {}).get("latency_ms_mean") is not None
    ]
    if pts:
        lat, ok = np.array(pts).T
        rng = np.random.default_rng(0)
        ax.plot(lat, ok + rng.uniform(-0.04, 0.04, len(ok)), ".", alpha=0.6)
        edges = np.unique(np.percentile(lat, np.linspace(0, 100, 6)))
        if len(edges) > 1:
            idx = np.clip(np.digitize(lat, edges[1:-1]), 0, len(edges) - 2)
            mids = [(edges[i] + edges[i + 1]) / 2 for i in range(len(edges) - 1) if np.any(idx == i)]
            means = [ok[idx == i].mean() for i in range(len(edges) - 1) if np.any(idx == i)]
            ax.plot(mids, means, "-o", color="tab:red", label="success rate per latency bin")
            ax.legend(fontsize=7)
        ax.set_title("success against VLM latency", fontsize=9)
    else:
        ax.set_title("success against VLM latency (no VLM episodes yet)", fontsize=9)
    ax.set_xlabel("mean VLM latency in the episode (ms)")
    ax.set_ylabel("success (0/1)")
    ax.set_ylim(-0.1, 1.1)
    names.append(_save(fig, out / "success_vs_latency.png", plt))
    curves: dict[tuple[str, str, str], list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        if r["answer_latency_s"] is not None:
            curves[(r["suite"], r["perception"], r["model"] or "")].append(r)
    if curves:  # success and SPL against the added answer latency, with their 95 % bands
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8))
        for (suite, perception, model), rs in sorted(curves.items()):
            rs = sorted(rs, key=lambda r: r["answer_latency_s"])
            x = [r["answer_latency_s"] for r in rs]
            name = f"{suite}/{perception}{'/' + model if model else ''}"
            _band(ax1, x, [r["success_rate"] for r in rs], [r["success_rate_ci95"] for r in rs], name)
            _band(ax2, x, [r["spl_mean"] for r in rs], [r["spl_ci95"] for r in rs], name)
        for ax, what in ((ax1, "success rate (95 % Wilson CI)"), (ax2, "SPL, go to (95 % bootstrap CI)")):
            ax.set_xlabel("added answer latency (s)")
            ax.set_ylabel(what)
            ax.set_ylim(-0.02, 1.05)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
        ax1.set_title("success against the answer latency", fontsize=9)
        ax2.set_title("SPL against the answer latency", fontsize=9)
        names.append(_save(fig, out / "success_spl_vs_added_latency.png", plt))
    return names


def _key(r: dict[str, Any]) -> tuple[str, str, str, float]:
    lat = r["answer_latency_s"]
    return r["suite"], r["perception"], r["model"] or "", -1.0 if lat is None else float(lat)


def _label(r: dict[str, Any], sep: str) -> str:
    parts = [r["suite"], r["perception"], r["model"] or ""]
    if r["answer_latency_s"] is not None:
        parts.append(f"+{r['answer_latency_s']:g} s")
    return sep.join(p for p in parts if p)


def _band(ax: Any, x: list[float], y: list[float | None], ci: list[list[float] | None], name: str) -> None:
    pts = [(a, b, c) for a, b, c in zip(x, y, ci, strict=True) if b is not None]
    if not pts:
        return
    xs, ys, cs = zip(*pts, strict=True)
    line = ax.plot(xs, ys, "-o", label=name)[0]
    lo = [c[0] if c else v for v, c in zip(ys, cs, strict=True)]
    hi = [c[1] if c else v for v, c in zip(ys, cs, strict=True)]
    ax.fill_between(xs, lo, hi, color=line.get_color(), alpha=0.2)


def _save(fig: Any, path: Path, plt: Any) -> str:
    fig.tight_layout()
    with atomic(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
    return path.name
