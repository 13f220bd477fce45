"""view: a Foxglove WebSocket server (foxglove-sdk) that shows the robot live in Foxglove (or
Lichtblick): `go2vlm view`, or `--foxglove` on `go2vlm launch | run | sim`.

Serves ws://host:port (protocol foxglove.sdk.v1), 127.0.0.1:8765 by default; another address only
when asked (`host`, `--foxglove-host`). Open it in Foxglove with "Open connection -> Foxglove
WebSocket" and load docs/foxglove/go2vlm_layout.json.

Topics (every one only while a client subscribes to its channel: no client, no cost)
  subscribes  every topic on the bus whose type go2vlm knows, forwarded as it came off the wire (raw
              CDR, schema ros2msg, so Foxglove decodes /tf, /odom, /cmd_vel, /safety/status ...
              natively, /map and /map/costmap nav_msgs/OccupancyGrid and the commander's /plan
              nav_msgs/Path drawn in the 3D panel, latched ones too), QoS adapted to the publishers,
              keep-last 5; except:
              sensor_msgs/Image topics: sent as `<topic>/compressed` sensor_msgs/CompressedImage
              (JPEG, jpeg_quality) at most max_image_hz, same header (stamp, frame_id)
              vlm_topic (/vlm/detections, vision_msgs/Detection2DArray) -> also
              `<vlm_topic>/annotations` foxglove.ImageAnnotations: a box and a `label score` text per
              detection, in the image's pixels
              target_topic (/detected_target, geometry_msgs/PointStamped, normalised x, y, size) ->
              also `<target_topic>/annotations`: a circle and an `x=+0.12` label, scaled to the
              size of the last image or camera_info seen
  serves      /view/robot  foxglove.SceneUpdate: a Go2-sized box on base_frame (base_link), every
              second, for the 3D panel (with /tf)
  publishes   nothing by default. With allow_client_publish (`go2vlm view --publish`), for clients
              that came in with the token (capability clientPublish), only these topics and types:
                /emergency_stop          std_msgs/Bool    (reliable): true only: a client engages the
                                         e-stop, never releases it (false is refused)
                /teleop/cmd_vel          geometry_msgs/Twist (reliable)
                /mcp/confirm             std_msgs/String  (reliable): "yes <id>" for /mcp/pending
              client messages in cdr or json encoding; anything else a client advertises or sends
              (/cmd_vel and /emergency_stop/release included: the release stays `go2vlm estop
              --release` at the robot's terminal) is refused, logged and counted
              (client_publish_refused), and the client is told so in a status message

Who may connect (apps/view/front.py): with publishing off, the SDK serves host:port and offers no
publishing at all. With it on, host:port is a front door that lets a WebSocket handshake in only
with the token (`?token=` in the URL, or `Authorization: Bearer`; from $GO2VLM_VIEW_TOKEN or
token_file, at least 16 characters, never a parameter or the command line) and, from a browser, an
Origin in allowed_origins; refused ones are counted (client_refused) with the reason in the log.
The SDK itself then listens on a loopback port of its own, and publishes only for clients whose
connection came through the front door.
"""

from __future__ import annotations

import json
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication

from go2vlm.apps.view.front import TOKEN_ENV, FrontDoor, Handshake
from go2vlm.bus import Node, ParamError, Publisher, QosProfile, RawSample, Subscription, param
from go2vlm.bus.domain import ros_topic_name
from go2vlm.bus.graph import profile_of
from go2vlm.bus.topics import (
    CAMERA_INFO,
    DETECTED_TARGET,
    EMERGENCY_STOP,
    ESTOP_RELEASE,
    MCP_CONFIRM,
    TELEOP_CMD_VEL,
    TOPICS,
    VLM_DETECTIONS,
)
from go2vlm.errors import ConfigError
from go2vlm.msgs import get_type
from go2vlm.msgs.convert import from_dict
from go2vlm.msgs.geometry_msgs import PointStamped
from go2vlm.msgs.msgdef import msgdef, ros_type
from go2vlm.msgs.sensor_msgs import CameraInfo, CompressedImage, Image
from go2vlm.msgs.vision_msgs import Detection2DArray, best_hypothesis, box_corners
from go2vlm.robot_profile.go2 import SIM
from go2vlm.secret import MIN_TOKEN_CHARS, read_secret

