"""The simulator's side of the Go2's WebRTC service: what a Go2 AIR/PRO/EDU serves to the Unitree app.

Like the robot's own WebRTC service, it is a relay between one WebRTC peer and the robot's DDS topics:
the sim's Unitree bridge (robots/go2_sim/unitree_bridge.py) stays the one place that obeys sport
requests, so the rules of the DDS route (Move only in balance stand, the 1 s Move timeout, the stop
lane, answers that mean "applied", the e-stop latch) hold here too.

Signalling (HTTP, `host`:`port`, default 127.0.0.1:9991; and the legacy /offer on `legacy_port`):
  POST /con_notify          -> base64 {"data1": the RSA key and the next path, sealed (`seal`), "data2"}
  POST /con_ing_<path>      -> the sealed offer in, the sealed SDP answer out (robots/go2/webrtc/codec.py)
  POST /offer (legacy port) -> the same in plain text
  A request whose Host is a DNS name (not an IP address or localhost: DNS rebinding) is refused with
  421; a Content-Length that is not a number of bytes with 400, over MAX_SIGNAL_BYTES with 413.
  One peer at a time, as on the robot: a second offer is answered {"sdp": "reject"}, unless
  `takeover` (then the new peer replaces the old one, as the phone app taking the robot over).
Data channel "data" (JSON, protocol.DC_*): validation first (the key, then base64 md5), then
  req  rt/api/sport/request        -> published on DDS rt/api/sport/request; the bridge's answer on
                                      rt/api/sport/response goes back as "res" (Move is answered too)
  req  rt/api/bashrunner/request   -> get_whole_packet_version.sh answers `firmware`; other scripts 3203
  subscribe rt/sportmodestate, rt/lf/sportmodestate  <- DDS rt/sportmodestate (lf: at most 20 Hz)
  subscribe rt/lowstate, rt/lf/lowstate              <- DDS rt/lowstate (the sim's /lowstate)
  subscribe rt/utlidar/voxel_map_compressed          <- DDS rt/utlidar/cloud as an LZ4 voxel map in the
                                                        odom frame, once "rt/utlidar/switch" is "on"
  subscribe rt/api/sport/request   <- every sport request on DDS (the peer's own included): others'
                                      requests are how a client sees a second controller
  vid "on"/"off"                   -> the video track: the head camera (/camera/image_raw), H.264
  heartbeat, rtc_inner_req (public_network_status, disable_traffic_saving) are answered.
Malformed messages are counted (`webrtc_bad_messages`) and dropped; the server keeps serving.

Threads: DDS callbacks run on the sim node's executor; the peer connection, the data channel and the
video track on the server's own asyncio loop; each HTTP request on a thread of the HTTP server.
Time: wall time throughout (network timeouts, the lf decimation); stamps come from the sim.
"""

from __future__ import annotations

import asyncio
import collections
import fractions
import json
import secrets
import threading
import time
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import numpy as np

from go2vlm.bus import QOS_UNITREE_READER, QOS_UNITREE_WRITER, Node
from go2vlm.bus.topics import CAMERA_IMAGE, LIDAR_CLOUD, LOWSTATE
from go2vlm.errors import ConfigError
from go2vlm.geometry.rotations import quat_to_mat
from go2vlm.geometry.scan import to_base
from go2vlm.msgs.image import image_to_numpy
from go2vlm.msgs.pointcloud import cloud_xyz
from go2vlm.msgs.sensor_msgs import Image, PointCloud2
from go2vlm.msgs.unitree import LowState, Request, Response, SportModeState
from go2vlm.robot_profile import RobotProfile
from go2vlm.robots.go2 import protocol as p
from go2vlm.robots.go2.webrtc import codec
from go2vlm.robots.go2.webrtc.link import stop_loop

LF_PERIOD_S = 0.05  # the rt/lf/* copies at most 20 Hz
MAX_PENDING = 1024  # sport requests waiting for the bridge's answer


class _Peer:
    """One connected client: its peer connection, data channel and what it asked for."""

    def __init__(self, pc: Any, silent: Callable[[], bool] = lambda: False) -> None:
        self.pc = pc
        self.silent = silent  # () -> True while the data channel is to say nothing (a fault drill)
        self.channel: Any = None
        self.key = secrets.token_hex(8)
        self.validated = False
        self.topics: set[str] = set()
        self.lidar = False
        self.video = False
        self.last_lf: dict[str, float] = {}
        self.sent_frames: collections.deque[tuple[int, float]] = collections.deque(maxlen=512)  # (pts, frame in)

    @property
    def alive(self) -> bool:
        return self.pc.connectionState not in ("closed", "failed")

    def send(self, data: str | bytes) -> None:
        ch = self.channel
        if ch is not None and ch.readyState == "open" and not self.silent():
            try:
                ch.send(data)
            except Exception:
                pass


