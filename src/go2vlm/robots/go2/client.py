"""A Unitree RPC client (sport, videohub, ...) on top of a go2vlm node.

Requests go out on `/api/<service>/request` (DDS `rt/api/<service>/request`); responses come back
on the node's own executor thread and are matched to their request by identity id, as
unitree_sdk2's ClientStub does. Two ways to call:

- `call_async(...)` returns an `RpcFuture` at once (for node code: never block the executor);
  `future.add_done_callback(fn)` runs `fn(result)` on the node thread when the answer or the
  timeout arrives.
- `call(...)` blocks until the answer or the timeout (for CLI code on another thread).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from go2vlm.bus import QOS_UNITREE_READER, QOS_UNITREE_WRITER, Node
from go2vlm.msgs.unitree import Request, Response
from go2vlm.robots.go2 import protocol as p


class RpcFuture:
    """The pending result of one request."""

    def __init__(self, api_id: int, request_id: int, deadline: float) -> None:
        self.api_id = api_id
        self.request_id = request_id
        self.deadline = deadline
        self._event = threading.Event()
        self._result: p.RpcResult | None = None
        self._callbacks: list[Callable[[p.RpcResult], None]] = []
        self._lock = threading.Lock()

    def done(self) -> bool:
        return self._event.is_set()

    def result(self) -> p.RpcResult | None:
        return self._result

    def wait(self, timeout_s: float | None = None) -> p.RpcResult:
        """The result; ERR_CLIENT_API_TIMEOUT if none arrived within `timeout_s`."""
        if not self._event.wait(timeout_s):
            return p.RpcResult(p.ERR_CLIENT_API_TIMEOUT)
        assert self._result is not None
        return self._result

    def add_done_callback(self, fn: Callable[[p.RpcResult], None]) -> None:
        with self._lock:
            if self._result is None:
                self._callbacks.append(fn)
                return
            result = self._result
        fn(result)

    def set_result(self, result: p.RpcResult) -> bool:
        with self._lock:
            if self._result is not None:
                return False
            self._result = result
            callbacks, self._callbacks = self._callbacks, []
        self._event.set()
        for fn in callbacks:
            fn(result)
        return True


class RpcClient:
    """Client of one Unitree RPC service (`sport`, `videohub`)."""

    def __init__(self, node: Node, service: str, *, timeout_s: float = 1.0) -> None:
        if not timeout_s > 0:
            raise ValueError(f"RPC timeout must be positive, got {timeout_s}")
        self.node = node
        self.service = service
        self.timeout_s = timeout_s
        self._pending: dict[int, RpcFuture] = {}
        self._lock = threading.Lock()
        self._pub = node.create_publisher(Request, p.request_topic(service), QOS_UNITREE_WRITER)
        self._sub = node.create_subscription(Response, p.response_topic(service), self._on_response, QOS_UNITREE_READER)
        # RPC timeouts are network timeouts: wall time, even on a node that runs on sim time.
        node.create_timer(0.05, self._expire, wall=True)
        self.sent = 0
        self.foreign_responses = 0

    @property
    def writer_guid(self) -> Any:
        """The GUID of this client's request writer (to tell our requests from other clients')."""
        return self._pub.guid

    @property
    def matched(self) -> bool:
        """True once a server is matched both ways (the robot or the sim is reachable): a reader of our
        requests and a writer of responses. A request reader alone may be a listener, not a server
        (the go2 driver watches the sport requests of other clients)."""
        return self._pub.matched > 0 and self._sub.publisher_count > 0

    def wait_for_server(self, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s  # wall time: waiting for DDS discovery
        while time.monotonic() < deadline:
            if self.matched:
                return True
            time.sleep(0.02)
        return self.matched

    def call_async(
        self, api_id: int, parameter: str | dict[str, Any] = "", binary: bytes = b"", timeout_s: float | None = None
    ) -> RpcFuture:
        request = p.build_request(api_id, parameter, binary)
        rid = request.header.identity.id
        future = RpcFuture(api_id, rid, time.monotonic() + (timeout_s or self.timeout_s))  # wall: network timeout
        if not self.matched:
            future.set_result(p.RpcResult(p.ERR_CLIENT_SEND))
            return future
        with self._lock:
            self._pending[rid] = future
        try:
            self._pub.publish(request)
        except Exception:
            with self._lock:
                self._pending.pop(rid, None)
            future.set_result(p.RpcResult(p.ERR_CLIENT_SEND))
            return future
        self.sent += 1
        return future

    def call(
        self, api_id: int, parameter: str | dict[str, Any] = "", binary: bytes = b"", timeout_s: float | None = None
    ) -> p.RpcResult:
        """Blocking call; the node must be spinning on another thread."""
        if self.node._thread is threading.current_thread():
            raise RuntimeError("RpcClient.call() would deadlock on the node's own thread; use call_async()")
        timeout = timeout_s or self.timeout_s
        future = self.call_async(api_id, parameter, binary, timeout)
        result = future.wait(timeout)
        if not future.done():
            with self._lock:
                self._pending.pop(future.request_id, None)
            future.set_result(result)
        return result

    def send_noreply(self, api_id: int, parameter: str | dict[str, Any] = "") -> bool:
        """Fire-and-forget (Move). False when no server is matched."""
        if not self.matched:
            return False
        self._pub.publish(p.build_request(api_id, parameter, noreply=True))
        self.sent += 1
        return True

    def pending(self) -> int:
        with self._lock:
            return len(self._pending)

    def _on_response(self, response: Response) -> None:
        rid = int(response.header.identity.id)
        with self._lock:
            future = self._pending.pop(rid, None)
        if future is None:
            self.foreign_responses += 1  # another client's answer, or one that came after its timeout
            return
        future.set_result(p.result_from_response(future.api_id, response))

    def _expire(self) -> None:
        now = time.monotonic()  # wall time: network timeouts
        with self._lock:
            late = [f for f in self._pending.values() if f.deadline <= now]
            for f in late:
                self._pending.pop(f.request_id, None)
        for f in late:
            f.set_result(p.RpcResult(p.ERR_CLIENT_API_TIMEOUT))
