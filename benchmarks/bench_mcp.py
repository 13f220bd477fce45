"""The cost of `go2vlm mcp`: its start-up time and its CPU share while idle and while a goal runs.

    python benchmarks/bench_mcp.py                 # 3 start-ups each, 20 s idle, one go_to
    python benchmarks/bench_mcp.py --runs 1 --idle 10

Start-up: from starting the process to the SDK's stdio client holding the tool list (what an agent
waits for), for `go2vlm mcp` joining a running robot graph and for `go2vlm mcp --sim` (which also
starts the sim graph, kinematic physics). CPU: the server alone (`go2vlm mcp --http`, one process;
user + system time of it and its children over wall time) beside the robot graph of `--sim` run as
its own `go2vlm launch mcp_sim` process: idle (no client calls) and during "go to the blue cylinder"
while the client polls status() once a second, as an agent would. Wall-clock figures: quote the load
average printed with them.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import re
import statistics
import subprocess
import sys
import tempfile
import time
from typing import Any

import anyio
import psutil

GO2VLM = [sys.executable, "-m", "go2vlm"]


def cpu_seconds(proc: psutil.Process) -> float:
    total = 0.0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            t = p.cpu_times()
            total += t.user + t.system
        except psutil.NoSuchProcess:
            pass
    return total


async def startup(args: list[str], env: dict[str, str]) -> float:
    from mcp import Client, StdioServerParameters

    t0 = time.perf_counter()
    params = StdioServerParameters(command=sys.executable, args=["-m", "go2vlm", "mcp", *args], env=env)
    async with Client(params, read_timeout_seconds=120) as client:
        await client.list_tools()
        return time.perf_counter() - t0


async def load(url: str, proc: psutil.Process, idle_s: float) -> dict[str, Any]:
    from mcp import Client

    out: dict[str, Any] = {}
    async with Client(url, read_timeout_seconds=120) as client:
        for _ in range(60):  # the robot graph is up when the gate reports
            st = json.loads((await client.call_tool("status", {})).content[0].text)
            if st["safety"] is not None and st["commander"] is not None:
                break
            await anyio.sleep(1.0)
        c0, w0 = cpu_seconds(proc), time.perf_counter()
        await anyio.sleep(idle_s)
        out["idle_cores"] = (cpu_seconds(proc) - c0) / (time.perf_counter() - w0)
        c0, w0 = cpu_seconds(proc), time.perf_counter()
        await client.call_tool("go_to", {"object": "blue cylinder"})
        state = ""
        while time.perf_counter() - w0 < 120:
            st = json.loads((await client.call_tool("status", {})).content[0].text)
            state = st["commander"]["state"]
            if state in ("reached", "not_found", "stopped"):
                break
            await anyio.sleep(1.0)
        out["goal_cores"] = (cpu_seconds(proc) - c0) / (time.perf_counter() - w0)
        out["goal_s"] = time.perf_counter() - w0
        out["goal_state"] = state
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--idle", type=float, default=20.0, help="seconds idle for the CPU share")
    ap.add_argument("--json", default=None, help="also write the results here")
    a = ap.parse_args()
    env = dict(os.environ)
    env.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 230)))
    env.setdefault("GO2VLM_IFACE", "lo")
    env.setdefault("MUJOCO_GL", "egl")
    env["XDG_STATE_HOME"] = tempfile.mkdtemp(prefix="bench-mcp-")
    print(f"domain {env['ROS_DOMAIN_ID']}, load average {os.getloadavg()}", flush=True)
    graph = subprocess.Popen([*GO2VLM, "launch", "mcp_sim", "-p", "sim.mode=kinematic"], env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    try:
        joined = [anyio.run(startup, [], env) for _ in range(a.runs)]
        server = subprocess.Popen([*GO2VLM, "mcp", "--http", "0"], env=env, stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, text=True)  # fmt: skip
        assert server.stdout is not None
        url = None
        for line in server.stdout:
            m = re.search(r"(http://\S+/mcp)", line)
            if m:
                url = m.group(1)
                break
        assert url is not None
        cost = anyio.run(load, url, psutil.Process(server.pid), a.idle)
        server.terminate()
        server.wait(20)
    finally:
        graph.terminate()
        graph.wait(30)
    sim_env = {**env, "ROS_DOMAIN_ID": str((int(env["ROS_DOMAIN_ID"]) + 1 - 100) % 131 + 100)}
    with_sim = [anyio.run(startup, ["--sim", "--mode", "kinematic"], sim_env) for _ in range(a.runs)]
    result = {
        "startup_s_joining": [round(v, 2) for v in joined],
        "startup_s_with_sim": [round(v, 2) for v in with_sim],
        "startup_s_joining_median": round(statistics.median(joined), 2),
        "startup_s_with_sim_median": round(statistics.median(with_sim), 2),
        "idle_cores": round(cost["idle_cores"], 4),
        "goal_cores": round(cost["goal_cores"], 4),
        "goal_s": round(cost["goal_s"], 1),
        "goal_state": cost["goal_state"],
        "load_average": os.getloadavg(),
    }
    print(json.dumps(result, indent=2))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(result, f, indent=2)


if __name__ == "__main__":
    main()
