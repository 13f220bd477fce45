"""The emergency stop: one latch, and one way for a node to hear it.

Rule (the same in the safety gate, the sim, the go2 driver and every tool):
- `/emergency_stop` (std_msgs/Bool) true latches the e-stop. false does NOT release it.
- Only `/emergency_stop/release` (std_msgs/String) carrying exactly the release token releases it
  (no trimming: "RELEASE " is not "RELEASE"). A token must not be empty or padded with whitespace.
- `go2vlm estop` (cli/estop.py) holds a latched `true` on /emergency_stop until `go2vlm estop
  --release`, so a node that starts or restarts meanwhile latches too.

`EstopLatch` is the pure rule; it also remembers since when and why it holds. `EstopInput`
subscribes a node to both topics with every QoS, so any publisher matches and a latched e-stop
reaches a node that starts late, keeps a latch in step and logs and counts each event the same way
in every node. `LatchFile` keeps a latch across restarts (the gate's): written atomically on every
change (statefiles.write_atomic: by folder descriptor, never through a symlink in the state
directory); a file that cannot be read counts as latched, because the stopped state is the default.
The latch's folder (`LATCH_KIND`, estop/) is the gate's alone: no service takes that kind.

The latch belongs to the robot, not to a node name: one file per robot and DDS domain
(`latch_path`), so every gate that commands that robot on that domain, whatever its `--name`, shares
it, and `go2vlm demo` / `go2vlm eval` can refuse to start on a latched robot (`find_latch`).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from go2vlm.bus import QOS_ANY, QOS_DEFAULT, QOS_LATCHED, discovery_info
from go2vlm.bus.topics import EMERGENCY_STOP, ESTOP_RELEASE
from go2vlm.statefiles import FileKind, StateFileError, read_bounded, state_dir, write_atomic

__all__ = [
    "ESTOP_TOPIC",
    "RELEASE_COMMAND",
    "RELEASE_TOKEN",
    "RELEASE_TOPIC",
    "EstopInput",
    "EstopLatch",
    "LATCH_KIND",
    "LatchFile",
    "LatchState",
    "check_token",
    "find_latch",
    "latch_path",
    "listen",
    "parse_stamp",
    "stamp_text",
]

ESTOP_TOPIC = EMERGENCY_STOP.name
RELEASE_TOPIC = ESTOP_RELEASE.name
RELEASE_TOKEN = "RELEASE"
RELEASE_COMMAND = "go2vlm estop --release"  # the deliberate release, as a person types it
LATCH_KIND = FileKind("e-stop latch", "estop", ".json")
MAX_LATCH_BYTES = 64 * 1024  # a latch state is one short JSON line


def stamp_text(t: float) -> str:
    """A wall-clock time (epoch seconds) as people read it in a latch file: local, with its offset."""
    return time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(t))


def parse_stamp(text: str) -> float | None:
    """`stamp_text` back to epoch seconds; None for anything else."""
    from datetime import datetime

    try:
        return datetime.strptime(text, "%Y-%m-%dT%H:%M:%S%z").timestamp()
    except (TypeError, ValueError):
        return None


def check_token(token: str) -> str:
    """The token itself, or ValueError: a release token is not empty and not padded with whitespace."""
    if not token or not token.strip():
        raise ValueError("the e-stop release token must not be empty")
    if token != token.strip():
        raise ValueError(f"the e-stop release token {token!r} must not start or end with whitespace")
    return token


class EstopLatch:
    """Engaged by `engage()`; only `release(token)` with exactly the right token disengages it.
    While engaged, `since` (wall-clock epoch seconds) and `why` say when and why it latched."""

    def __init__(self, token: str = RELEASE_TOKEN, engaged: bool = False) -> None:
        self._token = check_token(token)
        self.engaged = engaged
        self.since: float | None = time.time() if engaged else None  # wall time: for people and files
        self.why = "started latched" if engaged else ""

    @property
    def token(self) -> str:
        return self._token

    def engage(self, why: str = "", since: float | None = None) -> None:
        """Latch (again); an engaged latch keeps its first `since` and `why`."""
        if not self.engaged:
            self.since = time.time() if since is None else since
            self.why = why
        self.engaged = True

    def release(self, token: str) -> bool:
        """True when the latch was engaged and is now released."""
        if not self.engaged or token != self._token:
            return False
        self.engaged = False
        self.since, self.why = None, ""
        return True


def listen(
    node: Any,
    on_estop: Callable[..., None],
    on_release: Callable[..., None] | None = None,
    *,
    with_sender: bool = False,
) -> None:
    """Subscribe `node` to the e-stop (and the release) with every QoS a sender may use;
    `with_sender`: the callbacks get (msg, sender Endpoint or None)."""
    for qos in (QOS_LATCHED, QOS_DEFAULT, QOS_ANY):
        EMERGENCY_STOP.subscription(node, on_estop, qos=qos, with_sender=with_sender)
    if on_release is not None:
        for qos in (QOS_DEFAULT, QOS_ANY):
            ESTOP_RELEASE.subscription(node, on_release, qos=qos, with_sender=with_sender)


def latch_path(robot: str, domain_id: int) -> Path:
    """Where the latch of `robot` on DDS domain `domain_id` is kept: $XDG_STATE_HOME (default
    ~/.local/state)/go2vlm/estop/<robot>-domain<N>.json. One per robot and domain: every gate that
    commands that robot there shares it, whatever its node name; two robots never share one."""
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in robot) or "robot"
    return state_dir() / LATCH_KIND.folder / f"{safe}-domain{domain_id}{LATCH_KIND.suffix}"


@dataclass(frozen=True)
class LatchState:
    """A latch as a person needs to hear about it: engaged, since when, by whom, why, and where it is kept."""

    engaged: bool
    since: str = ""  # local time text (stamp_text), '' when unknown
    by: str = ""  # the node that latched it (or last wrote the file)
    why: str = ""
    where: str = ""  # the latch file, or the topic a holder keeps it latched on
    unreadable: bool = False  # a file that cannot be read: latched, because stopped is the default

    def line(self, robot: str, domain_id: int) -> str:
        """One line: what is latched, since when, who latched it, and how to release it."""
        since = f" since {self.since}" if self.since else ""
        by = f" by {self.by}" if self.by else ""
        why = f" ({self.why})" if self.why else ""
        return (
            f"the e-stop is latched for robot {robot!r} on DDS domain {domain_id}{since}{by}{why} [{self.where}]; "
            f"release it deliberately with `{RELEASE_COMMAND}` (same domain), then start again"
        )


class LatchFile:
    """A latch state on disk: `load()` at start-up, `save()` on every change (atomically)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def load(self) -> tuple[bool | None, str]:
        """(engaged, note): None when there is no file; True when it cannot be read (stopped is the default)."""
        state = self.read()
        if state is None:
            return None, f"no state file at {self.path}"
        if state.unreadable:
            return True, f"{state.why}: starting latched"
        return state.engaged, f"{self.path} says {'latched' if state.engaged else 'released'} ({state.why or '?'})"

    def read(self) -> LatchState | None:
        """The state in the file: None without a file; engaged when it cannot be read."""
        try:
            text = read_bounded(self.path, MAX_LATCH_BYTES)
        except FileNotFoundError:
            return None
        except (OSError, StateFileError) as exc:
            return LatchState(True, why=f"cannot read {self.path} ({exc})", where=str(self.path), unreadable=True)
        try:
            data = json.loads(text)
            engaged = data["engaged"]
            if not isinstance(engaged, bool):
                raise ValueError(f"engaged is {engaged!r}")
        except (ValueError, KeyError, TypeError) as exc:
            why = f"{self.path} is not a latch state ({exc})"
            return LatchState(True, why=why, where=str(self.path), unreadable=True)
        since = data.get("since") or (data.get("time", "") if engaged else "")
        why = data.get("why") or f"written {data.get('time', '?')}"
        return LatchState(engaged, str(since), str(data.get("node", "")), str(why), str(self.path))

    def save(self, engaged: bool, node: str, *, since: float | None = None, why: str = "") -> None:
        """Write the state to a temporary file in the same folder, fsync it, rename it over the old
        one: a crash leaves the old state or the new one, never half of either. Raises OSError
        (StateFileError, one, where a symlink stands in the way)."""
        # Wall time: when the state was written (and latched), for the person reading the file.
        data: dict[str, Any] = {"engaged": engaged, "node": node, "time": stamp_text(time.time())}
        if engaged:
            data["since"] = stamp_text(since if since is not None else time.time())
            data["why"] = why
        try:
            write_atomic(self.path, (json.dumps(data) + "\n").encode(), overwrite=True)
        except StateFileError as exc:
            raise OSError(str(exc)) from None


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
        # Who sent an e-stop, by name: the node's announcements, heard from the start (the same
        # process-wide directory the one-commander watch reads).
        self._names = discovery_info.directory(node.participant)
        listen(node, self._estop, self._release, with_sender=True)

    @property
    def engaged(self) -> bool:
        return self.latch.engaged

    def _who(self, sender: Any) -> str:
        """The node behind an e-stop sample's writer, for the log, the status and the latch file."""
        if sender is None:
            return "an unknown writer"
        return self._names.node_of(sender.guid) or f"participant {sender.participant}"

    def _estop(self, msg: Any, sender: Any = None) -> None:
        log = self.node.log
        if msg.data:
            if self.latch.engaged:
                return  # already latched (one sample arrives through several QoS; senders repeat)
            who = self._who(sender)
            log.warning(
                f"EMERGENCY STOP from {who}: {self.held} until {self.latch.token!r} is published on {RELEASE_TOPIC}"
            )
            self.latch.engage(f"{ESTOP_TOPIC} from {who}")
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
        self.latch.engage(why)
        self.node.count("estops")
        self.persist()
        if notify:
            self._on_engage()

    def _release(self, msg: Any, sender: Any = None) -> None:
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
            self.store.save(self.latch.engaged, self.node.node_name, since=self.latch.since, why=self.latch.why)
        except OSError as exc:
            n = self.node.count("estop_state_write_errors")
            self.node.log.error(f"cannot write the e-stop state to {self.store.path} ({n} so far): {exc}")


