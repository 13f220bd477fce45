"""Helpers for the `go2vlm mcp` tests: the official SDK's own client (over stdio or streamable HTTP)
against the server as a real process, and a probe node that watches the sim's ground truth."""

from __future__ import annotations

import json
import math
import sys
import threading
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from busutil import env

from go2vlm.bus import QOS_CLOCK, QOS_DEFAULT, QOS_LATCHED, Node
from go2vlm.msgs.geometry_msgs import Twist
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.tf2_msgs import TFMessage

TOOLS = {
    "go_to", "look_for", "follow", "turn", "sit", "stand", "stop", "estop", "status", "describe", "get_image",
    "where_is",
}  # fmt: skip


@asynccontextmanager
async def stdio_client(*args: str) -> AsyncIterator[Any]:
    """`go2vlm mcp ARGS` started by the SDK's stdio client, as a desktop agent starts it."""
    from mcp import Client, StdioServerParameters

    params = StdioServerParameters(command=sys.executable, args=["-m", "go2vlm", "mcp", *args], env=env())
    async with Client(params, read_timeout_seconds=120) as client:
        yield client


@asynccontextmanager
async def http_client(url: str, token: str | None = None) -> AsyncIterator[Any]:
    """The SDK's streamable HTTP client, with a bearer token if given."""
    import httpx2
    from mcp import Client
    from mcp.client.streamable_http import streamable_http_client

    headers = {"Authorization": f"Bearer {token}"} if token else {}
    async with (
        httpx2.AsyncClient(headers=headers, timeout=httpx2.Timeout(60.0)) as http,
        Client(streamable_http_client(url, http_client=http), read_timeout_seconds=120) as client,
    ):
        yield client


def data(result: Any) -> dict[str, Any]:
    """A tool result's JSON (asserting it is not an error)."""
    assert not result.is_error, result.content[0].text
    return json.loads(result.content[0].text)


def error(result: Any) -> str:
    """A tool error's text (asserting it is one)."""
    assert result.is_error, result.content
    return result.content[0].text


class Probe(Node):
    """Ground truth (the base's pose with its sim time), /cmd_vel and the commander's status."""

    name = "mcp_probe"

    def __init__(self) -> None:
        super().__init__()
        self.lock = threading.Lock()
        self.poses: list[tuple[float, float, float, float]] = []  # sim t, x, y, yaw
        self.objects: dict[str, tuple[float, float]] = {}
        self.cmd: list[tuple[float, float, float]] = []  # the sim time when it came, vx, wz
        self.status: list[dict] = []
        self.sim_time = 0.0  # the newest /clock (100 Hz)
        self.create_subscription(Clock, "/clock", self._on_clock, QOS_CLOCK)
        self.create_subscription(TFMessage, "/sim/ground_truth", self._on_gt, QOS_DEFAULT)
        self.create_subscription(Twist, "/cmd_vel", self._on_cmd, QOS_DEFAULT)
        self.create_subscription(String, "/commander/status", self._on_status, QOS_LATCHED)

    def _on_gt(self, msg: TFMessage) -> None:
        with self.lock:
            for tf in msg.transforms:
                p = tf.transform.translation
                if tf.child_frame_id == "gt/go2":
                    q = tf.transform.rotation
                    yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
                    self.poses.append((tf.header.stamp.to_sec(), p.x, p.y, yaw))
                else:
                    self.objects[tf.child_frame_id.removeprefix("gt/")] = (p.x, p.y)

    def _on_clock(self, msg: Clock) -> None:
        self.sim_time = msg.clock.to_sec()

    def _on_cmd(self, msg: Twist) -> None:
        with self.lock:
            self.cmd.append((self.sim_time, msg.linear.x, msg.angular.z))

    def _on_status(self, msg: String) -> None:
        with self.lock:
            self.status.append(json.loads(msg.data))

    def pose(self) -> tuple[float, float, float, float]:
        with self.lock:
            return self.poses[-1]

    def since(self, t: float) -> list[tuple[float, float, float, float]]:
        with self.lock:
            return [p for p in self.poses if p[0] >= t]

    def moving_cmds_since(self, t: float) -> list[tuple[float, float, float]]:
        with self.lock:
            return [c for c in self.cmd if c[0] >= t and (c[1] != 0.0 or c[2] != 0.0)]

    def state(self) -> str:
        with self.lock:
            return self.status[-1].get("state", "") if self.status else ""


def speed(poses: list[tuple[float, float, float, float]], i: int, window: int = 1) -> tuple[float, float]:
    """(linear m/s, |yaw rate| rad/s) of the base around pose i (centred: `window` samples either side),
    from ground truth."""
    a, b = poses[max(0, i - window)], poses[min(len(poses) - 1, i + window)]
    dt = b[0] - a[0]
    if dt <= 0:
        return 0.0, 0.0
    dyaw = math.atan2(math.sin(b[3] - a[3]), math.cos(b[3] - a[3]))
    return math.dist(a[1:3], b[1:3]) / dt, abs(dyaw) / dt
