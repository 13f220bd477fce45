"""`BagRecorder`: record a bag from inside another program (an episode runner, a demo, a test).

rec = BagRecorder("runs/ep1/bag", all_topics=True).start()
...                                   # run the episode
result = rec.stop()                   # the bag is complete here
print(result.out, result.messages)
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from go2vlm.apps.bag.recorder_node import RecorderConfig, RecorderNode, TopicStats
from go2vlm.bus import build_config

__all__ = ["BagRecorder", "RecordResult"]


@dataclass
class RecordResult:
    out: Path
    messages: int
    topics: list[TopicStats] = field(default_factory=list)


class BagRecorder:
    """A recorder node with start/stop. `topics` or `all_topics` picks what is recorded; other
    RecorderConfig parameters (queue_depth, compression, ...) go in `params`."""

    def __init__(
        self,
        out: str | Path,
        topics: Iterable[str] = (),
        *,
        all_topics: bool = False,
        exclude: Iterable[str] = (),
        domain_id: int | None = None,
        interface: str | None = None,
        node_name: str = "recorder",
        **params: Any,
    ) -> None:
        values = {"out": str(out), "topics": list(topics), "all": all_topics, "exclude": list(exclude), **params}
        config: RecorderConfig = build_config(RecorderConfig, values, node=node_name)
        self.node = RecorderNode(config, node_name=node_name, domain_id=domain_id, interface=interface)
        self.out = self.node.out
        self._result: RecordResult | None = None

    def start(self) -> BagRecorder:
        self.node.start()
        return self

    def stats(self) -> list[TopicStats]:
        return self.node.stats()

    @property
    def messages(self) -> int:
        return self.node.message_count

    def stop(self) -> RecordResult:
        """Stop recording and finish the bag (metadata.yaml and the MCAP summary)."""
        if self._result is None:
            self.node.shutdown()
            self._result = RecordResult(self.out, self.node.message_count, self.node.stats())
        return self._result

    def __enter__(self) -> BagRecorder:
        return self.start()

    def __exit__(self, *_exc: object) -> None:
        self.stop()
