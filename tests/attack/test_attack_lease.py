"""Attack: keep a goal going after its owner died (docs/safety.md, the attack table; docs/mcp.md). An agent
starts `follow` over `go2vlm mcp --http` on the robot's graph (`go2vlm launch mcp_sim --processes`);
the MCP server's goal carries a lease that only it can renew. Then someone else on the bus tries to keep
the goal alive, and the MCP server is killed with -9:

- a plain re-send of the running goal on /goal (a UI repeating it): the goal carries on and keeps its
  lease (the status still shows one), so after the kill the commander stops it when the lease runs
  out: `stopped: the goal's lease expired`;
- a third party renewing the lease on /goal/lease, with secrets of its own and by replaying every
  renewal it hears (asking 60 s): each is refused (counted `lease_not_ours`) and, after the kill, the
  goal ends within the lease all the same.

In both the robot is still within the deadman + 1 s of the kill (sim time, from ground truth).

Checked once against deliberately broken builds, each failing here: `CommanderNode.set_goal` that
drops the lease on a re-send, as before (the status shows no lease after the re-send: the first
assert of that row fails; after the kill the follow would run to max_goal_s); `Lease.renew` without
its proof check (the third party's renewals are taken: `lease_not_ours` stays 0 and the lease
reason never comes).
"""

from __future__ import annotations

import json
import os
import signal
import time

import anyio
import pytest
from attackutil import Graph, last_status, serve_http, still_from, walk_with_mcp
from busutil import Procs, wait_for
from mcputil import Probe

from go2vlm.behavior.lease import MAX_LEASE_S, LeaseKeys
from go2vlm.bus import Node
from go2vlm.bus.topics import GOAL, GOAL_LEASE
from go2vlm.msgs.std_msgs import String

pytest.importorskip("mcp")

pytestmark = pytest.mark.slow
DEADMAN_S = 5.0


class ThirdParty(Node):
    """Someone else on the bus: while `active`, renews the running goal's lease with secrets of its
    own every 0.1 s, and replays every renewal it hears, asking for 60 s."""

    name = "lease_thief"

    def __init__(self) -> None:
        super().__init__()
        self.active = False
        self.keys = LeaseKeys()
        self.mine: set[str] = set()
        self.sent = self.replayed = 0
        self.pub = GOAL_LEASE.publisher(self)
        GOAL_LEASE.subscription(self, self._heard)
        self.create_timer(0.1, self._renew, wall=True)

    def _send(self, text: str) -> None:
        self.mine.add(text)
        self.pub.publish(String(data=text))
        self.sent += 1

    def _renew(self) -> None:
        if self.active:
            self._send(self.keys.renewal(MAX_LEASE_S))

    def _heard(self, msg: String) -> None:
        if self.active and msg.data not in self.mine:
            self._send(json.dumps({**json.loads(msg.data), "s": MAX_LEASE_S}))
            self.replayed += 1


def _renewals(probe: Probe) -> int:
    """The running goal's lease renewals, as /commander/status says (-1: no lease)."""
    lease = last_status(probe).get("lease") or {}
    return int(lease.get("renewals", -1))


def _refused(probe: Probe) -> int:
    """Lease renewals the commander refused (`lease_not_ours`), as /commander/status says."""
    return int((last_status(probe).get("counters") or {}).get("lease_not_ours", 0))


def test_a_resent_or_stranger_renewed_goal_still_ends_within_its_lease(procs: Procs) -> None:
    Graph(procs)
    thief = ThirdParty()
    probe = Probe().start()
    thief.start()
    goal = GOAL.publisher(probe)
    found: dict[str, dict[str, object]] = {}
    try:
        assert wait_for(lambda: len(probe.poses) > 20, 120), "no ground truth from the sim"
        for row in ("re-send", "third-party renewal"):
            p, _, url = serve_http(procs, "127.0.0.1:0", "--deadman", str(DEADMAN_S))
            text = anyio.run(walk_with_mcp, url, "follow", probe)
            if row == "re-send":
                assert wait_for(lambda: goal.matched >= 1, 30)
                for _ in range(3):
                    goal.publish(String(data=text))  # the same goal, plain text
                n = _renewals(probe)
                # The goal carries on with its lease: renewed by its owner since the re-sends.
                assert wait_for(lambda: _renewals(probe) > n + 2, 10), last_status(probe)  # noqa: B023
            else:
                thief.active = True
                assert wait_for(lambda: thief.replayed >= 3 and thief.sent >= 10, 10), (thief.replayed, thief.sent)
            t_kill, wall_kill = probe.sim_time, time.monotonic()
            os.kill(p.pid, signal.SIGKILL)
            assert wait_for(lambda: "lease expired" in str(last_status(probe).get("reason")), DEADMAN_S + 30), (
                last_status(probe)
            )
            wall_stopped = time.monotonic() - wall_kill
            still = still_from(probe, t_kill)
            thief.active = False
            assert still is not None, f"{row}: the robot never stood still after the kill"
            st = last_status(probe)
            assert st["state"] == "stopped" and st["lease"] is None and st["goal"] != text, st
            if row == "third-party renewal":  # every renewal it sent is refused, once the last has arrived
                caught_up = lambda: _refused(probe) >= thief.sent - 5  # noqa: E731 - a few may be lost on the way
                assert wait_for(caught_up, 10), (_refused(probe), thief.sent)
            refused = _refused(probe)
            found[row] = {"commander_stopped_wall_s": round(wall_stopped, 2), "still_s": round(still - t_kill, 2),
                          "renewals_refused": refused, "third_party_sent": thief.sent}  # fmt: skip
            print(f"{row}, then kill -9 of the MCP server: {found[row]}")
            assert still - t_kill <= DEADMAN_S + 1.0, found
    finally:
        thief.shutdown()
        probe.shutdown()
    assert set(found) == {"re-send", "third-party renewal"}
