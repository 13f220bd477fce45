"""The WebRTC link to a Go2: signalling, the peer connection (aiortc), the data channel's validation
and heartbeat, requests with answers, topic subscriptions, the video track, and reconnects.

`Go2Link` runs its own asyncio loop on a thread of its own. Every callback it makes (`on_message`,
`on_frame`, `on_link`) runs on that thread: the owner hands the work to its own thread (the go2
driver does, through `Node.call_soon`). `request()` and `send()` may be called from any thread.

Start: `connect_first()` makes the first connection and raises `LinkError` (a ConfigError: one line,
exit 2 at start) when the robot does not answer, has no signalling port, answers something that
cannot be read, or speaks a protocol go2vlm does not know. Later drops are not errors: the link says
so (`on_link(False, reason)`), waits (backoff 0.5 s doubling to `max_backoff_s`) and connects again.
Nothing sent while it is down is queued: `request()` answers ERR_CLIENT_SEND at once.

Time: every timeout here is a network timeout, wall time.
"""

from __future__ import annotations

import asyncio
import collections
import json
import socket
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from go2vlm.errors import ConfigError
from go2vlm.robots.go2 import protocol as p
from go2vlm.robots.go2.client import RpcFuture
from go2vlm.robots.go2.webrtc import codec

HEARTBEAT_S = 2.0  # the app's heartbeat period
BUSY = "busy"  # on_link reason: another WebRTC client (the Unitree app?) holds the robot
CLOSED_BY_ROBOT = "closed by the robot"  # on_link reason: the robot ended our connection (a takeover?)


class LinkError(ConfigError):
    """The robot cannot be reached over WebRTC as configured (one line, exit 2 at start)."""


class RobotBusy(LinkError):
    """The robot answered "reject": another WebRTC client holds it."""


@dataclass
class LinkSettings:
    ip: str = ""
    mode: str = "sta"  # sta: the robot on your network (ip or serial); ap: your PC on the robot's Wi-Fi
    serial: str = ""  # find the robot on the LAN by its serial number (multicast), when no ip is given
    port: int = p.SIGNAL_PORT
    legacy_port: int = p.LEGACY_SIGNAL_PORT
    aes_key: str = field(default="", repr=False)  # the robot's AES-128 key (32 hex chars): a secret
    timeout_s: float = 10.0  # signalling + ICE + validation
    link_timeout_s: float = 1.5  # nothing heard for this long: the link is down
    max_backoff_s: float = 8.0

    def device_key(self) -> bytes | None:
        if not self.aes_key:
            return None
        try:
            key = bytes.fromhex(self.aes_key.strip())
        except ValueError:
            raise LinkError("the AES key is not hex (32 hex characters)") from None
        if len(key) != 16:
            raise LinkError(f"the AES key must be 16 bytes (32 hex characters), got {len(key)} bytes")
        return key


def _restrict_fingerprints() -> None:
    """Offer only the sha-256 DTLS fingerprint, as unitree_webrtc_connect does: a Go2 that sees the
    extra digests newer aiortc lists answers in an SCTP SDP syntax aiortc does not read."""
    from aiortc import rtcdtlstransport
    from cryptography.hazmat.primitives import hashes

    rtcdtlstransport.X509_DIGEST_ALGORITHMS = {"sha-256": hashes.SHA256()}


def discover(serial: str, timeout_s: float = 2.0) -> str | None:
    """The robot's IP on the LAN from its serial number: the Go2 answers a multicast query
    {"name": "unitree_dapengche", "sn": ...} on 231.1.1.1:10131 with {"sn", "ip"} to port 10134."""
    import struct

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(("", 10134))
        mreq = struct.pack("4sl", socket.inet_aton("231.1.1.1"), socket.INADDR_ANY)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
        for query in ({"name": "unitree_dapengche"}, {"name": "unitree_dapengche", "sn": serial}):
            sock.sendto(json.dumps(query).encode(), ("231.1.1.1", 10131))
        deadline = time.monotonic() + timeout_s
        while (left := deadline - time.monotonic()) > 0:
            sock.settimeout(left)
            try:
                data, addr = sock.recvfrom(2048)
            except TimeoutError:
                break
            ip = discovery_answer(data, addr[0], serial)
            if ip is not None:
                return ip
    except OSError:
        return None
    finally:
        sock.close()
    return None