class SimWebRtcServer:
    """Serve the Go2's WebRTC signalling, data channel and video on `host`, relaying the sim's DDS topics
    (`robot`: the sim's profile, where its lowstate and lidar cloud are published)."""

    def __init__(
        self,
        node: Node,
        robot: RobotProfile,
        *,
        host: str = "127.0.0.1",
        port: int = p.SIGNAL_PORT,
        legacy_port: int = 0,
        seal: int = p.SEAL_STATIC,
        aes_key: str = "",
        firmware: str = p.SIM_FIRMWARE,
        takeover: bool = False,
    ) -> None:
        if seal not in p.SIGNAL_SEALS:
            raise ConfigError(f"webrtc_seal must be one of {sorted(p.SIGNAL_SEALS)}, got {seal}")
        self.device_key = bytes.fromhex(aes_key) if aes_key else None
        if seal == p.SEAL_DEVICE and (self.device_key is None or len(self.device_key) != 16):
            raise ConfigError("webrtc_seal 3 needs the robot's AES key (32 hex characters): $GO2VLM_AES_KEY or "
                              "webrtc_aes_key_file")  # fmt: skip
        self.node = node
        self.seal = seal
        self.firmware = firmware
        self.takeover = takeover
        self.peer: _Peer | None = None
        self.counters: dict[str, int] = {}
        self._paths: dict[str, float] = {}
        self._pending: dict[int, _Peer] = {}
        self._lock = threading.Lock()
        self._state: SportModeState | None = None
        self._frame: np.ndarray | None = None
        self._frame_seq = 0
        self._frame_time = 0.0  # when the newest camera frame reached the server (wall)
        self._key = codec.new_robot_key()
        self._lidar_frame = robot.lidar.frame
        self._lidar_tf = robot.lidar_transforms()[robot.lidar.frame]

        self.pub_request = node.create_publisher(Request, p.request_topic(p.SPORT_SERVICE), QOS_UNITREE_WRITER)
        node.create_subscription(Response, p.response_topic(p.SPORT_SERVICE), self._on_response, QOS_UNITREE_READER)
        node.create_subscription(Request, p.request_topic(p.SPORT_SERVICE), self._on_dds_request, QOS_UNITREE_READER)
        node.create_subscription(SportModeState, p.SPORT_STATE_TOPIC, self._on_state, QOS_UNITREE_READER)
        LOWSTATE.subscription(node, self._on_lowstate, name=robot.health_topic)
        LIDAR_CLOUD.subscription(node, self._on_cloud, name=robot.lidar.topic)
        CAMERA_IMAGE.subscription(node, self._on_image)

        self._loop = asyncio.new_event_loop()
        self._frame_ready = asyncio.Event()
        self._loop_thread = threading.Thread(target=self._loop.run_forever, name="sim-webrtc", daemon=True)
        self._loop_thread.start()
        self._http: list[ThreadingHTTPServer] = []
        for http_port, legacy in ((port, False), (legacy_port, True)):
            if legacy and not http_port:
                continue
            try:
                server = ThreadingHTTPServer((host, http_port), _handler(self, legacy))
            except OSError as exc:
                self.close()
                raise ConfigError(f"cannot serve WebRTC signalling on {host}:{http_port}: {exc.strerror}") from None
            server.daemon_threads = True
            threading.Thread(target=server.serve_forever, name=f"sim-webrtc-http:{http_port}", daemon=True).start()
            self._http.append(server)
        self.address = (host, port)
        node.log.info(f"WebRTC signalling on http://{host}:{port} (data2={seal}, firmware {firmware})")

    def count(self, name: str) -> None:
        self.counters[name] = self.counters.get(name, 0) + 1
        self.node.count(f"webrtc_{name}")

    def close(self) -> None:
        for server in self._http:
            server.shutdown()
            server.server_close()
        stop_loop(self._loop, self._loop_thread, None if self.peer is None else self.peer.pc.close())

    def status(self) -> dict[str, Any]:
        peer = self.peer
        return {
            "peer": None if peer is None else {"state": peer.pc.connectionState, "validated": peer.validated},
            "counters": dict(self.counters),
        }

    # -- signalling (HTTP threads) -------------------------------------------------------------
    def con_notify(self) -> str:
        path = f"{secrets.randbelow(100000):05d}"
        now = time.monotonic()
        with self._lock:
            self._paths = {k: t for k, t in self._paths.items() if now - t < 30.0}
            self._paths[path] = now
        return codec.con_notify_body(self._key, path, self.seal, self.device_key)

    def con_ing(self, path: str, body: bytes) -> str:
        with self._lock:
            known = self._paths.pop(path, None) is not None
        if not known:
            raise codec.SignalError(f"unknown path con_ing_{path}")
        offer, key = codec.open_offer(body, self._key)
        return codec.aes_encrypt(json.dumps(self.answer(offer)), key)

    def answer(self, offer: dict[str, Any]) -> dict[str, Any]:
        return asyncio.run_coroutine_threadsafe(self._answer(offer), self._loop).result(20.0)

    # -- the peer (loop thread) ------------------------------------------------------------------
    async def _answer(self, offer: dict[str, Any]) -> dict[str, Any]:
        from aiortc import RTCPeerConnection, RTCSessionDescription

        old = self.peer
        if old is not None and old.alive:
            if not self.takeover:
                self.count("rejected_offers")
                self.node.log.warning("a second WebRTC client asked for the robot: rejected (one peer at a time)")
                return {"sdp": "reject", "type": "answer"}
            self.node.log.warning("a new WebRTC client takes the robot over; the old one is dropped")
            await old.pc.close()
        pc = RTCPeerConnection()
        peer = _Peer(pc, lambda: bool(getattr(self.node.config, "fault_webrtc_silent", False)))
        self.peer = peer

        @pc.on("datachannel")
        def on_channel(channel: Any) -> None:
            peer.channel = channel
            channel.on("message", lambda raw: self._on_message(peer, raw))
            peer.send(codec.message(p.DC_VALIDATION, "", peer.key))

        @pc.on("connectionstatechange")
        def on_state() -> None:
            self.node.log.info(f"WebRTC peer: {pc.connectionState}")

        try:
            await pc.setRemoteDescription(RTCSessionDescription(sdp=offer["sdp"], type="offer"))
        except Exception as exc:
            self.count("bad_offers")
            await pc.close()
            raise codec.SignalError(f"offer SDP rejected: {exc}") from None
        track = _CameraTrack(self, peer)
        for transceiver in pc.getTransceivers():
            if transceiver.kind == "video":
                pc.addTrack(track)
                _prefer_h264(transceiver)
        await pc.setLocalDescription(await pc.createAnswer())
        return {"sdp": pc.localDescription.sdp, "type": "answer"}

    def _on_message(self, peer: _Peer, raw: str | bytes) -> None:
        try:
            msg, _ = codec.decode(raw)
        except ValueError as exc:
            self.count("bad_messages")
            self.node.log.throttled("error", 2.0, f"WebRTC: dropped a malformed message: {exc}", key="webrtc-bad")
            return
        kind, topic, data = msg["type"], msg.get("topic", ""), msg.get("data")
        if kind == p.DC_VALIDATION:
            if data == codec.validation_reply(peer.key):
                peer.validated = True
                peer.send(codec.message(p.DC_VALIDATION, "", p.VALIDATION_OK))
            else:
                self.count("bad_validation")
                peer.send(codec.message(p.DC_ERR, "", info=p.VALIDATION_NEEDED))
            return
        if not peer.validated:
            self.count("unvalidated_messages")
            peer.send(codec.message(p.DC_ERR, "", info=p.VALIDATION_NEEDED))
            return
        if kind == p.DC_HEARTBEAT:
            peer.send(codec.message(p.DC_HEARTBEAT, "", data))
        elif kind == p.DC_SUBSCRIBE and isinstance(topic, str) and topic:
            peer.topics.add(topic)
        elif kind == p.DC_UNSUBSCRIBE and isinstance(topic, str):
            peer.topics.discard(topic)
        elif kind == p.DC_VIDEO:
            peer.video = str(data).lower() == "on"
        elif kind == p.DC_MSG and topic == p.RTC_LIDAR_SWITCH:
            peer.lidar = str(data).lower() == "on"
        elif kind == p.DC_RTC_INNER_REQ and isinstance(data, dict):
            self._inner(peer, data)
        elif kind == p.DC_REQUEST:
            self._request(peer, topic, data)
        elif kind != p.DC_AUDIO:
            self.count("unhandled_messages")

    def _inner(self, peer: _Peer, data: dict[str, Any]) -> None:
        req = data.get("req_type")
        if req == "public_network_status":
            info = {"req_type": req, "uuid": data.get("uuid"), "status": "NetworkStatus.ON_WIFI_CONNECTED"}
        elif req == "disable_traffic_saving":
            info = {"req_type": req, "execution": "ok"}
        else:
            self.count("unhandled_messages")
            return
        peer.send(codec.message(p.DC_RTC_INNER_REQ, "", info=info))

    def _request(self, peer: _Peer, topic: Any, data: Any) -> None:
        try:
            ident = data["header"]["identity"]
            rid, api = int(ident["id"]), int(ident["api_id"])
            parameter = data.get("parameter", "")
            if not isinstance(parameter, str):
                parameter = json.dumps(parameter)
        except (KeyError, TypeError, ValueError):
            self.count("bad_messages")
            self.node.log.throttled("error", 2.0, f"WebRTC: dropped a request without header.identity on {topic!r}")
            return
        if topic == p.RTC_SPORT_REQUEST:
            with self._lock:
                if len(self._pending) >= MAX_PENDING:
                    self._pending.pop(next(iter(self._pending)))
                self._pending[rid] = peer
            self.pub_request.publish(p.build_request(api, parameter, request_id=rid))
            return
        reply_topic = topic.replace("/request", "/response") if isinstance(topic, str) else ""
        code, text = p.ERR_SERVER_API_NOT_IMPL, ""
        if topic == p.RTC_BASH_REQUEST and api == p.BASH_RUN_SCRIPT:
            try:
                script = json.loads(parameter).get("script")
            except (ValueError, AttributeError):
                script = None
            if script == p.VERSION_SCRIPT:
                code, text = p.OK, json.dumps({"result": "ok", "info": self.firmware})
        peer.send(codec.message(p.DC_RESPONSE, reply_topic, _response_data(rid, api, code, text)))

    # -- DDS side (the sim node's executor thread) -------------------------------------------------
    def _to_peer(self, topic: str, make: Any) -> None:
        """Send `make()` on `topic` to the peer if it subscribed (the rt/lf/ copy at most 20 Hz)."""
        peer = self.peer
        if peer is None or not peer.validated:
            return
        lf = topic.replace("rt/", "rt/lf/", 1)
        now = time.monotonic()
        wants = [t for t in (topic, lf) if t in peer.topics]
        if lf in wants and now - peer.last_lf.get(lf, 0.0) < LF_PERIOD_S:
            wants.remove(lf)
        if not wants:
            return
        data = make()
        for t in wants:
            if t == lf:
                peer.last_lf[lf] = now
            self._loop.call_soon_threadsafe(peer.send, codec.message(p.DC_MSG, t, data))

    def _on_state(self, msg: SportModeState) -> None:
        self._state = msg
        self._to_peer(p.RTC_SPORT_STATE, lambda: codec.to_jsonable(msg))

    def _on_lowstate(self, msg: LowState) -> None:
        self._to_peer(p.RTC_LOW_STATE, lambda: codec.to_jsonable(msg))

    def _on_dds_request(self, req: Request) -> None:
        peer = self.peer
        if peer is not None and peer.validated and p.RTC_SPORT_REQUEST in peer.topics:
            data = {"header": codec.to_jsonable(req.header), "parameter": req.parameter}
            self._loop.call_soon_threadsafe(peer.send, codec.message(p.DC_MSG, p.RTC_SPORT_REQUEST, data))

    def _on_response(self, resp: Response) -> None:
        rid = int(resp.header.identity.id)
        with self._lock:
            peer = self._pending.pop(rid, None)
        if peer is None:
            return  # a DDS client's answer
        data = _response_data(rid, int(resp.header.identity.api_id), int(resp.header.status.code), resp.data)
        self._loop.call_soon_threadsafe(peer.send, codec.message(p.DC_RESPONSE, p.RTC_SPORT_RESPONSE, data))

    def _on_cloud(self, msg: PointCloud2) -> None:
        peer, state = self.peer, self._state
        if peer is None or not peer.validated or not peer.lidar or state is None:
            return
        if p.RTC_LIDAR_VOXELS not in peer.topics or msg.header.frame_id != self._lidar_frame:
            return
        base = to_base(cloud_xyz(msg), self._lidar_tf)
        base = base[np.isfinite(base).all(axis=1)]
        rot = quat_to_mat(np.array([float(v) for v in state.imu_state.quaternion]))
        pos = np.array([float(v) for v in state.position])
        world = base @ rot.T + pos
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        header, payload = codec.voxelize(world, pos, stamp)
        frame = codec.encode_binary({"type": p.DC_MSG, "topic": p.RTC_LIDAR_VOXELS, "data": header}, payload)
        self._loop.call_soon_threadsafe(peer.send, frame)

    def _on_image(self, msg: Image) -> None:
        peer = self.peer
        if peer is None or not peer.video:
            return
        rgb = image_to_numpy(msg)
        if msg.encoding == "bgr8":
            rgb = rgb[:, :, ::-1]
        self._frame = np.ascontiguousarray(rgb)
        self._frame_time = time.monotonic()
        self._frame_seq += 1
        self._loop.call_soon_threadsafe(self._frame_ready.set)