def find_latch(
    path: str | Path, domain_id: int | None = None, interface: str | None = None, wait_s: float = 1.5
) -> LatchState | None:
    """Whether a robot is latched, before anything is started for it: its latch file (`path`, see
    `latch_path`) says so, or a holder (`go2vlm estop`) keeps a latched `true` on /emergency_stop of
    the domain (heard within `wait_s` wall seconds of discovery). None when neither."""
    stored = LatchFile(path).read()
    if stored is not None and stored.engaged:
        return stored
    if wait_s <= 0:
        return None
    import threading

    from go2vlm.bus import Node

    heard: list[tuple[int, Any]] = []  # (source stamp in ns, writer)
    got = threading.Event()
    node = Node(node_name="go2vlm_estop_check", domain_id=domain_id, interface=interface, parameter_services=False)
    names = discovery_info.directory(node.participant)

    def on_estop(msg: Any, sender: Any) -> None:
        if msg.data and not got.is_set():
            heard.append((getattr(getattr(msg, "sample_info", None), "source_timestamp", 0) or 0, sender))
            got.set()

    EMERGENCY_STOP.subscription(node, on_estop, qos=QOS_LATCHED, with_sender=True)  # the held, latched one
    node.start()
    try:
        if not got.wait(wait_s):  # wall time: DDS discovery of a holder
            return None
        stamp, sender = heard[0]
        who = None
        deadline = time.monotonic() + 1.0  # its node name comes on ros_discovery_info, maybe a moment later
        while sender is not None and who is None and time.monotonic() < deadline:
            who = names.node_of(sender.guid)
            time.sleep(0.05)
        since = stamp_text(stamp / 1e9) if stamp > 0 else ""
        return LatchState(True, since, who or "an unnamed publisher", "", f"held on {ESTOP_TOPIC}")
    finally:
        node.shutdown()