def discovery_answer(data: bytes, sender: str, serial: str) -> str | None:
    """The robot's IP from one answer to the discovery query, or None when the answer is not one: JSON
    {"sn": serial, "ip": ...} whose ip, if given, is the sender's own unicast IPv4 address (an answer
    cannot send us to a third host, a broadcast, multicast or loopback address)."""
    import ipaddress

    try:
        reply = json.loads(data.decode())
        addr = ipaddress.IPv4Address(sender)
    except (ValueError, UnicodeDecodeError, RecursionError):
        return None
    if not isinstance(reply, dict) or not serial or reply.get("sn") != serial:
        return None
    ip = reply.get("ip", sender)
    if ip != sender or addr.is_multicast or addr.is_loopback or addr.is_unspecified or str(addr).endswith(".255"):
        return None
    return sender


def port_open(ip: str, port: int, timeout_s: float = 1.5) -> bool:
    try:
        with socket.create_connection((ip, port), timeout=timeout_s):
            return True
    except OSError:
        return False


def _post(url: str, body: bytes, timeout_s: float, content_type: str) -> str:
    req = urllib.request.Request(url, data=body, method="POST", headers={"Content-Type": content_type})
    try:
        with urllib.request.urlopen(req, timeout=timeout_s) as resp:  # noqa: S310 (http to the robot)
            return resp.read(codec.MAX_SIGNAL_BYTES).decode()
    except urllib.error.HTTPError as exc:
        raise LinkError(f"the robot's signalling at {url} answered HTTP {exc.code}") from None
    except (urllib.error.URLError, OSError) as exc:
        raise LinkError(f"the robot's signalling at {url} did not answer: {exc}") from None
    except UnicodeDecodeError:
        raise LinkError(f"the robot's signalling at {url} answered bytes that are not text") from None


def exchange(settings: LinkSettings, ip: str, offer: dict[str, Any]) -> dict[str, Any]:
    """Hand the offer to the robot (port 9991, else the legacy 8081) and return its answer."""
    timeout = min(settings.timeout_s, 5.0)
    base = f"http://{ip}:{settings.port}"
    if port_open(ip, settings.port):
        notify = _post(f"{base}/con_notify", b"", timeout, "application/json")
        try:
            robot_key, path, _ = codec.parse_con_notify(notify, settings.device_key())
            body, key = codec.offer_body(offer, robot_key)
        except codec.SignalError as exc:
            raise LinkError(str(exc)) from None
        except ValueError as exc:
            raise LinkError(f"the robot's key in the signalling answer cannot be used: {exc}") from None
        text = _post(f"{base}/con_ing_{path}", body.encode(), timeout, "application/x-www-form-urlencoded")
    elif settings.legacy_port and port_open(ip, settings.legacy_port):
        key = None
        text = _post(
            f"http://{ip}:{settings.legacy_port}/offer", json.dumps(offer).encode(), timeout, "application/json"
        )
    else:
        raise LinkError(
            f"no Go2 answers at {ip}: neither signalling port {settings.port} nor {settings.legacy_port} is open "
            "(wrong IP, robot off, or not on this network)"
        )
    try:
        return codec.parse_answer(text, key)
    except codec.SignalError as exc:
        raise LinkError(str(exc)) from None


