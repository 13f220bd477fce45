"""mcp: the bus side of `go2vlm mcp` -- a client on the bus, like `go2vlm estop` or `go2vlm topic`.
It turns the MCP tools into goals for the commander and reads what the robot reports. It never
publishes a velocity: every motion is a whitelisted goal (behavior/goals.py) that the commander turns
into commands, and the safety gate limits, guards and may stop them like anyone else's.

Topics (QoS: reliable, volatile, keep-last 10 unless noted)
  publishes   /goal                  std_msgs/String   the commander's goals: "go to the blue cylinder",
                                     "look for ...", "follow ...", "turn left 20 degrees", "sit", "stand",
                                     each with a lease (JSON {"goal", "lease": {"key", "s"}}:
                                     behavior/lease.py; key: the hash of a secret only this
                                     server holds), and "stop"
              /goal/lease            std_msgs/String   JSON {"proof", "next", "s"}: renews the goal's
                                     lease (proof: that secret; next: the next one's hash) every
                                     lease_s / 4 while this server lives, for min(lease_s, the deadman's
                                     time left + lease_s / 4): a server that dies leaves a goal that
                                     the commander itself stops; an agent that goes silent, this
                                     server's deadman stops first
              /emergency_stop        std_msgs/Bool, latched (transient-local, keep-last 1): true, held
                                     as `go2vlm estop` holds it, until the release arrives
              /mcp/pending           std_msgs/String, latched: JSON {id, goal, asked} of the goal waiting
                                     for a person's yes (confirm), {} when none
  subscribes  /commander/status      std_msgs/String, latched: the running goal and its state
              /safety/status         std_msgs/String, latched: the gate's e-stop, guard and output
              /target_tracker/status std_msgs/String, latched: how it grounds (color | vlm)
              /vlm/status            std_msgs/String   the describe model's name and mode
              /vlm/detection         std_msgs/String   a vlm node's answer text: describe(), while a
                                     /vlm/status says mode=describe
              /objects               vision_msgs/Detection3DArray, latched: the object memory (frame odom;
                                     class_id = label, score = confidence, bbox.center = where): where_is()
              /emergency_stop/release std_msgs/String  the release token ends the hold (nothing here sends it)
              /mcp/confirm           std_msgs/String   a person's answer to a pending goal, "yes <id>" or
                                     "no <id>" (the Foxglove view's Publish panel forwards it)
              image_topic            sensor_msgs/Image, sensor-data QoS, only while a tool needs a frame
                                     (get_image, describe) and for camera_linger_s after

Parameters (read-only at runtime)
  deadman_s          10.0   a goal started here stops when no status() call came for this long
                            (1..600 s)
  lease_s             2.0   the goals' lease: the commander stops a goal unrenewed for this long
  ack_timeout_s       3.0   wait this long for the commander to answer a goal (and for discovery)
  confirm            false  each motion goal waits for a person's yes (terminal or /mcp/confirm)
  confirm_timeout_s  60.0   no answer within this long is no
  describe_max_age_s 10.0   VLM text older than this is not what the camera sees now
  image_topic        /camera/image_raw
  camera_linger_s    10.0   keep the camera subscription this long after the last frame asked for
  release_token      RELEASE  the token that releases the e-stop (the hold ends when it is heard)

Time: wall time (time.monotonic). The deadman, the answers and the waits are about an agent and a
person talking over a network, not about the robot's clock (the sim may run faster or slower).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from go2vlm.apps.mcp.rules import CommanderState, Confirmations, MotionRules, Refused
from go2vlm.behavior.lease import LeaseKeys
from go2vlm.bus import QOS_LATCHED, Node, RawSample, param
from go2vlm.bus.topics import (
    CAMERA_IMAGE,
    COMMANDER_STATUS,
    EMERGENCY_STOP,
    ESTOP_RELEASE,
    GOAL,
    GOAL_LEASE,
    MCP_CONFIRM,
    MCP_PENDING,
    OBJECTS,
    SAFETY_STATUS,
    TRACKER_STATUS,
    VLM_STATUS,
    VLM_TEXT,
)
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.msgs.vision_msgs import Detection3DArray
from go2vlm.safety.estop import RELEASE_TOKEN, check_token

__all__ = ["McpBridgeConfig", "McpBridgeNode"]

MAX_DEADMAN_S = 600.0  # an agent silent for 10 minutes has gone
GATE_SILENT_S = 12.0  # a gate silent this long has gone (it reports every status_period_s, at most 10 s)


@dataclass
class McpBridgeConfig:
    deadman_s: float = param(
        10.0, help="stop a goal started here after this long without status()", min=1.0, max=MAX_DEADMAN_S
    )
    lease_s: float = param(2.0, help="the commander stops a goal unrenewed this long", min=0.5, max=30.0)
    ack_timeout_s: float = param(3.0, help="wait this long for the commander to answer a goal", min=0.2, max=60.0)
    confirm: bool = param(False, help="each motion goal waits for a person's yes")
    confirm_timeout_s: float = param(60.0, help="no answer within this long is no", min=1.0, max=3600.0)
    describe_max_age_s: float = param(10.0, help="VLM text older than this is stale", min=0.5)
    image_topic: str = param(CAMERA_IMAGE.name, help="the head camera")
    camera_linger_s: float = param(10.0, help="keep the camera subscription this long after use", min=0.5)
    release_token: str = param(RELEASE_TOKEN, help="the e-stop release token (ends the hold)")

    def validate(self) -> None:
        check_token(self.release_token)


@dataclass
class _Seen:
    data: dict[str, Any]
    at: float  # wall time of arrival
    seq: int


class McpBridgeNode(Node):
    """The ``mcp`` bus client; its contract is the module docstring. Methods are called from the MCP
    server's worker threads; everything shared is under `self._cv`."""

    name = "mcp"
    Config = McpBridgeConfig

    def __init__(self, config: McpBridgeConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        c: McpBridgeConfig = self.config
        self._cv = threading.Condition()
        self.rules = MotionRules(c.deadman_s)
        self.confirms = Confirmations(c.confirm_timeout_s)
        self.on_question: Callable[[int, str], None] | None = None  # the terminal prompt
        self._seq = 0
        self._status: dict[str, _Seen] = {}  # topic -> newest JSON status
        self._gates: dict[str, tuple[bool, float]] = {}  # /safety/status writer -> (estop, arrival)
        self._vlm_text: tuple[str, float] | None = None
        self._describing = -1e9  # when a /vlm/status last said mode=describe
        self._objects: tuple[Detection3DArray, float] | None = None
        self._frame: tuple[bytes, float] | None = None
        self._camera: Any = None
        self._camera_wanted = 0.0
        self._estop_pub: Any = None
        self.last_event = ""  # the newest thing this server did on its own (deadman, unanswered goal)
        self.pub_goal = GOAL.publisher(self)
        self.pub_lease = GOAL_LEASE.publisher(self)
        self._keys: LeaseKeys | None = None  # our goal's lease secrets (None: no goal of ours)
        self._starting = ""  # the goal a tool call is starting now ('' = none)
        self._renewed = -1e9
        self.pub_pending = MCP_PENDING.publisher(self)
        self.pub_pending.publish(String(data="{}"))
        for topic in (COMMANDER_STATUS, TRACKER_STATUS, VLM_STATUS):
            topic.subscription(self, lambda m, t=topic.name: self._on_status(t, m))
        SAFETY_STATUS.subscription(self, self._on_safety, with_sender=True)
        VLM_TEXT.subscription(self, self._on_vlm_text)
        OBJECTS.subscription(self, self._on_objects)
        ESTOP_RELEASE.subscription(self, self._on_release)
        MCP_CONFIRM.subscription(self, lambda m: self.answer(m.data, need_id=True))
        self.create_timer(0.1, self._tick)

    # -- what the bus says ---------------------------------------------------------------------
    def _on_status(self, topic: str, msg: String) -> None:
        try:
            data = json.loads(msg.data)
        except ValueError:
            self.count("bad_status")
            return
        if not isinstance(data, dict):
            return
        with self._cv:
            self._seq += 1
            self._status[topic] = _Seen(data, time.monotonic(), self._seq)
            if topic == VLM_STATUS.name and data.get("mode") == "describe":
                self._describing = time.monotonic()
            if topic == COMMANDER_STATUS.name:
                kind = data.get("kind")
                self.rules.observe(
                    CommanderState(str(data.get("goal") or ""), kind if isinstance(kind, str) else None,
                                   str(data.get("state") or "idle")),
                    time.monotonic(),
                )  # fmt: skip
            self._cv.notify_all()

    def _on_safety(self, msg: String, sender: Any) -> None:
        self._on_status(SAFETY_STATUS.name, msg)
        with self._cv:
            seen = self._status.get(SAFETY_STATUS.name)
            if seen is not None and isinstance(seen.data.get("estop"), bool):
                key = str(sender.guid) if sender is not None else "?"
                self._gates[key] = (seen.data["estop"], seen.at)

    def _on_vlm_text(self, msg: String) -> None:
        with self._cv:
            self._vlm_text = (msg.data, time.monotonic())

    def _on_objects(self, msg: Detection3DArray) -> None:
        with self._cv:
            self._objects = (msg, time.monotonic())

    def _on_release(self, msg: String) -> None:
        if msg.data != self.config.release_token:
            return
        with self._cv:
            pub, self._estop_pub = self._estop_pub, None
        if pub is not None:
            pub.close()  # no latched `true` left behind for late joiners, as `go2vlm estop` does
            self.log.warning("the e-stop was released by a person; no longer holding it")

    def _on_frame(self, s: RawSample) -> None:
        with self._cv:
            self._frame = (bytes(s.data), time.monotonic())
            self._cv.notify_all()

    def _tick(self) -> None:
        now = time.monotonic()
        with self._cv:
            why = self.rules.deadman(now)
            if why is None and self.rules.unanswered(now, self.config.ack_timeout_s * 3):
                self.rules.forget()
                why = "a goal sent here was never answered by the commander"
            renew = self._renewal(now)
            cam = self._camera
            linger = cam is not None and now - self._camera_wanted > self.config.camera_linger_s
            if linger:
                self._camera, self._frame = None, None
        if renew is not None:
            self.pub_lease.publish(String(data=renew))
        if why is not None:
            self.last_event = f"stopped: {why}"
            self.log.warning(self.last_event)
            self.pub_goal.publish(String(data="stop"))
        if linger:
            self.destroy_subscription(cam)

    def _renewal(self, now: float) -> str | None:
        """The lease renewal to send now (under self._cv), or None: while our goal runs and the agent
        polls, every lease_s / 4, for no longer than the deadman leaves (and a quarter lease)."""
        c = self.config
        if self.rules.ours is None or self._keys is None or now - self._renewed < c.lease_s / 4:
            return None
        # A quarter lease past the deadman: while this server lives, its own deadman stops the goal
        # first (and says so); only a server that died leaves it to the lease.
        ttl = min(c.lease_s, c.deadman_s - (now - self.rules.last_poll) + c.lease_s / 4)
        if ttl < 0.1:
            return None
        self._renewed = now
        return self._keys.renewal(round(ttl, 3))

    # -- reading --------------------------------------------------------------------------------
    def status_of(self, topic: str, max_age_s: float | None = None) -> dict[str, Any] | None:
        with self._cv:
            seen = self._status.get(topic)
        if seen is None or (max_age_s is not None and time.monotonic() - seen.at > max_age_s):
            return None
        return seen.data

    def estop_reports(self) -> dict[str, bool]:
        """Each live gate's e-stop, as its newest /safety/status says."""
        now = time.monotonic()
        with self._cv:
            return {k: v[0] for k, v in self._gates.items() if now - v[1] <= GATE_SILENT_S}

    def grounding(self) -> str | None:
        s = self.status_of(TRACKER_STATUS.name)
        g = s.get("grounding") if s else None
        return g if isinstance(g, str) else None

    def vlm_text(self) -> tuple[str, float, dict[str, Any] | None] | None:
        """The newest answer of a vlm node in describe mode, its age (s) and the newest /vlm/status, if
        recent enough (a detect node's answers are grounding JSON, not a description)."""
        with self._cv:
            item = self._vlm_text
            describing = time.monotonic() - self._describing < 5.0
        if item is None or not describing:
            return None
        age = time.monotonic() - item[1]
        if age > self.config.describe_max_age_s:
            return None
        return item[0], age, self.status_of(VLM_STATUS.name, 5.0)

    def objects(self) -> tuple[Detection3DArray, float] | None:
        with self._cv:
            return self._objects

    def frame(self, timeout_s: float = 3.0) -> tuple[np.ndarray, Image, float]:
        """The newest camera frame (BGR), its message and its age (s); subscribes on demand."""
        from go2vlm.msgs.image import to_bgr

        with self._cv:
            self._camera_wanted = time.monotonic()
            if self._camera is None:
                self._camera = self.create_raw_subscription(
                    CAMERA_IMAGE.type, self.config.image_topic, self._on_frame, CAMERA_IMAGE.reader_qos
                )
            got = self._cv.wait_for(lambda: self._frame is not None, timeout_s)
            frame = self._frame
        if not got or frame is None:
            raise Refused(f"no image on {self.config.image_topic} within {timeout_s:g} s: is a camera (or the sim) up?")
        msg = Image.deserialize(frame[0])
        try:
            bgr = to_bgr(msg)
        except ValueError as exc:
            raise Refused(f"the camera frame cannot be shown: {exc}") from None
        return bgr, msg, time.monotonic() - frame[1]

    # -- motion ----------------------------------------------------------------------------------
    def estop_latched(self) -> bool:
        with self._cv:
            held = self._estop_pub is not None
        return held or any(self.estop_reports().values())

    def require_gate(self) -> None:
        if not self.estop_reports():
            raise Refused(
                "no safety gate reports on /safety/status: nothing would limit or stop the robot, so no goal is "
                "sent (is the robot's graph running, on this ROS_DOMAIN_ID and interface?)"
            )

    def start_goal(self, text: str, *, replace: bool) -> dict[str, Any]:
        """Send a motion goal under the rules (busy, e-stop, confirm); the commander's answer."""
        self.require_gate()
        with self._cv:  # the check and the claim are one step: two concurrent calls never both pass
            if self._starting:
                raise Refused(f"another motion goal ({self._starting!r}) is being started right now; call status()")
            self.rules.check_start(text, replace=replace, estop=self.estop_latched())
            self._starting = text
        try:
            if self.config.confirm:
                self._confirm(text)
                with self._cv:  # the world may have changed while a person thought about it
                    self.rules.check_start(text, replace=replace, estop=self.estop_latched())
            with self._cv:
                self.rules.started(text, time.monotonic())
                self.last_event = ""
                self._keys, self._renewed = LeaseKeys(), time.monotonic()
            try:
                return self._send(text, self._keys)
            except Refused:
                with self._cv:
                    self.rules.forget()
                raise
        finally:
            with self._cv:
                self._starting = ""

    def stop(self) -> dict[str, Any]:
        with self._cv:
            self.rules.forget()
        return self._send("stop")

    def hold_estop(self) -> None:
        """Latch the e-stop and hold it (as `go2vlm estop` does) until a person releases it; the
        commander's goal is stopped too, so that nothing resumes after the release."""
        with self._cv:
            if self._estop_pub is None:
                self._estop_pub = EMERGENCY_STOP.publisher(self, qos=QOS_LATCHED)  # held, as `go2vlm estop` does
            self._estop_pub.publish(Bool(data=True))
            self.rules.forget()
        self.log.warning("EMERGENCY STOP requested by the MCP agent; release with `go2vlm estop --release`")
        self.pub_goal.publish(String(data="stop"))

    def wait_estop_reported(self, timeout_s: float) -> dict[str, bool]:
        deadline = time.monotonic() + timeout_s
        with self._cv:
            self._cv.wait_for(
                lambda: bool(self.estop_reports()) and all(self.estop_reports().values()),
                max(0.0, deadline - time.monotonic()),
            )
        return self.estop_reports()

    def _send(self, text: str, keys: LeaseKeys | None = None) -> dict[str, Any]:
        timeout = self.config.ack_timeout_s
        deadline = time.monotonic() + timeout
        while self.pub_goal.matched == 0 and time.monotonic() < deadline:
            time.sleep(0.02)  # discovery of the commander's /goal reader
        if self.pub_goal.matched == 0:
            raise Refused(f"no commander listens on /goal (waited {timeout:g} s): is the robot's graph running?")
        with self._cv:
            seq0 = self._seq
        lease = None if keys is None else {"key": keys.key, "s": min(self.config.lease_s, self.config.deadman_s)}
        self.pub_goal.publish(String(data=json.dumps({"goal": text, "lease": lease}) if lease else text))

        def answered() -> bool:
            s = self._status.get(COMMANDER_STATUS.name)
            return s is not None and s.seq > seq0 and s.data.get("goal") == text

        with self._cv:
            ok = self._cv.wait_for(answered, max(0.0, deadline - time.monotonic()))
            status = dict(self._status[COMMANDER_STATUS.name].data) if ok else None
        if status is None:
            self.pub_goal.publish(String(data="stop"))  # it may arrive late: then it ends at once
            raise Refused(f"the commander did not answer {text!r} within {timeout:g} s; sent stop")
        if status.get("state") == "rejected":
            raise Refused(f"the commander rejected {text!r}: {status.get('reason')}")
        return status

    # -- confirmations ---------------------------------------------------------------------------
    def _confirm(self, text: str) -> None:
        with self._cv:
            qid = self.confirms.ask(text, time.monotonic())
        self.pub_pending.publish(String(data=json.dumps({"id": qid, "goal": text, "answer": f"yes {qid}"})))
        if self.on_question is not None:
            self.on_question(qid, text)
        self.log.info(f"waiting for a person to confirm #{qid}: {text!r}")
        with self._cv:
            self._cv.wait_for(lambda: self.confirms.result(qid, time.monotonic()) is not None,
                              self.config.confirm_timeout_s + 1.0)  # fmt: skip
            yes = self.confirms.result(qid, time.monotonic())
        self.pub_pending.publish(String(data="{}"))
        if not yes:
            raise Refused(f"a person did not confirm {text!r} (#{qid}: no, or no answer): nothing was sent")

    def answer(self, line: str, *, need_id: bool) -> str:
        """A person's answer (the terminal: need_id False; the bus: True)."""
        with self._cv:
            what = self.confirms.answer(line, need_id=need_id)
            self._cv.notify_all()
        self.log.info(f"confirmation: {what}")
        return what

    def close(self) -> None:
        # Leaving (SIGTERM, stdin EOF): stop our goal now rather than when its lease runs out.
        with self._cv:
            ours, self._keys = self.rules.ours, None
        if ours is not None:
            self.pub_goal.publish(String(data="stop"))

    # -- status ----------------------------------------------------------------------------------
    def deadman_left(self) -> float | None:
        with self._cv:
            if self.rules.ours is None:
                return None
            return max(0.0, self.config.deadman_s - (time.monotonic() - self.rules.last_poll))

    def poll(self) -> None:
        with self._cv:
            self.rules.poll(time.monotonic())

    def our_goal(self) -> str | None:
        with self._cv:
            return self.rules.ours.text if self.rules.ours is not None else None