def _response_data(rid: int, api: int, code: int, text: str) -> dict[str, Any]:
    return {"header": {"identity": {"id": rid, "api_id": api}, "status": {"code": code}}, "data": text}


def _prefer_h264(transceiver: Any) -> None:
    """The Go2 sends its camera as H.264: offer that first where the client can take it."""
    from aiortc import RTCRtpSender

    codecs = RTCRtpSender.getCapabilities("video").codecs
    h264 = [c for c in codecs if c.mimeType == "video/H264"]
    if h264:
        transceiver.setCodecPreferences(h264 + [c for c in codecs if c.mimeType != "video/H264"])


def _camera_track_class() -> type:
    from aiortc import MediaStreamTrack

    class CameraTrack(MediaStreamTrack):
        """The head camera as a video track: each new /camera/image_raw frame once, while video is on."""

        kind = "video"

        def __init__(self, server: SimWebRtcServer, peer: _Peer) -> None:
            super().__init__()
            self.server = server
            self.peer = peer
            self.seq = 0
            self.t0 = time.monotonic()

        async def recv(self) -> Any:
            import av

            server = self.server
            while server._frame is None or server._frame_seq == self.seq or not self.peer.video:
                server._frame_ready.clear()
                await server._frame_ready.wait()
            self.seq = server._frame_seq
            frame = av.VideoFrame.from_ndarray(server._frame, format="rgb24")
            frame.pts = int((time.monotonic() - self.t0) * 90000)
            frame.time_base = fractions.Fraction(1, 90000)
            self.peer.sent_frames.append((frame.pts, server._frame_time))
            return frame

    return CameraTrack


