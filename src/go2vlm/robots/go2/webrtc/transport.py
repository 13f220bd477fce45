"""The go2 driver's WebRTC transport: everything the DDS route gives the driver, over a `Go2Link`.

The driver (robots/go2/driver_node.py) stays the same above the transport: `sport` answers like its
DDS `RpcClient` (call_async, send_noreply, matched), and the robot's messages arrive as the same IDL
types on the same driver methods (_on_state, _on_lowstate, _on_cloud), on the driver's own executor
thread (`Node.call_soon`). What only WebRTC has:

- the camera is a video track: each decoded frame goes to `_publish_camera` (at most `camera_rate_hz`);
- the lidar is a voxel map in the odom frame: its cells go back into base_link with the pose of the
  newest sportmodestate and become the same PointCloud2 the DDS route gets (frame base_link);
- a second controller shows as sport requests of ids we did not send (the robot relays
  rt/api/sport/request to subscribers), or as the robot closing our connection (another WebRTC
  client, e.g. the phone app, took it over), or as "reject" on reconnect (another client holds it);
- the link itself: `_on_link(up, reason)`, and the firmware version read on each connect.

Malformed messages (JSON that does not fit the IDL, a voxel map that does not decode) are counted
(`webrtc_bad_messages`) and dropped; the driver keeps running.
"""

from __future__ import annotations

import math
import time
from collections import deque
from typing import Any

import numpy as np

from go2vlm.geometry.rotations import quat_to_mat
from go2vlm.msgs.pointcloud import xyz_cloud
from go2vlm.msgs.std_msgs import Header
from go2vlm.robots.go2 import protocol as p
from go2vlm.robots.go2.client import RpcFuture
from go2vlm.robots.go2.webrtc import codec
from go2vlm.robots.go2.webrtc.link import BUSY, CLOSED_BY_ROBOT, Go2Link, LinkSettings
from go2vlm.secret import read_secret

OWN_IDS = 4096  # request ids remembered as ours (to tell other controllers' requests apart)
QUIET_S = 0.5  # nothing heard on the data channel for this long: send no Move (it might arrive late);
# video frames do not count: a stalled data channel with live video must not queue Moves


class WebRtcSport:
    """The sport service over the link, shaped like the DDS RpcClient the driver uses."""

    def __init__(self, transport: WebRtcTransport, timeout_s: float) -> None:
        self.transport = transport
        self.timeout_s = timeout_s
        self.writer_guid = None  # no DDS writer: other controllers are told apart by request id
        self.sent = 0

    @property
    def matched(self) -> bool:
        return self.transport.link.connected

    def call_async(
        self, api_id: int, parameter: str | dict[str, Any] = "", binary: bytes = b"", timeout_s: float | None = None
    ) -> RpcFuture:
        """The answer arrives on the driver's thread, as from the DDS client."""
        node = self.transport.node
        link = self.transport.link
        rid = link.new_id()
        timeout = timeout_s or self.timeout_s
        future = RpcFuture(api_id, rid, time.monotonic() + timeout)
        self.transport.own(rid)
        inner = link.request(p.RTC_SPORT_REQUEST, api_id, parameter, timeout_s=timeout, request_id=rid)
        inner.add_done_callback(lambda result: node.call_soon(lambda: future.set_result(result)))
        self.sent += 1
        return future

    def send_noreply(self, api_id: int, parameter: str | dict[str, Any] = "") -> bool:
        """Fire and forget (Move): the robot answers it over WebRTC, and the answer is not waited for."""
        link = self.transport.link
        if time.monotonic() - link.channel_heard > QUIET_S:  # wall: the data channel's silence
            link.count("quiet_link")
            return False
        rid = link.new_id()
        self.transport.own(rid)
        result = link.request(p.RTC_SPORT_REQUEST, api_id, parameter, reply=False, request_id=rid).result()
        if result is None or not result.ok:
            return False
        self.sent += 1
        return True


