"""Node.call_soon: work handed in from another thread runs on the node's executor thread, in order,
and a failing call is counted without stopping the node."""

from __future__ import annotations

import threading

from busutil import wait_for

from go2vlm.bus import Node, running


def test_call_soon_runs_on_the_executor_thread_in_order() -> None:
    node = Node(node_name="call_soon_probe", parameter_services=False)
    seen: list[tuple[int, str]] = []

    def boom() -> None:
        raise RuntimeError("boom")

    with running(node):
        worker = threading.Thread(
            target=lambda: [
                node.call_soon(lambda i=i: seen.append((i, threading.current_thread().name))) for i in range(50)
            ]
        )
        worker.start()
        worker.join()
        node.call_soon(boom)
        node.call_soon(lambda: seen.append((50, threading.current_thread().name)))
        assert wait_for(lambda: len(seen) == 51, 5)
    assert [i for i, _ in seen] == list(range(51))
    assert {name for _, name in seen} == {"node:call_soon_probe"}
    assert node.counters.get("callback_errors") == 1