class Go2Link:
    """A WebRTC link to one Go2 (or the simulator's WebRTC server), kept up until `stop()`."""

    def __init__(
        self,
        settings: LinkSettings,
        *,
        on_message: Callable[[dict[str, Any], bytes | None], None],
        on_link: Callable[[bool, str], None],
        on_frame: Callable[[np.ndarray], None] | None = None,
        topics: tuple[str, ...] = (),
        lidar: bool = False,
        log: Any = None,
    ) -> None:
        self.settings = settings
        self.on_message = on_message
        self.on_link = on_link
        self.on_frame = on_frame
        self.topics = topics
        self.lidar = lidar
        self.log = log
        self.connected = False
        self.firmware: str | None = None
        self.ip = ""
        self.seal: int | None = None
        self.counters: dict[str, int] = {}
        self.connects = 0
        self.last_heard = 0.0  # anything from the robot: the data channel or a video frame
        self.channel_heard = 0.0  # the data channel itself (what a Move travels on)
        self.frame_log: collections.deque[tuple[int, float]] = collections.deque(maxlen=512)  # (pts, arrival)
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="go2-webrtc", daemon=True)
        self._pending: dict[int, tuple[RpcFuture, str]] = {}
        self._lock = threading.Lock()
        self._pc: Any = None
        self._channel: Any = None
        self._validated: asyncio.Event | None = None
        self._stopping = False
        self._supervisor: Any = None
        self._next_id = int(time.time() * 1000) % 2_000_000_000

    def count(self, name: str) -> None:
        self.counters[name] = self.counters.get(name, 0) + 1

    # -- lifecycle (any thread) ------------------------------------------------------------------
    def connect_first(self) -> None:
        """Connect once, synchronously; LinkError (one line) if it cannot. Then keep the link up."""
        _restrict_fingerprints()
        self._thread.start()
        fut = asyncio.run_coroutine_threadsafe(self._connect(), self._loop)
        try:
            fut.result(self.settings.timeout_s + 5.0)
        except LinkError:
            self.stop()
            raise
        except Exception as exc:
            self.stop()
            raise LinkError(f"WebRTC connection to the Go2 failed: {type(exc).__name__}: {exc}") from None
        self._supervisor = asyncio.run_coroutine_threadsafe(self._supervise(), self._loop)

    def stop(self) -> None:
        self._stopping = True
        stop_loop(self._loop, self._thread, self._close())

    # -- sending (any thread) -----------------------------------------------------------------
    def send(self, text: str) -> bool:
        if not self.connected:
            return False
        self._loop.call_soon_threadsafe(self._send_now, text)
        return True

    def new_id(self) -> int:
        with self._lock:
            self._next_id = (self._next_id + 1) % 2_000_000_000
            return self._next_id

    def request(
        self,
        topic: str,
        api_id: int,
        parameter: str | dict[str, Any] = "",
        *,
        timeout_s: float = 1.0,
        reply: bool = True,
        request_id: int | None = None,
    ) -> RpcFuture:
        """A request on `topic` (rt/api/<service>/request); the future gets the answer, or
        ERR_CLIENT_SEND at once while the link is down, or ERR_CLIENT_API_TIMEOUT."""
        rid = self.new_id() if request_id is None else request_id
        future = RpcFuture(api_id, rid, time.monotonic() + timeout_s)
        text = json.dumps(parameter) if isinstance(parameter, dict) else parameter
        data = {"header": {"identity": {"id": rid, "api_id": api_id}}, "parameter": text}
        if not self.connected:
            future.set_result(p.RpcResult(p.ERR_CLIENT_SEND))
            return future
        if reply:
            with self._lock:
                self._pending[rid] = (future, topic)
        self._loop.call_soon_threadsafe(self._send_now, codec.message(p.DC_REQUEST, topic, data))
        if not reply:
            future.set_result(p.RpcResult(p.OK))
        return future

    # -- the loop's side --------------------------------------------------------------------------
    def _send_now(self, text: str) -> None:
        ch = self._channel
        if ch is not None and ch.readyState == "open":
            try:
                ch.send(text)
            except Exception:
                self.count("send_errors")

    def _ip(self) -> str:
        s = self.settings
        if s.mode == "ap":
            return p.AP_IP
        if s.ip:
            return s.ip
        if s.serial:
            ip = discover(s.serial)
            if ip is None:
                raise LinkError(f"no Go2 with serial number {s.serial} answered on this network; give its ip")
            return ip
        raise LinkError("transport=webrtc needs ip, or serial, or mode=ap")

    async def _connect(self) -> None:
        from aiortc import RTCConfiguration, RTCPeerConnection, RTCSessionDescription

        self.ip = await asyncio.to_thread(self._ip)
        pc = RTCPeerConnection(RTCConfiguration(iceServers=[]))
        self._pc = pc
        self._validated = asyncio.Event()
        channel = pc.createDataChannel("data")
        self._channel = channel
        pc.addTransceiver("video", direction="recvonly")
        pc.addTransceiver("audio", direction="recvonly")
        channel.on("message", self._on_message)

        def closed() -> None:
            if self._pc is pc:
                self._lost(f"{CLOSED_BY_ROBOT}: data channel closed")

        channel.on("close", closed)

        @pc.on("track")
        def on_track(track: Any) -> None:
            if track.kind == "video":
                asyncio.ensure_future(self._read_video(track))

        @pc.on("connectionstatechange")
        def on_state() -> None:
            if self._pc is pc and pc.connectionState == "closed":
                self._lost(f"{CLOSED_BY_ROBOT}: peer connection closed")
            elif self._pc is pc and pc.connectionState == "failed":
                self._lost("peer connection failed")

        await pc.setLocalDescription(await pc.createOffer())
        offer = {"id": "" if self.settings.mode == "ap" else "STA_localNetwork", "sdp": pc.localDescription.sdp}
        offer.update(type="offer", token="")
        answer = await asyncio.to_thread(exchange, self.settings, self.ip, offer)
        if answer["sdp"] == "reject":
            await pc.close()
            raise RobotBusy(
                f"the Go2 at {self.ip} is held by another WebRTC client (the Unitree app?): close it and try again"
            )
        try:
            await pc.setRemoteDescription(RTCSessionDescription(sdp=answer["sdp"], type="answer"))
        except Exception as exc:
            await pc.close()
            raise LinkError(f"the Go2's SDP answer cannot be used: {type(exc).__name__}: {exc}") from None
        try:
            await asyncio.wait_for(self._validated.wait(), self.settings.timeout_s)
        except asyncio.TimeoutError:
            state = f"peer {pc.connectionState}, ice {pc.iceConnectionState}, channel {channel.readyState}"
            await pc.close()
            raise LinkError(f"the Go2 at {self.ip} did not complete the WebRTC handshake in time ({state})") from None
        self.connects += 1
        self.last_heard = self.channel_heard = time.monotonic()  # it validated over the data channel
        self.connected = True
        for topic in self.topics:
            self._send_now(codec.message(p.DC_SUBSCRIBE, topic))
        if self.lidar:
            self._send_now(
                codec.message(p.DC_RTC_INNER_REQ, data={"req_type": "disable_traffic_saving", "instruction": "on"})
            )
            self._send_now(codec.message(p.DC_MSG, p.RTC_LIDAR_SWITCH, "on"))
        if self.on_frame is not None:
            self._send_now(codec.message(p.DC_VIDEO, "", "on"))
        self.on_link(True, f"connected to {self.ip}")
        self._ask_firmware()

    def _ask_firmware(self) -> None:
        def got(result: p.RpcResult) -> None:
            version = None
            if result.ok:
                try:
                    info = json.loads(result.data)
                    version = info.get("info") if isinstance(info, dict) else None
                except ValueError:
                    version = result.data
            self.firmware = str(version).strip() if version else None
            self.on_message({"type": "firmware", "data": self.firmware, "code": result.code}, None)

        fut = self.request(p.RTC_BASH_REQUEST, p.BASH_RUN_SCRIPT, {"script": p.VERSION_SCRIPT}, timeout_s=3.0)
        fut.add_done_callback(got)

    async def _read_video(self, track: Any) -> None:
        from aiortc.mediastreams import MediaStreamError

        try:
            while True:
                frame = await track.recv()
                self.last_heard = time.monotonic()
                self.frame_log.append((int(frame.pts or 0), self.last_heard))
                if self.on_frame is not None:
                    self.on_frame(frame.to_ndarray(format="bgr24"))
        except MediaStreamError:
            return
        except Exception as exc:
            self.count("video_errors")
            if self.log is not None:
                self.log.throttled("error", 2.0, f"video track failed: {type(exc).__name__}: {exc}")

    def _on_message(self, raw: str | bytes) -> None:
        self.last_heard = self.channel_heard = time.monotonic()
        try:
            msg, payload = codec.decode(raw)
        except ValueError as exc:
            self.count("bad_messages")
            if self.log is not None:
                self.log.throttled("error", 2.0, f"dropped a malformed data-channel message: {exc}", key="dc-bad")
            return
        kind = msg["type"]
        if kind == p.DC_VALIDATION:
            if msg.get("data") == p.VALIDATION_OK:
                if self._validated is not None:
                    self._validated.set()
            elif isinstance(msg.get("data"), str):
                self._send_now(codec.message(p.DC_VALIDATION, "", codec.validation_reply(msg["data"])))
            return
        if kind == p.DC_RESPONSE:
            self._on_response(msg)
            return
        if kind in (p.DC_HEARTBEAT, p.DC_ERR) or kind in p.DC_ERRORS:
            return
        try:
            self.on_message(msg, payload)
        except Exception as exc:
            self.count("handler_errors")
            if self.log is not None:
                self.log.throttled("error", 2.0, f"data-channel handler failed: {type(exc).__name__}: {exc}")

    def _on_response(self, msg: dict[str, Any]) -> None:
        data: Any = msg.get("data")  # JSON from the robot, checked below
        try:
            header = data["header"]
            rid = int(header["identity"]["id"])
            api = int(header["identity"]["api_id"])
            code = int(header["status"]["code"])
        except (KeyError, TypeError, ValueError):
            self.count("bad_messages")
            return
        with self._lock:
            entry = self._pending.pop(rid, None)
        if entry is None:
            self.count("foreign_responses")  # a reply to a fire-and-forget Move, or one after its timeout
            return
        future, _ = entry
        text = data.get("data", "") if isinstance(data.get("data", ""), str) else json.dumps(data.get("data"))
        future.set_result(p.RpcResult(code, text) if api == future.api_id else p.RpcResult(p.ERR_CLIENT_API_NOT_MATCH))

    def _lost(self, reason: str) -> None:
        if self.connected:
            self.connected = False
            self._fail_pending()
            self.on_link(False, reason)

    def _fail_pending(self) -> None:
        with self._lock:
            pending, self._pending = list(self._pending.values()), {}
        for future, _ in pending:
            future.set_result(p.RpcResult(p.ERR_CLIENT_SEND))

    async def _close(self) -> None:
        if self._supervisor is not None:
            self._supervisor.cancel()
        self.connected = False
        self._fail_pending()
        if self._pc is not None:
            try:
                await self._pc.close()
            except Exception:
                pass

    async def _supervise(self) -> None:
        """Heartbeat, request timeouts, link watchdog; reconnect with backoff after a drop."""
        next_beat = time.monotonic()
        backoff = 0.5
        while not self._stopping:
            await asyncio.sleep(0.05)
            now = time.monotonic()
            with self._lock:
                late = [rid for rid, (f, _) in self._pending.items() if f.deadline <= now]
                expired = [self._pending.pop(rid)[0] for rid in late]
            for future in expired:
                future.set_result(p.RpcResult(p.ERR_CLIENT_API_TIMEOUT))
            if self.connected:
                backoff = 0.5
                if now >= next_beat:
                    next_beat = now + HEARTBEAT_S
                    t = time.time()
                    beat = {"timeInStr": time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(t)), "timeInNum": int(t)}
                    self._send_now(codec.message(p.DC_HEARTBEAT, "", beat))
                if now - self.last_heard > self.settings.link_timeout_s:
                    self._lost(f"nothing heard for {self.settings.link_timeout_s:g} s")
                continue
            if self._pc is not None:
                try:
                    await self._pc.close()
                except Exception:
                    pass
                self._pc = None
            await asyncio.sleep(backoff)
            if self._stopping:
                return
            try:
                await self._connect()
            except RobotBusy as exc:
                self.on_link(False, f"{BUSY}: {exc}")
                backoff = min(backoff * 2, self.settings.max_backoff_s)
            except Exception as exc:
                self.on_link(False, f"reconnect failed ({one_line(exc)}); next try in {backoff * 2:g} s")
                backoff = min(backoff * 2, self.settings.max_backoff_s)


def stop_loop(loop: asyncio.AbstractEventLoop, thread: threading.Thread, closing: Any = None) -> None:
    """Run `closing` (a coroutine: close the peer connections) on the loop's thread, then stop the
    loop and join its thread; each step at most 3 s (wall)."""
    if not thread.is_alive():
        if closing is not None:
            closing.close()
        return
    if closing is not None:
        try:
            asyncio.run_coroutine_threadsafe(closing, loop).result(3.0)
        except Exception:
            pass
    loop.call_soon_threadsafe(loop.stop)
    thread.join(3.0)


def one_line(exc: BaseException) -> str:
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__
