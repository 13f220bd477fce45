"""Attack: orders and writers that should not be obeyed, in the middle of a goal, against the robot's
graph (`go2vlm launch mcp_sim --processes`), judged from the sim's ground truth (docs/safety.md, the
attack table). One graph for the module; the rows run in order and each ends with a still robot.

- Concurrent goals: two agents' go_to calls arrive at once: exactly one is accepted, the other refused
  with the reason (the busy check and the claim are one step). Then SIGTERM of the server: its
  `close()` stops the goal (`stop requested`), before the 2 s lease could (checked against a broken
  build: bridge_node.py's `close()` without its `stop`: the goal ends by its lease, and the test fails
  on the reason).
- A rogue /cmd_vel writer (2 m/s at 200 Hz) mid go to: the robot stops and takes nothing from it.
- A second safety gate mid go to: both refuse to drive; the robot stops.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator

import anyio
import pytest
from attackutil import Graph, last_status, moving, serve_http, still_from
from busutil import Procs, wait_for
from mcputil import Probe, http_client

pytest.importorskip("mcp")

pytestmark = pytest.mark.slow


class Rig:
    def __init__(self, procs: Procs) -> None:
        self.procs = procs
        self.graph = Graph(procs)
        self.probe = Probe().start()
        assert wait_for(lambda: len(self.probe.poses) > 20, 120), "no ground truth from the sim"
        from go2vlm.bus.topics import GOAL, SAFETY_STATUS

        self.goal = GOAL.publisher(self.probe)
        self.gates: dict[str, float] = {}  # /safety/status writer -> the sim time it was first heard
        SAFETY_STATUS.subscription(self.probe, self._on_gate, with_sender=True)
        assert wait_for(lambda: self.goal.matched >= 1, 30)

    def _on_gate(self, _msg: object, sender: object) -> None:
        self.gates.setdefault(str(getattr(sender, "guid", sender)), self.probe.sim_time)

    def send(self, text: str) -> None:
        from go2vlm.msgs.std_msgs import String

        self.goal.publish(String(data=text))

    def walk(self) -> float:
        """A go to the blue cylinder, walking: the sim time it walks at."""
        self.send("stop")
        assert wait_for(lambda: last_status(self.probe).get("state") == "stopped", 30)
        self.send("go to the blue cylinder")
        assert wait_for(lambda: moving(self.probe), 120), last_status(self.probe)
        return self.probe.sim_time


@pytest.fixture(scope="module")
def rig() -> Iterator[Rig]:
    procs = Procs()
    r = None
    try:
        r = Rig(procs)
        yield r
    finally:
        if r is not None:
            r.probe.shutdown()
        procs.stop_all()


def test_concurrent_goals_one_is_accepted(rig: Rig) -> None:
    p, _, url = serve_http(rig.procs, "127.0.0.1:0")
    results: list[tuple[str, bool, str]] = []

    async def main() -> None:
        from contextlib import AsyncExitStack

        async with AsyncExitStack() as stack:  # three agents connected first, then their calls at once
            clients = [await stack.enter_async_context(http_client(url)) for _ in range(3)]
            go = anyio.Event()

            async def one(client: object, obj: str) -> None:
                await go.wait()
                r = await client.call_tool("go_to", {"object": obj})  # type: ignore[attr-defined]
                results.append((obj, not r.is_error, r.content[0].text))

            async with anyio.create_task_group() as tg:
                for client, obj in zip(clients, ("blue cylinder", "red ball", "green box"), strict=True):
                    tg.start_soon(one, client, obj)
                await anyio.sleep(0.1)
                go.set()

    anyio.run(main)
    accepted = [r for r in results if r[1]]
    print(f"concurrent goals: {len(accepted)} of {len(results)} accepted; refused: "
          + "; ".join(r[2][:90] for r in results if not r[1]))  # fmt: skip
    assert len(results) == 3 and len(accepted) == 1, results
    assert all("busy" in r[2] or "being started" in r[2] for r in results if not r[1])
    rig.procs.stop(p, signal.SIGTERM, 20)  # it stops its goal on the way out
    assert wait_for(lambda: last_status(rig.probe).get("state") == "stopped", 30), last_status(rig.probe)
    # Stopped by close()'s `stop`, not by the lease running out (which would stop it as well).
    assert last_status(rig.probe).get("reason") == "stop requested", last_status(rig.probe)


def test_a_rogue_cmd_vel_writer_mid_go_to_stops_the_robot(rig: Rig) -> None:
    from go2vlm.bus import QOS_DEFAULT, Node
    from go2vlm.msgs.geometry_msgs import Twist, Vector3

    rig.walk()
    rogue = Node(node_name="rogue").start()
    pub = rogue.create_publisher(Twist, "/cmd_vel", QOS_DEFAULT)
    stop = threading.Event()

    def flood() -> None:
        while not stop.wait(0.005):
            pub.publish(Twist(linear=Vector3(2.0, 0.0, 0.0)))

    t_rogue = rig.probe.sim_time
    threading.Thread(target=flood, daemon=True).start()
    try:
        still = still_from(rig.probe, t_rogue)
        assert still is not None, "the robot never stopped under a rogue /cmd_vel writer"
        print(f"rogue /cmd_vel writer (2 m/s, 200 Hz) mid go to: the robot still {still - t_rogue:.2f} s (sim) "
              "after it began")  # fmt: skip
        assert still - t_rogue <= 2.0
    finally:
        stop.set()
        rogue.shutdown()
    rig.send("stop")


def test_a_second_gate_mid_go_to_stops_the_robot(rig: Rig) -> None:
    rig.walk()
    n = len(rig.gates)
    gate2 = rig.procs.start("run", "safety", "--name", "safety2", "--param", "use_sim_time=true")
    try:
        assert wait_for(lambda: len(rig.gates) > n, 120), "the second gate never reported"
        t_both = max(rig.gates.values())
        walking = moving(rig.probe)
        still = still_from(rig.probe, t_both, timeout_s=180)
        assert still is not None, "the robot never stopped with two gates"
        print(f"a second gate mid go to (walking when it reported: {walking}): the robot still "
              f"{still - t_both:.2f} s (sim) after both gates reported")  # fmt: skip
        assert still - t_both <= 2.0
        t = rig.probe.sim_time
        rig.send("go to the red ball")  # a new goal: nothing moves while two gates disagree
        assert wait_for(lambda: rig.probe.sim_time > t + 3.0, 60)
        assert rig.probe.moving_cmds_since(t) == [], "a gate drove with another gate on /cmd_vel"
    finally:
        rig.procs.stop(gate2, signal.SIGINT, 20)
    rig.send("stop")