class WebRtcTransport:
    """The driver's link to a Go2 over WebRTC (the Unitree app's route)."""

    def __init__(self, driver: Any, cfg: Any) -> None:
        self.node = driver
        self.driver = driver
        self._own: deque[int] = deque(maxlen=OWN_IDS)
        self._own_set: set[int] = set()
        self._pose: tuple[np.ndarray, np.ndarray] | None = None  # (R world<-base, position) of the newest state
        self._frame_period = 1.0 / cfg.camera_rate_hz if cfg.camera_rate_hz > 0 else math.inf
        self._last_frame = -math.inf
        self.firmware: str | None = None
        self.firmware_note: str | None = None
        self.link_events: list[str] = []
        topics = [p.RTC_SPORT_STATE, p.RTC_SPORT_REQUEST]
        if cfg.lowstate_topic:
            topics.append(p.RTC_LOW_STATE)
        if cfg.lidar:
            topics.append(p.RTC_LIDAR_VOXELS)
        settings = LinkSettings(
            ip=cfg.ip,
            mode=cfg.mode,
            serial=cfg.serial,
            port=cfg.signal_port,
            aes_key=read_secret(p.AES_KEY_ENV, cfg.aes_key_file, "aes_key_file"),
            timeout_s=cfg.connect_timeout_s,
        )
        self.link = Go2Link(
            settings,
            on_message=self._on_message,
            on_link=self._on_link,
            on_frame=self._on_frame if cfg.camera_rate_hz > 0 else None,
            topics=tuple(topics),
            lidar=cfg.lidar,
            log=driver.log,
        )
        self.sport = WebRtcSport(self, cfg.rpc_timeout_s)

    def start(self) -> None:
        """The first connection: LinkError (exit 2, one line) when it cannot be made."""
        self.link.connect_first()

    def stop(self) -> None:
        self.link.stop()

    def own(self, rid: int) -> None:
        if len(self._own) == self._own.maxlen:
            self._own_set.discard(self._own[0])
        self._own.append(rid)
        self._own_set.add(rid)

    def status(self) -> dict[str, Any]:
        link = self.link
        return {
            "ip": link.ip,
            "connected": link.connected,
            "connects": link.connects,
            "firmware": self.firmware,
            "firmware_note": self.firmware_note,
            "counters": dict(link.counters),
            "last_event": self.link_events[-1] if self.link_events else None,
        }

    # -- from the link's loop thread --------------------------------------------------------------
    def _bad(self, what: str) -> None:
        self.link.count("bad_messages")
        self.node.call_soon(lambda: self._report_bad(what))

    def _report_bad(self, what: str) -> None:
        self.driver.count("webrtc_bad_messages")
        self.driver.log.throttled("error", 2.0, f"dropped a malformed WebRTC message: {what}", key="webrtc-bad")

    def _on_message(self, msg: dict[str, Any], payload: bytes | None) -> None:
        topic, data = msg.get("topic"), msg.get("data")
        if msg["type"] == "firmware":
            self.node.call_soon(lambda: self._on_firmware(data, msg.get("code")))
            return
        if msg["type"] != p.DC_MSG:
            return
        try:
            if topic in (p.RTC_SPORT_STATE, p.RTC_LF_SPORT_STATE):
                state = codec.sport_state_from_json(data)
                q = np.array([float(v) for v in state.imu_state.quaternion])
                if np.isfinite(q).all() and np.linalg.norm(q) > 1e-6:
                    self._pose = (quat_to_mat(q / np.linalg.norm(q)), np.array([float(v) for v in state.position]))
                self.node.call_soon(lambda: self.driver._on_state(state))
            elif topic in (p.RTC_LOW_STATE, p.RTC_LF_LOW_STATE):
                low = codec.low_state_from_json(data)
                self.node.call_soon(lambda: self.driver._on_lowstate(low))
            elif topic == p.RTC_LIDAR_VOXELS:
                self._on_voxels(data, payload)
            elif topic == p.RTC_SPORT_REQUEST:
                self._on_request(data)
        except ValueError as exc:
            self._bad(f"{topic}: {exc}")

    def _on_voxels(self, header: Any, payload: bytes | None) -> None:
        if not isinstance(header, dict) or payload is None:
            raise ValueError("a voxel map without its header or payload")
        world = codec.voxel_points(header, payload)
        pose = self._pose
        if pose is None:
            return  # no pose yet to bring the map into base_link
        rot, pos = pose
        base = (world - pos) @ rot
        stamp = header.get("stamp")
        base_frame = self.driver.profile.frames.base
        cloud_header = Header(stamp=self.driver.stamp(), frame_id=base_frame)
        if isinstance(stamp, (int, float)) and math.isfinite(stamp) and not self.driver.clock.sim:
            cloud_header = Header(stamp=self.driver.stamp(float(stamp)), frame_id=base_frame)
        cloud = xyz_cloud(cloud_header, base.astype(np.float32))
        self.node.call_soon(lambda: self.driver._on_cloud(cloud))

    def _on_request(self, data: Any) -> None:
        try:
            ident = data["header"]["identity"]
            rid, api = int(ident["id"]), int(ident["api_id"])
        except (KeyError, TypeError, ValueError):
            raise ValueError("a relayed sport request without header.identity") from None
        if rid in self._own_set or api not in p.SPORT_API_NAMES:
            return
        who = f"another client of the robot (request id {rid})"
        self.node.call_soon(lambda: self.driver._foreign_sport(p.SPORT_API_NAMES[api], who, None, None))

    def _on_frame(self, bgr: np.ndarray) -> None:
        now = time.monotonic()  # wall: the video's arrival, not a node's clock
        if now - self._last_frame < 0.75 * self._frame_period:  # at most camera_rate_hz, jitter allowed
            return
        self._last_frame = now
        self.node.call_soon(lambda: self.driver._publish_camera(bgr, self.driver.now(), None))

    def _on_link(self, up: bool, reason: str) -> None:
        self.link_events.append(("up: " if up else "down: ") + reason)
        del self.link_events[:-8]
        self.node.call_soon(lambda: self._link_changed(up, reason))

    # -- on the driver's thread ---------------------------------------------------------------------
    def _link_changed(self, up: bool, reason: str) -> None:
        d = self.driver
        if up:
            d.log.info(f"WebRTC link up ({reason})")
            d.cmd_vel.require_zero()  # nothing from before the drop restarts the robot
            return
        d.count("link_down")
        d.stop_now("the WebRTC link is down")
        d.moving = False
        if reason.startswith((BUSY, CLOSED_BY_ROBOT)):
            who = "another WebRTC client (the Unitree app?)"
            what = "holds the robot" if reason.startswith(BUSY) else "took the robot's WebRTC connection over"
            d.log.throttled("error", 2.0, f"{who} {what}", key="webrtc-takeover")
            d._foreign_sport("WebRTC takeover", who, None, None)
        d.log.throttled("error", 2.0, f"WebRTC link DOWN ({reason}): stopped, nothing queued; reconnecting")

    def _on_firmware(self, version: Any, code: Any) -> None:
        d = self.driver
        self.firmware = version if isinstance(version, str) and version else None
        if self.firmware is None:
            self.firmware_note = f"the robot did not tell its firmware version (code {code})"
            d.log.warning(f"Go2 firmware: unknown ({self.firmware_note})")
            return
        self.firmware_note = p.firmware_note(self.firmware)
        if self.firmware_note is None:
            d.log.info(f"Go2 firmware {self.firmware} (tested)")
        else:
            d.log.warning(f"Go2 firmware {self.firmware}: {self.firmware_note}")
