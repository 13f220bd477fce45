"""Attack: raise the goal bounds while the robot runs (docs/safety.md, the attack table). Anyone on the bus
can call a node's parameter services (`go2vlm param set`, `ros2 param set`); `max_goal_s` (up to
86,400 s) and `max_go_to_m` (up to 500 m) are live so that they may be lowered. Here real processes: a
commander and a safety gate, and `go2vlm param` as the attacker.

- Raising `max_goal_s` or `max_go_to_m` (before a goal, or while one runs after a lowering) is
  refused, exit 2, with the reason ("loosening a safety limit at runtime is refused (...)"), and the
  value stays; lowering is taken at once.
- The lowered bound holds: a follow (which never ends by itself) stops at the lowered max_goal_s, with
  that reason, though a raise was asked for while it ran.
- The gate's speed limits fall under the same rule (one rule for every node).

Checked once against a deliberately broken build: the parameter service without its `loosened`
check (bus/param_services.py): the raise is taken (exit 0), the first assert on the refusal fails.
"""

from __future__ import annotations

import json
import subprocess
import time

from busutil import GO2VLM, Procs, env, wait_for

from go2vlm.bus import Node, running
from go2vlm.bus.topics import COMMANDER_STATUS, GOAL
from go2vlm.msgs.std_msgs import String


def _param(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*GO2VLM, "param", *args], capture_output=True, text=True, timeout=60, env=env())


def _value(node: str, name: str) -> str:
    out = _param("get", node, name)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_a_live_raise_of_the_goal_bounds_is_refused(procs: Procs) -> None:
    procs.start("run", "commander")
    procs.start("run", "safety")
    probe = Node(node_name="bounds_attack_probe", parameter_services=False)
    status: list[dict[str, object]] = []
    stopped_at: list[float] = []  # when a status first said stopped (wall)

    def on_status(m: String) -> None:
        status.append(json.loads(m.data))
        if status[-1].get("state") == "stopped" and not stopped_at:
            stopped_at.append(time.monotonic())

    COMMANDER_STATUS.subscription(probe, on_status)
    goal = GOAL.publisher(probe)
    found: dict[str, object] = {}
    with running(probe):
        assert wait_for(lambda: bool(status) and goal.matched >= 1, 60), "no commander"
        for name, value in (("max_goal_s", "86400"), ("max_go_to_m", "500")):
            out = _param("set", "commander", name, value)
            assert out.returncode == 2, (name, out.stdout, out.stderr)
            assert f"loosening a safety limit at runtime is refused ({name} " in out.stderr, out.stderr
        assert _value("commander", "max_goal_s") == "Double value is: 900.0"
        assert _value("commander", "max_go_to_m") == "Double value is: 25.0"

        # Lowered: taken at once. Raised again while a follow runs: refused, and the follow stops at
        # the lowered bound, with that reason.
        out = _param("set", "commander", "max_goal_s", "3")
        assert out.returncode == 0, out.stderr
        stopped_at.clear()
        t0 = time.monotonic()
        goal.publish(String(data="follow the red ball"))
        assert wait_for(lambda: status[-1].get("goal") == "follow the red ball", 10), status[-1:]
        out = _param("set", "commander", "max_goal_s", "900")
        assert out.returncode == 2 and "(max_goal_s 3 -> 900)" in out.stderr, out.stderr
        assert wait_for(lambda: status[-1].get("state") == "stopped", 60), status[-1:]
        found["follow stopped after s (wall)"] = round(stopped_at[0] - t0, 2)
        reason = str(status[-1].get("reason"))
        assert "max_goal_s = 3 s" in reason, reason
        found["reason"] = reason

        # The same rule in the gate: a raise of a speed limit is refused with the same reason.
        out = _param("set", "safety", "max_vx_forward", "2.0")
        assert out.returncode == 2 and "loosening a safety limit at runtime is refused (max_vx_forward 1 -> 2)" in (
            out.stderr
        ), out.stderr
    print(f"a live raise of the goal bounds: {found}")