if TYPE_CHECKING:
    from foxglove.websocket import ServerListener

__all__ = ["CLIENT_TOPICS", "ViewConfig", "ViewNode"]

# What a Foxglove client may publish (with allow_client_publish and the token): the e-stop (engage
# only), teleop and a person's yes to an MCP agent's goal (`go2vlm mcp --confirm`); nothing else:
# never /cmd_vel, never the e-stop's release (a deliberate act at the robot's terminal).
CLIENT_TOPICS: dict[str, type] = {t.name: t.type for t in (EMERGENCY_STOP, TELEOP_CMD_VEL, MCP_CONFIRM)}
ROBOT_TOPIC = "/view/robot"
GO2_BOX = (SIM.footprint_length, SIM.footprint_width, 0.40)  # metres: the Go2 standing, as one box


@dataclass
class ViewConfig:
    host: str = param("127.0.0.1", help="address to serve on; 127.0.0.1 = this machine only")
    port: int = param(8765, help="WebSocket port (0: any free port)", min=0, max=65535)
    jpeg_quality: int = param(80, help="JPEG quality of forwarded camera images", min=10, max=100)
    max_image_hz: float = param(10.0, help="images per second per camera topic, at most", min=0.1, max=60.0)
    vlm_topic: str = param(VLM_DETECTIONS.name, help="vision_msgs/Detection2DArray to draw as image annotations")
    target_topic: str = param(DETECTED_TARGET.name, help="geometry_msgs/PointStamped (normalised) to draw")
    camera_info_topic: str = param(CAMERA_INFO.name, help="image size for target annotations")
    base_frame: str = param("base_link", help="frame of the robot box in /view/robot")
    exclude: list[str] = param(list, help="topics never forwarded")
    allow_client_publish: bool = param(
        False, help="let clients with the token publish the e-stop (engage only), teleop and /mcp/confirm"
    )
    token_file: str = param(
        "", help=f"with allow_client_publish: a file whose first line is the clients' token; '' = ${TOKEN_ENV}"
    )
    allowed_origins: list[str] = param(
        ["https://app.foxglove.dev"],
        help="with allow_client_publish: browser pages (Origin) that may connect, 'scheme://host:*' for any port; "
        "clients without an Origin (not a browser) need only the token",
    )
    discovery_period_s: float = param(0.5, help="look for new topics this often", min=0.05)

    def validate(self) -> None:
        if not self.host.strip():
            raise ValueError("host must not be empty (127.0.0.1 serves this machine only)")


@dataclass
class _Forward:
    """One bus topic and what is served from it."""

    topic: str
    cls: type
    publishers: dict[Any, QosProfile] = field(default_factory=dict)
    sub: Subscription[Any] | None = None
    wanted: int = 0  # client subscriptions to any channel fed by this topic
    last_image: float = 0.0