def _CameraTrack(server: SimWebRtcServer, peer: _Peer) -> Any:  # noqa: N802 (a class built lazily)
    return _camera_track_class()(server, peer)


def host_is_literal(host: str) -> bool:
    """A Host header that names no DNS name: an IP address or localhost, with or without a port. A web
    page's request after DNS rebinding carries the attacker's name and is refused."""
    import ipaddress

    name = host.strip()
    if name.startswith("["):
        name = name[1 : name.find("]")] if "]" in name else ""
    elif name.count(":") == 1:
        name = name.split(":")[0]
    if name == "localhost":
        return True
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def _handler(server: SimWebRtcServer, legacy: bool) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 (the base class's name)
            pass  # the node logs what matters

        def _reply(self, code: int, text: str) -> None:
            body = text.encode()
            self.send_response(code)
            self.send_header("Content-Type", "text/plain")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def do_POST(self) -> None:  # noqa: N802 (http.server's name)
            if not host_is_literal(self.headers.get("Host") or ""):
                server.count("bad_signals")
                self._reply(421, "the Host header must be an IP address or localhost (DNS rebinding)")
                return
            text = (self.headers.get("Content-Length") or "0").strip()
            length = int(text) if text.isascii() and text.isdigit() else -1
            if length < 0:
                server.count("bad_signals")
                self._reply(400, "Content-Length must be a number of bytes")
                return
            if length > codec.MAX_SIGNAL_BYTES:
                server.count("bad_signals")
                self._reply(413, "too large")
                return
            body = self.rfile.read(length)
            try:
                if legacy and self.path == "/offer":
                    offer = codec.check_offer(json.loads(body.decode()))
                    self._reply(200, json.dumps(server.answer(offer)))
                elif not legacy and self.path == "/con_notify":
                    self._reply(200, server.con_notify())
                elif not legacy and self.path.startswith("/con_ing_"):
                    self._reply(200, server.con_ing(self.path[len("/con_ing_") :], body))
                else:
                    self._reply(404, "not found")
            except (codec.SignalError, ValueError) as exc:
                server.count("bad_signals")
                server.node.log.throttled("error", 2.0, f"WebRTC signalling: {exc}", key="webrtc-signal")
                self._reply(400, str(exc))
            except Exception as exc:
                server.count("bad_signals")
                server.node.log.throttled("error", 2.0, f"WebRTC signalling failed: {type(exc).__name__}: {exc}")
                self._reply(500, "internal error")

    return Handler
