"""Attack: kill -9 one process of the robot's graph in the middle of a goal (docs/safety.md, the attack
table). The graph runs one process per node (`go2vlm launch mcp_sim --processes`: the MuJoCo sim, the
target_tracker, the object memory, the commander, the follower, the safety gate) and an agent drives
it through `go2vlm mcp --http` with the official SDK client; the outcome is judged from the sim's
ground truth.

- The MCP server, mid `follow` and mid `go to`: the commander's goal lease runs out and the commander
  stops the goal itself; the robot is still within the deadman + 1 s (the assertion is that bound).
- The agent quits a stdio server (stdin EOF) mid `follow`: the server's `close()` sends `stop` on its way
  out, so the goal ends `stop requested`, not by its lease (whose 2 s would stop it too). Checked
  against a broken build: bridge_node.py's `close()` without its `stop`: the goal ends `the goal's
  lease ... expired`, and the test fails on the reason.
- The commander: the gate times its input out; the robot stops.
- The target_tracker: nothing confirms the target any more; the go to goes on, if at all, only on
  what the object memory remembered, comes to rest and touches nothing.
- The object memory: the go to carries on with the tracker and reaches the cylinder, no collision.
- The vlm node (the shipped tiny grounder, on the CPU, grounding for the target_tracker): the tracker
  carries the target on its own for at most max_grounding_age_s, the go to comes to rest (reached, or
  stopped for want of answers) and touches nothing.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import anyio
import pytest
from attackutil import Graph, last_status, min_clearance, moving, serve_http, still_from
from busutil import Procs, wait_for
from mcputil import Probe, data, http_client, stdio_client

pytest.importorskip("mcp")

pytestmark = pytest.mark.slow
DEADMAN_S = 5.0
STOP_REQUESTED = "stop requested"  # the commander's reason for a `stop` goal (behavior/mission.py)


async def _call_when_a_gate_reports(client: object, tool: str) -> None:
    """tool("blue cylinder"), once the server joining the bus has heard the gate (discovery takes a while)."""
    for _ in range(120):
        r = await client.call_tool(tool, {"object": "blue cylinder"})  # type: ignore[attr-defined]
        if not (r.is_error and "no safety gate reports" in r.content[0].text):
            data(r)
            return
        await anyio.sleep(0.25)
    raise AssertionError("the server never heard the gate")


async def _start_and_walk(url: str, tool: str, probe: Probe) -> None:
    """Call tool("blue cylinder") and poll status() until the robot walks."""
    async with http_client(url) as client:
        await _call_when_a_gate_reports(client, tool)
        for _ in range(400):
            data(await client.call_tool("status", {}))
            if moving(probe):
                return
            await anyio.sleep(0.25)
    raise AssertionError(f"{tool}: the robot never walked; commander {last_status(probe)}")


def test_kill_9_the_mcp_server_mid_follow_and_mid_go_to(procs: Procs) -> None:
    Graph(procs)
    probe = Probe().start()
    found: dict[str, dict[str, float]] = {}
    try:
        assert wait_for(lambda: len(probe.poses) > 20, 120), "no ground truth from the sim"
        for tool in ("follow", "go_to"):
            p, _, url = serve_http(procs, "127.0.0.1:0", "--deadman", str(DEADMAN_S))
            anyio.run(_start_and_walk, url, tool, probe)
            t_kill, wall_kill = probe.sim_time, time.monotonic()
            os.kill(p.pid, signal.SIGKILL)
            assert wait_for(lambda: "lease" in (last_status(probe).get("reason") or ""), DEADMAN_S + 30), last_status(
                probe
            )
            wall_stopped = time.monotonic() - wall_kill
            still = still_from(probe, t_kill)
            assert still is not None, f"{tool}: the robot never stood still after the kill"
            found[tool] = {"still_s": still - t_kill, "commander_stopped_wall_s": wall_stopped}
            print(f"kill -9 mcp mid {tool}: the commander stopped it {wall_stopped:.2f} s (wall) after the kill; "
                  f"the robot still {still - t_kill:.2f} s (sim) after it")  # fmt: skip
            assert still - t_kill <= DEADMAN_S + 1.0, found
            st = last_status(probe)
            assert st["state"] == "stopped" and st["lease"] is None, st
        # stdin EOF: the agent that started a stdio server quits; the server stops its goal on the way out.
        t_quit = anyio.run(_stdio_follow_then_quit, probe)
        assert wait_for(lambda: last_status(probe).get("state") == "stopped", DEADMAN_S + 30), last_status(probe)
        # Stopped by close()'s `stop`, not by the lease running out (which would stop it as well).
        assert last_status(probe).get("reason") == STOP_REQUESTED, last_status(probe)
        still = still_from(probe, t_quit)
        assert still is not None
        found["stdin EOF"] = {"still_s": still - t_quit}
        print(f"stdin EOF mid follow: {last_status(probe).get('reason')}; the robot still {still - t_quit:.2f} s (sim)")
        assert still - t_quit <= DEADMAN_S + 1.0
    finally:
        probe.shutdown()
    assert set(found) == {"follow", "go_to", "stdin EOF"}


async def _stdio_follow_then_quit(probe: Probe) -> float:
    """follow over a stdio server joining the bus; the agent quits (stdin EOF) while the robot walks."""
    async with stdio_client("--deadman", str(DEADMAN_S)) as client:
        await _call_when_a_gate_reports(client, "follow")
        for _ in range(400):
            data(await client.call_tool("status", {}))
            if moving(probe, 0.1):
                break
            await anyio.sleep(0.25)
        return probe.sim_time


def _goal(probe: Probe, text: str) -> None:
    from go2vlm.bus.topics import GOAL
    from go2vlm.msgs.std_msgs import String

    pub = GOAL.publisher(probe)
    assert wait_for(lambda: pub.matched >= 1, 30)
    pub.publish(String(data=text))


def remembers(probe: Probe) -> bool:
    """The commander's status says the object memory holds an object (the cylinder, in this world)."""
    return (last_status(probe).get("memory") or {}).get("objects", 0) >= 1


