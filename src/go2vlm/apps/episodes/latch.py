"""The e-stop and an episode: refuse to start one on a latched robot, and say what a latch did to a run.

Before: `refuse_if_latched` finds the safety gate of the episode's graph, the robot it commands and
its latch (the gate's latch file for that robot and domain, or a `go2vlm estop` holding the e-stop on
the domain) and raises `RobotLatched` (exit 2) with one line: since when, who latched it, and the
release command. It runs before any node of the episode is built, so the sim never starts.

After: `estop_metrics` turns the gate's /safety/status over the run into the latches that held the
robot: when (sim seconds from the start), for how long, and why.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from go2vlm.errors import UsageError
from go2vlm.safety.estop import RELEASE_COMMAND, find_latch

__all__ = ["RobotLatched", "estop_metrics", "gate_latch", "refuse_if_latched", "stopped_line"]


class RobotLatched(UsageError):
    """The robot an episode would command is latched: nothing is started (exit 2)."""


def gate_latch(entries: list[Any], domain_id: int) -> tuple[str, Path] | None:
    """(robot, latch file) of the safety gate among a graph's launch entries, or None without a gate."""
    from go2vlm.bus import build_node_config
    from go2vlm.safety.gate_node import SafetyGateConfig, gate_latch_path

    gate = next((e for e in entries if e.kind == "safety"), None)
    if gate is None:
        return None
    cfg, _ = build_node_config(SafetyGateConfig, gate.params, node=gate.name)
    return cfg.robot, gate_latch_path(cfg, domain_id)


def refuse_if_latched(entries: list[Any], domain_id: int | None, interface: str | None, wait_s: float = 1.5) -> None:
    """RobotLatched when the gate of `entries` would start latched on `domain_id` (None: ROS_DOMAIN_ID)."""
    from go2vlm.bus.domain import domain_id_from_env

    did = domain_id if domain_id is not None else domain_id_from_env()
    found = gate_latch(entries, did)
    if found is None:
        return
    robot, path = found
    state = find_latch(path, did, interface, wait_s)
    if state is not None:
        raise RobotLatched(state.line(robot, did))


def estop_metrics(events: list[tuple[float, bool, str]], t0: float, t_end: float) -> dict[str, Any]:
    """The latches in a run from the gate's e-stop state over time ((sim t, engaged, why), in order):
    {latched, latched_s, latched_at_end, latches: [{at_s, for_s, why, released}]}, times in sim
    seconds from `t0`; a latch from before the start counts from 0."""
    latches: list[dict[str, Any]] = []
    open_: dict[str, Any] | None = None
    for t, engaged, why in events:
        if engaged and open_ is None:
            open_ = {"at_s": round(max(0.0, t - t0), 2), "why": why}
        elif not engaged and open_ is not None:
            open_.update(for_s=round(max(0.0, t - t0 - open_["at_s"]), 2), released=True)
            latches.append(open_)
            open_ = None
    if open_ is not None:
        open_.update(for_s=round(max(0.0, t_end - t0 - open_["at_s"]), 2), released=False)
        latches.append(open_)
    return {
        "latched": bool(latches),
        "latched_s": round(sum(x["for_s"] for x in latches), 2),
        "latched_at_end": open_ is not None,
        "latches": latches,
    }


def stopped_line(estop: dict[str, Any] | None) -> str | None:
    """'STOPPED by the e-stop ...' for a run a latch held, else None."""
    if not estop or not estop.get("latched"):
        return None
    first = estop["latches"][0]
    more = f", {len(estop['latches'])} latches" if len(estop["latches"]) > 1 else ""
    held = "still latched at the end" if estop["latched_at_end"] else "released"
    why = f": {first['why']}" if first.get("why") else ""
    tail = f"; release it with `{RELEASE_COMMAND}`" if estop["latched_at_end"] else ""
    return f"STOPPED by the e-stop at {first['at_s']:.1f} s for {estop['latched_s']:.1f} s{more} ({held}{why}){tail}"
