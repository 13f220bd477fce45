"""The emergency stop: one latch, and one way for a node to hear it.

Rule (the same in the safety gate, the sim, the go2 driver and every tool):
- `/emergency_stop` (std_msgs/Bool) true latches the e-stop. false does NOT release it.
- Only `/emergency_stop/release` (std_msgs/String) carrying exactly the release token releases it
  (no trimming: "RELEASE " is not "RELEASE"). A token must not be empty or padded with whitespace.
- `go2vlm estop` (cli/estop.py) holds a latched `true` on /emergency_stop until `go2vlm estop
  --release`, so a node that starts or restarts meanwhile latches too.

`EstopLatch` is the pure rule. `EstopInput` subscribes a node to both topics with every QoS, so
any publisher matches and a latched e-stop reaches a node that starts late, keeps a latch in step
and logs and counts each event the same way in every node. `LatchFile` keeps a latch across
restarts (the gate's): written atomically on every change; a file that cannot be read counts as
latched, because the stopped state is the default.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from go2vlm.bus import QOS_ANY, QOS_DEFAULT, QOS_LATCHED
from go2vlm.msgs.std_msgs import Bool, String

__all__ = [
    "ESTOP_TOPIC",
    "RELEASE_TOKEN",
    "RELEASE_TOPIC",
    "EstopInput",
    "EstopLatch",
    "LatchFile",
    "check_token",
    "default_state_file",
    "listen",
]

ESTOP_TOPIC = "/emergency_stop"
RELEASE_TOPIC = "/emergency_stop/release"
RELEASE_TOKEN = "RELEASE"


def check_token(token: str) -> str:
    """The token itself, or ValueError: a release token is not empty and not padded with whitespace."""
    if not token or not token.strip():
        raise ValueError("the e-stop release token must not be empty")
    if token != token.strip():
        raise ValueError(f"the e-stop release token {token!r} must not start or end with whitespace")
    return token


class EstopLatch:
    """Engaged by `engage()`; only `release(token)` with exactly the right token disengages it."""

    def __init__(self, token: str = RELEASE_TOKEN, engaged: bool = False) -> None:
        self._token = check_token(token)
        self.engaged = engaged

    @property
    def token(self) -> str:
        return self._token

    def engage(self) -> None:
        self.engaged = True

    def release(self, token: str) -> bool:
        """True when the latch was engaged and is now released."""
        if not self.engaged or token != self._token:
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


def default_state_file(node_name: str, domain_id: int) -> Path:
    """Where a node keeps its latch: $XDG_STATE_HOME (default ~/.local/state)/go2vlm/estop/, one
    file per node name and DDS domain, so two robots on two domains never share a latch."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in node_name) or "node"
    return Path(base) / "go2vlm" / "estop" / f"{safe}-domain{domain_id}.json"


class LatchFile:
    """A latch state on disk: `load()` at start-up, `save()` on every change (atomically)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def load(self) -> tuple[bool | None, str]:
        """(engaged, note): None when there is no file; True when it cannot be read (stopped is the default)."""
        try:
            text = self.path.read_text()
        except FileNotFoundError:
            return None, f"no state file at {self.path}"
        except OSError as exc:
            return True, f"cannot read {self.path} ({exc}): starting latched"
        try:
            data = json.loads(text)
            engaged = data["engaged"]
            if not isinstance(engaged, bool):
                raise ValueError(f"engaged is {engaged!r}")
        except (ValueError, KeyError, TypeError) as exc:
            return True, f"{self.path} is not a latch state ({exc}): starting latched"
        return engaged, f"{self.path} says {'latched' if engaged else 'released'} (written {data.get('time', '?')})"

    def save(self, engaged: bool, node: str) -> None:
        """Write the state to a temporary file in the same folder, fsync it, rename it over the old
        one: a crash leaves the old state or the new one, never half of either. Raises OSError."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # Wall time: when the state was written, for the person reading the file.
        data = {"engaged": engaged, "node": node, "time": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
        fd, tmp = tempfile.mkstemp(prefix=self.path.name + ".", dir=self.path.parent)
        try:
            with os.fdopen(fd, "w") as f:
                f.write(json.dumps(data) + "\n")
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        try:  # the rename itself survives a power cut once the folder is synced
            dfd = os.open(self.path.parent, os.O_RDONLY)
            try:
                os.fsync(dfd)
            finally:
                os.close(dfd)
        except OSError:
            pass


class EstopInput:
    """A node's e-stop: keeps `latch` in step with the topics and calls back on each change.

    `held` says what the e-stop holds in this node ("/cmd_vel held at zero", "Damp"); the same
    sample arriving through several QoS counts once. With `store`, every change is written there
    (a write that fails is logged and counted, and the latch in memory still holds). Counters on
    the node: estops, releases, release_refused, estop_false_ignored, estop_state_write_errors.
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
        store: LatchFile | None = None,
    ) -> None:
        self.node = node
        self.latch = latch
        self.held = held
        self.released_note = released_note
        self.store = store
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
            self.persist()
            self._on_engage()
        elif self.latch.engaged:
            self.node.count("estop_false_ignored")
            log.throttled("warning", 2.0, f"{ESTOP_TOPIC} false does not release the e-stop; use {RELEASE_TOPIC}")

    def engage(self, why: str, *, notify: bool = True) -> None:
        """Latch from inside the node (the gate's health monitor), logged, counted and persisted as
        if `true` had arrived on /emergency_stop; `notify` False skips the on_engage callback (a
        caller that is already applying it)."""
        if self.latch.engaged:
            return
        self.node.log.warning(
            f"EMERGENCY STOP ({why}): {self.held} until {self.latch.token!r} is published on {RELEASE_TOPIC}"
        )
        self.latch.engage()
        self.node.count("estops")
        self.persist()
        if notify:
            self._on_engage()

    def _release(self, msg: Any) -> None:
        if not self.latch.engaged:
            return  # nothing to release, or a duplicate read through the other QoS
        if self.latch.release(msg.data):
            self.node.count("releases")
            self.persist()
            self.node.log.warning("e-stop released" + (f"; {self.released_note}" if self.released_note else ""))
            self._on_release()
        else:
            n = self.node.count("release_refused")
            self.node.log.throttled("warning", 2.0, f"e-stop release refused: wrong token ({n} so far)", key="refused")

    def persist(self) -> None:
        """Write the latch's state to the store, if any."""
        if self.store is None:
            return
        try:
            self.store.save(self.latch.engaged, self.node.node_name)
        except OSError as exc:
            n = self.node.count("estop_state_write_errors")
            self.node.log.error(f"cannot write the e-stop state to {self.store.path} ({n} so far): {exc}")