@pytest.mark.parametrize("victim", ["commander", "target_tracker", "object_memory"])
def test_kill_9_a_node_mid_go_to(procs: Procs, victim: str) -> None:
    graph = Graph(procs)
    probe = Probe().start()
    try:
        assert wait_for(lambda: len(probe.poses) > 20, 120), "no ground truth from the sim"
        _goal(probe, "go to the blue cylinder")
        # mid go to: walking, with the cylinder in the object memory (what the rest may go on)
        assert wait_for(lambda: moving(probe) and remembers(probe), 120), last_status(probe)
        t_kill = probe.sim_time
        graph.kill9(victim)
        if victim == "object_memory":
            # Nothing it said is needed to finish: the tracker confirms the cylinder, the walk ends reached.
            assert wait_for(lambda: last_status(probe).get("state") == "reached", 180), last_status(probe)
            assert min_clearance(probe, t_kill) > 0.0
            return
        if victim == "target_tracker":
            # Nothing confirms the cylinder any more: the commander goes on, if at all, only on what the
            # object memory remembered (turn to it, walk to its remembered place, look); it comes to rest
            # and never touches anything.
            still = still_from(probe, t_kill, hold_s=3.0, timeout_s=240.0)
            assert still is not None, f"the robot never came to rest: {last_status(probe)}"
            gap = min_clearance(probe, t_kill)
            print(
                f"kill -9 target_tracker mid go to: at rest {still - t_kill:.2f} s (sim) after it, "
                f"{last_status(probe).get('state')} ({last_status(probe).get('basis')}), nearest {gap:.2f} m"
            )
            assert gap > 0.0
            return
        still = still_from(probe, t_kill)
        assert still is not None, "the robot never stood still after the commander died"
        print(f"kill -9 commander mid go to: the robot still {still - t_kill:.2f} s (sim) after it")
        assert still - t_kill <= 2.0
    finally:
        probe.shutdown()


def test_kill_9_the_vlm_mid_go_to(procs: Procs, tmp_path: Path) -> None:
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    import yaml

    from go2vlm.launch.launcher import resolve
    from testing_support.tiny_grounder import grounder_checkpoint, grounder_node_params

    graph_file = tmp_path / "episode_vlm.yaml"
    nodes = yaml.safe_load(resolve("episode_vlm").read_text())
    for n in nodes:
        if n["node"] == "vlm":
            n["params"].update(model=str(grounder_checkpoint()), backend="transformers", **grounder_node_params())
    graph_file.write_text(yaml.safe_dump(nodes))
    graph = Graph(procs, str(graph_file))
    probe = Probe().start()
    try:
        assert wait_for(lambda: len(probe.poses) > 20, 180), "no ground truth from the sim"
        _goal(probe, "go to the blue cylinder")
        walking = lambda: moving(probe, 0.1) and last_status(probe).get("state") == "approaching" and remembers(probe)  # noqa: E731
        assert wait_for(walking, 300), last_status(probe)
        t_kill = probe.sim_time
        graph.kill9("vlm")
        still = still_from(probe, t_kill, hold_s=3.0, timeout_s=240.0)
        assert still is not None, f"the robot never came to rest: {last_status(probe)}"
        gap = min_clearance(probe, t_kill)
        print(
            f"kill -9 vlm mid go to: at rest {still - t_kill:.2f} s (sim) after it, "
            f"{last_status(probe).get('state')}: {last_status(probe).get('reason')}; nearest {gap:.2f} m"
        )
        assert gap > 0.0
    finally:
        probe.shutdown()
