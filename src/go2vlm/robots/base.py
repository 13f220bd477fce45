"""The robot end: the node that turns the safety gate's /cmd_vel into motion on one robot. This base
wires what every robot end shares, so that each one implements only its own parts.

What the base wires, in this order (the order is the priority lane: each executor pass reads the
e-stop before /cmd_vel):
1. The e-stop (safety/estop.py): `true` on /emergency_stop latches; the command goes to zero and the
   robot end's `damp()` runs; only the exact release token releases, and motion then resumes only
   after /cmd_vel has passed through zero.
2. /cmd_vel from the one safety gate only (safety/commander.py `CmdVelInput`): a sample with a
   non-finite value is refused and stops the robot; a valid one is clamped to the robot's ceilings
   (its profile) and kept with its time. `command()` is the command to execute now: zero when it is
   older than `cmd_timeout_s` (the node's clock: sim time with use_sim_time) or the e-stop holds.
3. Postures on `posture_topic`, checked against one vocabulary (`postures`; while the e-stop holds,
   only `estop_postures`). An unknown word or a refused one is counted, logged and reported; a valid
   one goes to `posture(word)`. Every posture ends in `posture_done(word, result)`, which the status
   carries as `last_command` {seq, name, result}.
4. Status on `status_topic` (latched JSON): the robot end's own fields (`status()`) plus `estop`,
   `estop_why`, `commander` (who may drive /cmd_vel, and why not) and `last_command`.

A robot end subclasses `RobotEnd`, sets `profile` (robot_profile/), `postures`, `estop_postures`,
`posture_topic` and `status_topic`, gives its Config the fields of `RobotEndConfig`, and implements:
    damp()          the robot's emergency action (a Go2: Damp)
    posture(word)   carry out one posture word (already checked); end with posture_done(word, result)
    status()        its own status fields
and applies `command()` in its own loop (the sim: its physics thread; the go2 driver: a Move timer
on its transport). `on_stop(reason)` is called when the command was just forced to zero because
driving is not allowed any more (`stop_now(reason)`: another /cmd_vel writer, or a transport that
lost the robot): stop at once.
"""

from __future__ import annotations

import json
import math
import threading
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, ClassVar

from go2vlm.bus import Node, param
from go2vlm.bus.topics import Topic
from go2vlm.msgs.geometry_msgs import Twist
from go2vlm.msgs.std_msgs import String
from go2vlm.robot_profile import RobotProfile
from go2vlm.safety.commander import CmdVelInput
from go2vlm.safety.estop import RELEASE_TOKEN, EstopInput, EstopLatch, check_token

__all__ = ["Command", "RobotEnd", "RobotEndConfig"]

Command = tuple[float, float, float]  # vx, vy (m/s), wz (rad/s) in the base frame
ZERO: Command = (0.0, 0.0, 0.0)


@dataclass
class RobotEndConfig:
    """The parameters every robot end has."""

    cmd_timeout_s: float = param(
        0.5,
        help="a /cmd_vel older than this counts as zero (the node's clock: sim s with use_sim_time)",
        min=0.05,
        max=10.0,
    )
    release_token: str = param(
        RELEASE_TOKEN, help="the /emergency_stop/release text that releases the e-stop (exact match)"
    )

    def validate(self) -> None:
        check_token(self.release_token)


