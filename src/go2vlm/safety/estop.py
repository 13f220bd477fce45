"""The emergency stop: one latch, and one way for a node to hear it.

Rule (the same in the safety gate, the go2 driver and every tool):
- `/emergency_stop` (std_msgs/Bool) true latches the e-stop. false does NOT release it.
- Only `/emergency_stop/release` (std_msgs/String) carrying the release token releases it.

`EstopLatch` is the pure rule. `EstopInput` subscribes a node to both topics with every QoS, so
any publisher matches and a latched e-stop reaches a node that starts late, keeps a latch in step
and logs and counts each event the same way in every node.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from go2vlm.bus import QOS_ANY, QOS_DEFAULT, QOS_LATCHED
from go2vlm.msgs.std_msgs import Bool, String

__all__ = ["ESTOP_TOPIC", "RELEASE_TOKEN", "RELEASE_TOPIC", "EstopInput", "EstopLatch", "listen"]

ESTOP_TOPIC = "/emergency_stop"
RELEASE_TOPIC = "/emergency_stop/release"
RELEASE_TOKEN = "RELEASE"


class EstopLatch:
    """Engaged by `engage()`; only `release(token)` with the right token disengages it."""

    def __init__(self, token: str = RELEASE_TOKEN, engaged: bool = False) -> None:
        if not token:
            raise ValueError("the e-stop release token must not be empty")
        self._token = token
        self.engaged = engaged

    @property
    def token(self) -> str:
        return self._token

    def engage(self) -> None:
        self.engaged = True

    def release(self, token: str) -> bool:
        """True when the latch was engaged and is now released."""
        if not self.engaged or token.strip() != self._token:
            return False
        self.engaged = False
        return True


def listen(node: Any, on_estop: Callable[[Any], None], on_release: Callable[[Any], None] | None = None) -> None:
    """Subscribe `node` to the e-stop (and the release) with every QoS a sender may use."""
    for qos in (QOS_LATCHED, QOS_DEFAULT, QOS_ANY):
        node.create_subscription(Bool, ESTOP_TOPIC, on_estop, qos)
    if on_release is not None:
        for qos in (QOS_DEFAULT, QOS_ANY):
            node.create_subscription(String, RELEASE_TOPIC, on_release, qos)


class EstopInput:
    """A node's e-stop: keeps `latch` in step with the topics and calls back on each change.

    `held` says what the e-stop holds in this node ("/cmd_vel held at zero", "Damp"); the same
    sample arriving through several QoS counts once. Counters on the node: estops, releases,
    release_refused, estop_false_ignored.
    """

    def __init__(
        self,
        node: Any,
        latch: EstopLatch,
        *,
        held: str,
        on_engage: Callable[[], None],
        on_release: Callable[[], None],
        released_note: str = "",
    ) -> None:
        self.node = node
        self.latch = latch
        self.held = held
        self.released_note = released_note
        self._on_engage = on_engage
        self._on_release = on_release
        listen(node, self._estop, self._release)

    @property
    def engaged(self) -> bool:
        return self.latch.engaged

    def _estop(self, msg: Any) -> None:
        log = self.node.log
        if msg.data:
            if self.latch.engaged:
                return  # already latched (one sample arrives through several QoS; senders repeat)
            log.warning(f"EMERGENCY STOP: {self.held} until {self.latch.token!r} is published on {RELEASE_TOPIC}")
            self.latch.engage()
            self.node.count("estops")
            self._on_engage()
        elif self.latch.engaged:
            self.node.count("estop_false_ignored")
            log.throttled("warning", 2.0, f"{ESTOP_TOPIC} false does not release the e-stop; use {RELEASE_TOPIC}")

    def _release(self, msg: Any) -> None:
        if not self.latch.engaged:
            return  # nothing to release, or a duplicate read through the other QoS
        if self.latch.release(msg.data):
            self.node.count("releases")
            self.node.log.warning("e-stop released" + (f"; {self.released_note}" if self.released_note else ""))
            self._on_release()
        else:
            n = self.node.count("release_refused")
            self.node.log.throttled("warning", 2.0, f"e-stop release refused: wrong token ({n} so far)", key="refused")
