"""probe: a small real node for bus tests (parameters, remapping, timers, shutdown, discovery).

Topics
  subscribes  /probe/in    std_msgs/String  (default QoS)
  publishes   /probe/out   std_msgs/String  prefix + every received text
              /probe/tick  std_msgs/String  "tick N" every 1/rate seconds

Run it as a process exactly as `go2vlm run` runs a node: `python -m bus_probe_node run probe ...`
(with tests/bus on PYTHONPATH); the module registers itself in the node registry first.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from go2vlm.bus import Node, param
from go2vlm.msgs.std_msgs import String


@dataclass
class ProbeConfig:
    rate: float = param(5.0, help="tick rate in Hz", min=0.1, max=1000.0)
    prefix: str = param("echo: ", help="prepended to every echoed text")
    mode: str = param("echo", help="what to do with input", choices=("echo", "count"))
    repeat: int = param(1, help="publish each echo this many times", min=1, max=10)
    loud: bool = param(False, help="log every message")
    labels: list[str] = param(list, help="free-form labels")
    stuck_close: bool = param(False, help="close() never returns (a stuck driver, for shutdown tests)")


class ProbeNode(Node):
    name = "probe"
    Config = ProbeConfig

    def __init__(self, config: ProbeConfig | None = None, **kwargs: object) -> None:
        super().__init__(config, **kwargs)  # type: ignore[arg-type]
        self.ticks = 0
        self.received = 0
        self.out = self.create_publisher(String, "/probe/out")
        self.tick_pub = self.create_publisher(String, "/probe/tick")
        self.create_subscription(String, "/probe/in", self.on_in)
        self.create_timer(1.0 / self.config.rate, self.on_tick)

    def on_in(self, msg: String) -> None:
        self.received += 1
        if self.config.loud:
            self.log.info(f"got {msg.data!r}")
        text = msg.data if self.config.mode == "echo" else str(self.received)
        for _ in range(self.config.repeat):
            self.out.publish(String(data=self.config.prefix + text))

    def close(self) -> None:
        if self.config.stuck_close:
            self.log.info("close: stuck")
        while self.config.stuck_close:
            time.sleep(0.1)

    def on_tick(self) -> None:
        self.ticks += 1
        self.tick_pub.publish(String(data=f"tick {self.ticks}"))


def register() -> None:
    from go2vlm.launch import registry

    registry.NODES.setdefault("probe", "bus_probe_node:ProbeNode")


if __name__ == "__main__":
    register()
    from go2vlm.cli.main import main

    sys.exit(main(sys.argv[1:]))


def start(procs: Any, *args: str) -> subprocess.Popen[str]:
    """Start the probe as a real `go2vlm run`-style process, stopped with the `procs` fixture."""
    from busutil import env

    e = env()
    e["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).parent), e.get("PYTHONPATH", "")])
    p = subprocess.Popen(
        [sys.executable, "-m", "bus_probe_node", "run", "probe", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=e,
    )
    procs.procs.append(p)
    return p
