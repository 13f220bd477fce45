"""Helpers for the attack suite (tests/attack/): the robot's graph with one process per node (so one
node can be killed with -9), the MCP server beside it, and when the robot is still again (the sim's
ground truth)."""

from __future__ import annotations

import re
import subprocess
from typing import Any

from busutil import Output, Procs, wait_for
from mcputil import Probe, speed

STILL_M_S = 0.1  # a standing Go2 sways a few cm/s while its legs settle
STILL_RAD_S = 0.25


class Graph:
    """`go2vlm launch mcp_sim --processes`: the sim, target_tracker, object_memory, commander, follower
    and safety, each its own process; `pids[name]`."""

    def __init__(self, procs: Procs, launch: str = "mcp_sim") -> None:
        self.proc = procs.start("launch", launch, "--processes")
        self.out = Output(self.proc)
        assert self.out.wait_line("up: safety", 120), "".join(self.out.lines)[-3000:]
        self.pids = {m[1]: int(m[2]) for m in re.finditer(r"up: (\S+) \(\S+\) pid (\d+)", "".join(self.out.lines))}

    def kill9(self, name: str) -> None:
        import os
        import signal

        os.kill(self.pids[name], signal.SIGKILL)
        assert self.out.wait_line(f"died: {name} ", 30), "".join(self.out.lines)[-3000:]


def serve_http(procs: Procs, *args: str) -> tuple[subprocess.Popen[str], Output, str]:
    p = procs.start("mcp", "--http", *args)
    out = Output(p)
    assert out.wait_line("serving MCP on http://", 120), "".join(out.lines)[-3000:]
    url = re.search(r"(http://\S+/mcp)", "".join(out.lines))
    assert url is not None
    return p, out, url.group(1)


def moving(probe: Probe, min_speed: float = 0.2) -> bool:
    poses = probe.since(0.0)
    return len(poses) > 3 and speed(poses, len(poses) - 1)[0] > min_speed


def still_from(probe: Probe, t0: float, hold_s: float = 1.5, timeout_s: float = 120.0) -> float | None:
    """The sim time, from t0 on, after which the robot stayed still for at least hold_s of sim time
    (None if it never did within timeout_s of wall time): its stop, seen from ground truth."""

    def find() -> float | None:
        poses = probe.since(t0)
        for i in range(1, len(poses)):
            end = poses[-1][0]
            if end - poses[i][0] < hold_s:
                return None
            if all(speed(poses, j)[0] <= STILL_M_S and speed(poses, j)[1] <= STILL_RAD_S for j in range(i, len(poses))):
                return poses[i][0]
        return None

    got: list[float] = []

    def done() -> bool:
        t = find()
        if t is not None:
            got.append(t)
        return t is not None

    wait_for(done, timeout_s, period=0.5)
    return got[0] if got else None


def last_status(probe: Probe) -> dict[str, Any]:
    with probe.lock:
        return dict(probe.status[-1]) if probe.status else {}


def min_clearance(probe: Probe, t0: float, world: str = "vision_test") -> float:
    """The smallest gap (m) between the robot's footprint and the world's objects from sim time t0 on."""
    from go2vlm.geometry.footprint import Footprint, clearance
    from go2vlm.robot_profile.go2 import FOOTPRINT_LENGTH, FOOTPRINT_WIDTH
    from go2vlm.sim.worlds import world_footprints, world_model

    shapes = world_footprints(world_model(world)[0])
    robot = [Footprint.rect(p[1], p[2], p[3], FOOTPRINT_LENGTH, FOOTPRINT_WIDTH) for p in probe.since(t0)[::10]]
    return min(clearance(r, s) for r in robot for s in shapes.values())


async def walk_with_mcp(url: str, tool: str, probe: Probe, obj: str = "blue cylinder") -> str:
    """An agent calls tool(obj) on the MCP server at url (once the server has heard the gate) and polls
    status() until the robot walks; the goal's text as the commander took it."""
    import anyio
    from mcputil import data, http_client

    async with http_client(url) as client:
        for _ in range(120):
            r = await client.call_tool(tool, {"object": obj})
            if not (r.is_error and "no safety gate reports" in r.content[0].text):
                data(r)
                break
            await anyio.sleep(0.25)
        else:
            raise AssertionError("the server never heard the gate")
        for _ in range(400):
            data(await client.call_tool("status", {}))
            if moving(probe):
                return str(last_status(probe).get("goal"))
            await anyio.sleep(0.25)
    raise AssertionError(f"{tool}: the robot never walked; commander {last_status(probe)}")