class ViewNode(Node):
    name = "view"
    Config = ViewConfig

    def __init__(self, config: ViewConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        import foxglove
        from foxglove import Channel, Context, Schema
        from foxglove.channels import ImageAnnotationsChannel, SceneUpdateChannel
        from foxglove.websocket import Capability

        self._fg = foxglove
        self._Channel, self._Schema = Channel, Schema
        c: ViewConfig = self.config
        self.ctx = Context()
        self._forwards: dict[str, _Forward] = {}
        self._channels: dict[str, Any] = {}  # foxglove topic -> channel
        self._feeds: dict[str, str] = {}  # foxglove topic -> bus topic
        self._requests: queue.Queue[tuple[str, int]] = queue.Queue()
        self._approved: dict[tuple[int, int], tuple[str, type[Any], str]] = {}
        self._image_size = (640, 480)
        self._approved_lock = threading.Lock()
        self._trusted: set[int] = set()  # SDK client ids whose connection came through the front door
        self.client_pubs: dict[str, Publisher[Any]] = {}
        self.door: FrontDoor | None = None
        token = self._token() if c.allow_client_publish else ""
        if c.allow_client_publish:
            for name in CLIENT_TOPICS:
                self.client_pubs[name] = TOPICS[name].publisher(self)
        self._ann_vlm = ImageAnnotationsChannel(c.vlm_topic + "/annotations", context=self.ctx)
        self._ann_target = ImageAnnotationsChannel(c.target_topic + "/annotations", context=self.ctx)
        self._feeds[c.vlm_topic + "/annotations"] = c.vlm_topic
        self._feeds[c.target_topic + "/annotations"] = c.target_topic
        self._robot = SceneUpdateChannel(ROBOT_TOPIC, context=self.ctx)
        self._pubs_reader = BuiltinDataReader(self.participant, BuiltinTopicDcpsPublication)
        caps = [Capability.ClientPublish] if c.allow_client_publish else []
        # Publishing on: the SDK on a loopback port of its own, behind the front door on host:port.
        host, port = ("127.0.0.1", 0) if c.allow_client_publish else (c.host, c.port)
        try:
            self.server = foxglove.start_server(
                name="go2vlm",
                host=host,
                port=port,
                capabilities=caps,
                supported_encodings=["cdr", "json"],
                # The SDK's Protocol has default bodies, meant to be inherited; foxglove is imported lazily.
                server_listener=cast("ServerListener", _Listener(self)),
                context=self.ctx,
            )
            if c.allow_client_publish:
                rules = Handshake(token, tuple(c.allowed_origins))
                self.door = FrontDoor(c.host, c.port, self.server.port, rules, self._refused_handshake)
        except Exception as exc:  # port taken, address not local: a setting to change, said in one line
            self._pubs_reader.__del__()
            if getattr(self, "server", None) is not None:
                self.server.stop()
            raise ParamError(f"cannot serve Foxglove on {c.host}:{c.port}: {exc}") from None
        self.port = self.door.port if self.door is not None else self.server.port
        CAMERA_INFO.subscription(self, self._on_camera_info, name=c.camera_info_topic)
        self.create_timer(c.discovery_period_s, self._discover)
        self.create_timer(0.05, self._apply_requests)
        self.create_timer(1.0, self._send_robot)
        self._discover()
        self.log.info(f"Foxglove WebSocket on ws://{c.host}:{self.port} (Open connection -> Foxglove WebSocket)")
        if self.door is not None:
            self.log.info(f"clients with the token may publish; the SDK itself on 127.0.0.1:{self.server.port} "
                          "publishes for none that bypass the front door")  # fmt: skip

    def _token(self) -> str:
        """The clients' token, from token_file or $GO2VLM_VIEW_TOKEN; a ParamError when there is none."""
        try:
            token = read_secret(TOKEN_ENV, self.config.token_file or None, "the view's token_file")
        except ConfigError as exc:
            raise ParamError(str(exc)) from None
        if len(token) < MIN_TOKEN_CHARS:
            raise ParamError(
                f"allow_client_publish needs a token of at least {MIN_TOKEN_CHARS} characters in ${TOKEN_ENV} or "
                "token_file (e.g. `openssl rand -hex 16`); never on the command line"
            )
        return token

    def _refused_handshake(self, why: str) -> None:
        n = self.count("client_refused")
        self.log.throttled("warning", 1.0, f"refused a client: {why} ({n} refused so far)", key="handshake")

    # -- what the bus has --------------------------------------------------------------------------
    def _discover(self) -> None:
        own = {str(p.guid) for p in self.client_pubs.values()}  # what clients publish is not shown back
        for ep in self._pubs_reader.take(N=256):
            if str(getattr(ep, "key", "")) in own:
                continue
            name = getattr(ep, "topic_name", None)
            topic = ros_topic_name(name) if isinstance(name, str) else None
            if topic is None or topic in self.config.exclude or topic == ROBOT_TOPIC:
                continue
            try:
                cls = get_type(ep.type_name)
            except ValueError:
                continue
            fwd = self._forwards.get(topic)
            if fwd is None:
                fwd = self._forwards[topic] = _Forward(topic, cls)
                self._advertise(fwd)
            if cls is fwd.cls:
                fwd.publishers[ep.key] = profile_of(ep.qos)

    def _advertise(self, fwd: _Forward) -> None:
        cls: type[Any]
        if fwd.cls is Image:
            name, cls = fwd.topic + "/compressed", CompressedImage
        else:
            name, cls = fwd.topic, fwd.cls
        schema = self._Schema(name=ros_type(cls), encoding="ros2msg", data=msgdef(cls).encode())
        self._channels[name] = self._Channel(name, schema=schema, message_encoding="cdr", context=self.ctx)
        self._feeds[name] = fwd.topic

    # -- client subscriptions drive bus subscriptions (on the node's thread) ------------------------
    def _apply_requests(self) -> None:
        while True:
            try:
                fg_topic, delta = self._requests.get_nowait()
            except queue.Empty:
                return
            bus_topic = self._feeds.get(fg_topic)
            if bus_topic is None:
                continue
            fwd = self._forwards.get(bus_topic)
            if fwd is None:  # an annotation source nobody publishes yet: watch for it
                cls = Detection2DArray if bus_topic == self.config.vlm_topic else PointStamped
                fwd = self._forwards[bus_topic] = _Forward(bus_topic, cls)
                self._advertise(fwd)
            fwd.wanted = max(0, fwd.wanted + delta)
            if fwd.wanted and fwd.sub is None:
                fwd.sub = self.create_raw_subscription(fwd.cls, fwd.topic, self._handler(fwd), self._reader_qos(fwd))
            elif not fwd.wanted and fwd.sub is not None:
                self.destroy_subscription(fwd.sub)
                fwd.sub = None

    def _reader_qos(self, fwd: _Forward) -> QosProfile:
        pubs = list(fwd.publishers.values())
        if fwd.cls is Image:
            return QosProfile(reliable=False, depth=1)  # the newest frame; drop what we cannot show
        return QosProfile(
            reliable=bool(pubs) and all(p.reliable for p in pubs),
            transient_local=bool(pubs) and all(p.transient_local for p in pubs),
            depth=5,
        )

    def _handler(self, fwd: _Forward) -> Callable[[RawSample], None]:
        if fwd.cls is Image:
            return lambda s: self._on_image(fwd, s)
        raw = self._channels.get(fwd.topic)
        extra = None
        if fwd.topic == self.config.vlm_topic:
            extra = self._vlm_annotations
        elif fwd.topic == self.config.target_topic:
            extra = self._target_annotations

        def forward(s: RawSample) -> None:
            if raw is not None and raw.has_sinks():
                raw.log(s.data, log_time=time.time_ns())
                self.count("forwarded")
            if extra is not None:
                extra(s.data)

        return forward

    # -- conversions ---------------------------------------------------------------------------
    def _on_image(self, fwd: _Forward, s: RawSample) -> None:
        import cv2

        from go2vlm.msgs.image import to_bgr

        now = time.monotonic()
        if now - fwd.last_image < 1.0 / self.config.max_image_hz * 0.95:
            return
        fwd.last_image = now
        msg = Image.deserialize(s.data)
        try:
            bgr = to_bgr(msg)
        except ValueError as exc:
            self.count("bad_images")
            self.log.throttled("warning", 5.0, f"{fwd.topic}: cannot show an image: {exc}", key=fwd.topic)
            return
        ok, jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, self.config.jpeg_quality])
        if not ok:
            return
        self._image_size = (int(msg.width), int(msg.height))
        out = CompressedImage(header=msg.header, format="jpeg", data=jpeg.tobytes())
        self._channels[fwd.topic + "/compressed"].log(out.serialize(), log_time=time.time_ns())
        self.count("images")

    def _on_camera_info(self, msg: CameraInfo) -> None:
        if msg.width and msg.height:
            self._image_size = (int(msg.width), int(msg.height))

    def _vlm_annotations(self, data: bytes) -> None:
        from foxglove.messages import (
            Color,
            ImageAnnotations,
            Point2,
            PointsAnnotation,
            PointsAnnotationType,
            TextAnnotation,
        )

        if not self._ann_vlm.has_sinks():
            return
        msg = Detection2DArray.deserialize(data)
        ts = _timestamp(msg.header.stamp)
        green = Color(r=0.1, g=1.0, b=0.3, a=1.0)
        boxes, texts = [], []
        for det in msg.detections:
            x0, y0, x1, y1 = box_corners(det.bbox)
            corners = [Point2(x=x0, y=y0), Point2(x=x1, y=y0), Point2(x=x1, y=y1), Point2(x=x0, y=y1)]
            boxes.append(
                PointsAnnotation(
                    timestamp=ts, type=PointsAnnotationType.LineLoop, points=corners, outline_color=green, thickness=3
                )
            )
            hyp = best_hypothesis(det.results)
            label = f"{hyp.class_id} {hyp.score:.2f}" if hyp else (det.id or "object")
            texts.append(
                TextAnnotation(
                    timestamp=ts,
                    position=Point2(x=x0, y=max(0.0, y0 - 4)),
                    text=label,
                    font_size=16,
                    text_color=Color(r=0.0, g=0.0, b=0.0, a=1.0),
                    background_color=green,
                )
            )
        self._ann_vlm.log(ImageAnnotations(timestamp=ts, points=boxes, texts=texts))

    def _target_annotations(self, data: bytes) -> None:
        from foxglove.messages import CircleAnnotation, Color, ImageAnnotations, Point2, TextAnnotation

        if not self._ann_target.has_sinks():
            return
        msg = PointStamped.deserialize(data)
        w, h = self._image_size
        p = msg.point
        cx, cy, diameter = (p.x + 1) * w / 2, (p.y + 1) * h / 2, max(4.0, p.z * w)
        ts = _timestamp(msg.header.stamp)
        cyan = Color(r=0.0, g=1.0, b=1.0, a=1.0)
        self._ann_target.log(
            ImageAnnotations(
                timestamp=ts,
                circles=[
                    CircleAnnotation(
                        timestamp=ts, position=Point2(x=cx, y=cy), diameter=diameter, thickness=3, outline_color=cyan
                    )
                ],
                texts=[
                    TextAnnotation(
                        timestamp=ts,
                        position=Point2(x=cx - diameter / 2, y=max(0.0, cy - diameter / 2 - 4)),
                        text=f"target x={p.x:+.2f}",
                        font_size=16,
                        text_color=Color(r=0.0, g=0.0, b=0.0, a=1.0),
                        background_color=cyan,
                    )
                ],
            )
        )

    def _send_robot(self) -> None:
        from foxglove.messages import Color, CubePrimitive, Pose, Quaternion, SceneEntity, SceneUpdate, Vector3

        if not self._robot.has_sinks():
            return
        lx, ly, lz = GO2_BOX
        cube = CubePrimitive(
            pose=Pose(position=Vector3(x=0.0, y=0.0, z=0.0), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
            size=Vector3(x=lx, y=ly, z=lz),
            color=Color(r=0.9, g=0.9, b=0.95, a=0.8),
        )
        entity = SceneEntity(frame_id=self.config.base_frame, id="go2", frame_locked=True, cubes=[cube])
        self._robot.log(SceneUpdate(entities=[entity]))

    # -- what clients send -----------------------------------------------------------------------
    def client_advertised(self, client_id: int, channel_id: int, topic: str, encoding: str, schema: str) -> None:
        if self.door is not None and topic == self.door.hello_topic:
            with self._approved_lock:  # this connection came through the front door (token, Origin)
                self._trusted.add(client_id)
            return
        cls = CLIENT_TOPICS.get(topic)
        if not self.config.allow_client_publish:
            self._refuse(f"clients may not publish here (the view runs without allow_client_publish): {topic}")
            return
        with self._approved_lock:
            trusted = client_id in self._trusted
        if not trusted:
            self._refuse(f"{topic}: this client did not come in through the view's port with the token")
            return
        if topic == ESTOP_RELEASE.name:
            self._refuse("a client never releases the e-stop: release it at the robot with `go2vlm estop --release`")
            return
        if cls is None:
            self._refuse(f"a client may not publish {topic}; allowed: {', '.join(CLIENT_TOPICS)}")
            return
        if _ros2_name(schema) != ros_type(cls):
            self._refuse(f"{topic} takes {ros_type(cls)}, not {schema!r}")
            return
        if encoding not in ("cdr", "json"):
            self._refuse(f"{topic}: encoding {encoding!r} is not cdr or json")
            return
        with self._approved_lock:
            self._approved[(client_id, channel_id)] = (topic, cls, encoding)
        self.log.info(f"a client may publish {topic} ({encoding})")

    def client_unadvertised(self, client_id: int, channel_id: int) -> None:
        with self._approved_lock:
            self._approved.pop((client_id, channel_id), None)

    def client_message(self, client_id: int, channel_id: int, data: bytes) -> None:
        with self._approved_lock:
            entry = self._approved.get((client_id, channel_id))
        if entry is None:
            self._refuse("a message on a channel that was refused", quiet=True)
            return
        topic, cls, encoding = entry
        try:
            msg = cls.deserialize(data) if encoding == "cdr" else from_dict(cls, json.loads(data))
        except Exception as exc:
            n = self.count("client_bad_messages")
            self.log.throttled("warning", 2.0, f"a client's {topic} message is malformed ({n} so far): {exc}")
            return
        if topic == EMERGENCY_STOP.name and not msg.data:
            self._refuse(f"{topic} false: a client engages the e-stop, never releases it", quiet=True)
            return
        self.client_pubs[topic].publish(msg)
        self.count("client_published")
        if topic == EMERGENCY_STOP.name:
            self.log.warning("a Foxglove client engaged the e-stop")

    def _refuse(self, why: str, quiet: bool = False) -> None:
        n = self.count("client_publish_refused")
        self.log.throttled("warning", 1.0, f"refused: {why} ({n} refused so far)", key="refused")
        if not quiet:
            try:
                self.server.publish_status(f"go2vlm: refused: {why}", self._fg.StatusLevel.Error)
            except Exception:
                pass

    def close(self) -> None:
        if self.door is not None:
            self.door.close()
        self.server.stop()
        try:
            self._pubs_reader.__del__()
        except Exception:
            pass


class _Listener:
    """foxglove-sdk callbacks (on the SDK's threads): hand over to the node."""

    def __init__(self, node: ViewNode) -> None:
        self.node = node

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self.node._requests.put((channel.topic, +1))

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        self.node._requests.put((channel.topic, -1))

    def on_client_advertise(self, client: Any, channel: Any) -> None:
        self.node.client_advertised(client.id, channel.id, channel.topic, channel.encoding, channel.schema_name)

    def on_client_unadvertise(self, client: Any, client_channel_id: int) -> None:
        self.node.client_unadvertised(client.id, client_channel_id)

    def on_message_data(self, client: Any, client_channel_id: int, data: bytes) -> None:
        self.node.client_message(client.id, client_channel_id, data)


def _ros2_name(schema: str) -> str:
    """`std_msgs/Bool` or `std_msgs/msg/Bool` -> `std_msgs/msg/Bool`."""
    parts = schema.strip().split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else schema.strip()


def _timestamp(stamp: Any) -> Any:
    from foxglove.messages import Timestamp

    return Timestamp(sec=int(stamp.sec) & 0xFFFFFFFF, nsec=int(stamp.nanosec))