class RobotEnd(Node):
    profile: ClassVar[RobotProfile]
    postures: ClassVar[Iterable[str]] = ()
    estop_postures: ClassVar[frozenset[str]] = frozenset()
    posture_topic: ClassVar[Topic[String]]  # from the topic table (bus/topics.py)
    status_topic: ClassVar[Topic[String]]

    def __init__(
        self,
        config: Any = None,
        *,
        held: str,
        released_note: str,
        take_postures: bool = True,
        **kwargs: Any,
    ) -> None:
        super().__init__(config, **kwargs)
        self._cmd_lock = threading.Lock()  # /cmd_vel comes on the executor, a sim applies it on its physics thread
        self._cmd: Command = ZERO
        self._cmd_t = -math.inf  # node-clock time of the last valid /cmd_vel
        self._command_seq = 0
        self.last_command: dict[str, Any] | None = None
        self.pub_status = self.status_topic.publisher(self)
        # The e-stop first: each executor pass takes it before /cmd_vel.
        self.estop = EstopLatch(self.config.release_token)
        self.estop_input = EstopInput(
            self,
            self.estop,
            held=held,
            on_engage=self._on_estop,
            on_release=self._on_release,
            released_note=released_note,
        )
        self.cmd_vel = CmdVelInput(self, self._on_cmd_vel, self.stop_now)
        if take_postures:
            self.posture_topic.subscription(self, self._on_posture)

    # -- what a robot end implements ---------------------------------------------------------
    def damp(self) -> None:
        """The robot's emergency action."""
        raise NotImplementedError

    def posture(self, word: str) -> None:
        """Carry out `word` (in `postures`, allowed now); end with `posture_done(word, result)`."""
        raise NotImplementedError

    def status(self) -> dict[str, Any]:
        """The robot end's own status fields."""
        return {}

    def on_stop(self, reason: str) -> None:
        """The command was just forced to zero (another /cmd_vel writer): stop now, not at the timeout."""

    def on_posture_done(self) -> None:
        """A posture ended: by default the status goes out at once (`go2vlm go2 <posture>` waits for it)."""
        self.publish_status()

    # -- the command -------------------------------------------------------------------------
    def command(self) -> Command:
        """The command to execute now: zero when it is stale or the e-stop holds."""
        cmd, timed_out = self.latest_command()
        return ZERO if timed_out or self.estop.engaged else cmd

    def latest_command(self) -> tuple[Command, bool]:
        """(the newest valid command, whether it is older than cmd_timeout_s)."""
        with self._cmd_lock:
            cmd, t = self._cmd, self._cmd_t
        return cmd, self.clock.monotonic() - t > self.config.cmd_timeout_s

    def _set_command(self, cmd: Command) -> None:
        with self._cmd_lock:
            self._cmd, self._cmd_t = cmd, self.clock.monotonic()

    def _on_cmd_vel(self, msg: Twist) -> None:
        vals = (msg.linear.x, msg.linear.y, msg.angular.z)
        if not all(isinstance(v, float) and math.isfinite(v) for v in vals):
            self.count("bad_cmd_vel")
            self.log.throttled("error", 2.0, f"rejected /cmd_vel with a non-finite value {vals}: stopping instead")
            self._set_command(ZERO)
            return
        self._set_command(self.profile.ceilings.clamp(*vals))

    def stop_now(self, reason: str) -> None:
        """Driving is not allowed any more (another /cmd_vel writer, a transport that lost the robot):
        zero now, and `on_stop(reason)`."""
        self._set_command(ZERO)
        self.on_stop(reason)

    # -- the e-stop --------------------------------------------------------------------------
    def _on_estop(self) -> None:
        self._set_command(ZERO)
        self.damp()

    def _on_release(self) -> None:
        self.cmd_vel.require_zero()

    # -- postures ----------------------------------------------------------------------------
    def _on_posture(self, msg: String) -> None:
        word = msg.data.strip().lower()
        known = tuple(self.postures)
        if word not in known:
            self.count("bad_command")
            self.log.throttled(
                "error", 2.0, f"unknown {self.posture_topic.name} {msg.data[:40]!r}; use one of {', '.join(known)}"
            )
            self.posture_done(word[:40], "unknown command")
            return
        if self.estop.engaged and word not in self.estop_postures:
            self.count("refused_command")
            self.log.throttled("error", 2.0, f"refused {word!r}: emergency stop latched (release it first)")
            self.posture_done(word, "refused: emergency stop latched")
            return
        self.posture(word)

    def posture_done(self, word: str, result: str) -> None:
        """Say how a posture ended (`last_command` in the status)."""
        self._command_seq += 1
        self.last_command = {"seq": self._command_seq, "name": word, "result": result}
        self.on_posture_done()

    # -- status ------------------------------------------------------------------------------
    def publish_status(self) -> None:
        status = {
            **self.status(),
            "estop": self.estop.engaged,
            "estop_why": self.estop.why if self.estop.engaged else None,
            "commander": self.cmd_vel.status(),
            "last_command": self.last_command,
        }
        self.pub_status.publish(String(data=json.dumps(status)))
