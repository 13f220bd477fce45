"""The Go2's sport and videohub RPC protocol, pure (no DDS): API ids, error codes, request and
response building, JSON parameter parsing.

Unitree RPC (unitree_sdk2): a client writes `unitree_api/Request_` on `rt/api/<service>/request`;
the service answers `unitree_api/Response_` on `rt/api/<service>/response` with the same
identity {id, api_id} and a status code (0 = ok). Requests with `policy.noreply` (Move) get no
answer. Parameters are JSON text, payloads (camera JPEGs) go in `binary`.
"""

from __future__ import annotations

import json
import math
import threading
import time
from dataclasses import dataclass
from typing import Any

from go2vlm.msgs.unitree import (
    Request,
    RequestHeader,
    RequestIdentity,
    RequestLease,
    RequestPolicy,
    Response,
    ResponseHeader,
    ResponseStatus,
)
from go2vlm.robot_profile.go2 import GO2
from go2vlm.vocabulary.words import POSTURES as VOCABULARY_POSTURES

SPORT_SERVICE = "sport"
VIDEO_SERVICE = "videohub"
SPORT_API_VERSION = "1.0.0.1"
VIDEO_API_VERSION = "1.0.0.1"

# Our ROS-style names; the bus prefixes `rt`, giving Unitree's `rt/api/sport/request` etc.
SPORT_STATE_TOPIC = "/sportmodestate"


def request_topic(service: str) -> str:
    return f"/api/{service}/request"


def response_topic(service: str) -> str:
    return f"/api/{service}/response"


# -- API ids ---------------------------------------------------------------------------------
API_VERSION = 1  # internal: every server answers its API version string
DAMP = 1001
BALANCE_STAND = 1002
STOP_MOVE = 1003
STAND_UP = 1004
STAND_DOWN = 1005
RECOVERY_STAND = 1006
MOVE = 1008
SIT = 1009
RISE_SIT = 1010
HELLO = 1016
GET_IMAGE_SAMPLE = 1001  # videohub

SPORT_API_NAMES: dict[int, str] = {
    DAMP: "Damp",
    BALANCE_STAND: "BalanceStand",
    STOP_MOVE: "StopMove",
    STAND_UP: "StandUp",
    STAND_DOWN: "StandDown",
    RECOVERY_STAND: "RecoveryStand",
    MOVE: "Move",
    SIT: "Sit",
    RISE_SIT: "RiseSit",
    HELLO: "Hello",
}

# -- status codes (unitree_sdk2py/rpc/internal.py, go2/sport/sport_api.py) -------------------
OK = 0
ERR_UNKNOWN = 3001
ERR_CLIENT_SEND = 3102
ERR_CLIENT_API_NOT_REG = 3103
ERR_CLIENT_API_TIMEOUT = 3104
ERR_CLIENT_API_NOT_MATCH = 3105
ERR_CLIENT_API_DATA = 3106
ERR_CLIENT_LEASE_INVALID = 3107
ERR_SERVER_SEND = 3201
ERR_SERVER_INTERNAL = 3202
ERR_SERVER_API_NOT_IMPL = 3203
ERR_SERVER_API_PARAMETER = 3204
ERR_SERVER_LEASE_DENIED = 3205
ERR_SERVER_LEASE_NOT_EXIST = 3206
ERR_SERVER_LEASE_EXIST = 3207
SPORT_ERR_SERVER_OVERTIME = 4201
SPORT_ERR_SERVER_NOT_INIT = 4202

CODE_NAMES: dict[int, str] = {
    OK: "ok",
    ERR_UNKNOWN: "unknown error",
    ERR_CLIENT_SEND: "client: request could not be sent (no server matched)",
    ERR_CLIENT_API_NOT_REG: "client: api not registered",
    ERR_CLIENT_API_TIMEOUT: "client: no response before the timeout",
    ERR_CLIENT_API_NOT_MATCH: "client: response api id does not match the request",
    ERR_CLIENT_API_DATA: "client: response data is malformed",
    ERR_CLIENT_LEASE_INVALID: "client: lease invalid",
    ERR_SERVER_SEND: "server: response could not be sent",
    ERR_SERVER_INTERNAL: "server: internal error",
    ERR_SERVER_API_NOT_IMPL: "server: api not implemented",
    ERR_SERVER_API_PARAMETER: "server: bad api parameter",
    ERR_SERVER_LEASE_DENIED: "server: lease denied",
    ERR_SERVER_LEASE_NOT_EXIST: "server: lease does not exist",
    ERR_SERVER_LEASE_EXIST: "server: lease exists",
    SPORT_ERR_SERVER_OVERTIME: "sport: overtime",
    SPORT_ERR_SERVER_NOT_INIT: "sport: not initialised",
}


def describe_code(code: int) -> str:
    return f"{code} ({CODE_NAMES.get(code, 'unknown code')})"


# -- sport modes ------------------------------------------------------------------------------
# SportModeState.mode (Unitree sport-mode documentation); SPORT_MODE_CODES is the inverse.
SPORT_MODES = {
    0: "idle",
    1: "balance_stand",
    2: "pose",
    3: "locomotion",
    5: "lie_down",
    6: "joint_lock",
    7: "damping",
    8: "recovery_stand",
    10: "sit",
    11: "front_flip",
    12: "front_jump",
    13: "front_pounce",
}
SPORT_MODE_CODES: dict[str, int] = {name: code for code, name in SPORT_MODES.items()}

# -- limits -----------------------------------------------------------------------------------
MAX_PARAMETER_CHARS = 64 * 1024  # JSON parameters are tiny; anything huge is a bug or an attack
MAX_REQUEST_BINARY = 64 * 1024  # sport/videohub requests carry no payload
MAX_IMAGE_BYTES = 8 * 1024 * 1024  # a 1280x720 JPEG is ~100-300 KB


class ProtocolError(ValueError):
    """A request or response that breaks the protocol; `code` is the status to answer with."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


# -- request ids ------------------------------------------------------------------------------
_id_lock = threading.Lock()
_last_id = 0


def new_request_id() -> int:
    """Unique, increasing int64 per process; unitree_sdk2 uses monotonic nanoseconds too."""
    global _last_id
    with _id_lock:
        _last_id = max(_last_id + 1, time.monotonic_ns())  # an id, not a time: any increasing source
        return _last_id


# -- building -----------------------------------------------------------------------------------
def build_request(
    api_id: int,
    parameter: str | dict[str, Any] = "",
    binary: bytes = b"",
    *,
    request_id: int | None = None,
    noreply: bool = False,
    priority: int = 0,
    lease_id: int = 0,
) -> Request:
    text = json.dumps(parameter) if isinstance(parameter, dict) else parameter
    return Request(
        header=RequestHeader(
            identity=RequestIdentity(id=new_request_id() if request_id is None else request_id, api_id=api_id),
            lease=RequestLease(id=lease_id),
            policy=RequestPolicy(priority=priority, noreply=noreply),
        ),
        parameter=text,
        binary=bytes(binary),
    )


def move_request(vx: float, vy: float, vyaw: float) -> Request:
    """Move is fire-and-forget (noreply), as in unitree_sdk2's SportClient.Move."""
    return build_request(MOVE, {"x": float(vx), "y": float(vy), "z": float(vyaw)}, noreply=True)


def build_response(request: Request, code: int = OK, data: str = "", binary: bytes = b"") -> Response:
    ident = request.header.identity
    return Response(
        header=ResponseHeader(
            identity=RequestIdentity(id=ident.id, api_id=ident.api_id), status=ResponseStatus(code=code)
        ),
        data=data if code == OK else "",
        binary=bytes(binary) if code == OK else b"",
    )


# -- parsing ----------------------------------------------------------------------------------
def parse_parameter(request: Request) -> Any:
    """The JSON parameter of a request ("" counts as {}); ProtocolError(3204) if malformed."""
    text = request.parameter
    if len(text) > MAX_PARAMETER_CHARS:
        raise ProtocolError(ERR_SERVER_API_PARAMETER, f"parameter is {len(text)} chars (max {MAX_PARAMETER_CHARS})")
    if len(request.binary) > MAX_REQUEST_BINARY:
        raise ProtocolError(
            ERR_SERVER_API_PARAMETER, f"binary is {len(request.binary)} bytes (max {MAX_REQUEST_BINARY})"
        )
    if not text.strip():
        return {}
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise ProtocolError(ERR_SERVER_API_PARAMETER, f"parameter is not valid JSON: {exc}") from None


def _number(params: dict[str, Any], key: str) -> float:
    if key not in params:
        raise ProtocolError(ERR_SERVER_API_PARAMETER, f"Move parameter {key!r} is missing")
    value = params[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ProtocolError(ERR_SERVER_API_PARAMETER, f"Move parameter {key!r} = {value!r} is not a finite number")
    return float(value)


def parse_move(params: Any) -> tuple[float, float, float]:
    """`{"x": vx, "y": vy, "z": vyaw}` -> (vx, vy, vyaw), clamped to the sport-mode limits."""
    if not isinstance(params, dict):
        raise ProtocolError(ERR_SERVER_API_PARAMETER, f"Move parameter must be a JSON object, got {params!r:.80}")
    vx, vy, vyaw = _number(params, "x"), _number(params, "y"), _number(params, "z")
    return GO2.ceilings.clamp(vx, vy, vyaw)


@dataclass(frozen=True)
class RpcResult:
    """What a call returned: status code, JSON text, binary payload."""

    code: int
    data: str = ""
    binary: bytes = b""

    @property
    def ok(self) -> bool:
        return self.code == OK

    def describe(self) -> str:
        return describe_code(self.code)


def result_from_response(request_api_id: int, response: Response) -> RpcResult:
    """The SDK's checks: a response for another api id is ERR_CLIENT_API_NOT_MATCH."""
    if response.header.identity.api_id != request_api_id:
        return RpcResult(ERR_CLIENT_API_NOT_MATCH)
    return RpcResult(int(response.header.status.code), response.data, bytes(response.binary))


# -- posture commands (/go2/command, `go2vlm go2 ...`): the one vocabulary -------------------
# Every robot end of a Go2 (the go2 driver, the sim) takes these words on /go2/command
# (bus/topics.py: GO2_COMMAND), and `go2vlm go2` offers exactly these verbs.
# name -> sequence of sport API ids sent in order, each after the previous one answered.
# "stand" = StandUp (joints locked upright) then BalanceStand (balancing, accepts Move).
COMMANDS: dict[str, tuple[int, ...]] = {
    "stand": (STAND_UP, BALANCE_STAND),
    "balance": (BALANCE_STAND,),
    "sit": (SIT,),
    "rise": (RISE_SIT,),
    "standdown": (STAND_DOWN,),
    "damp": (DAMP,),
    "recover": (RECOVERY_STAND,),
    "hello": (HELLO,),
    "stop": (STOP_MOVE,),
}
POSTURES = VOCABULARY_POSTURES  # the words are the vocabulary's; this table says what each does on a Go2
if tuple(COMMANDS) != POSTURES:
    raise ImportError(f"protocol.COMMANDS {tuple(COMMANDS)} differ from the vocabulary's postures {POSTURES}")
# Allowed while the emergency stop is latched: nothing that makes the robot stand or move.
ESTOP_ALLOWED = frozenset({"damp", "standdown", "stop"})
ESTOP_ALLOWED_APIS = frozenset(api for name in ESTOP_ALLOWED for api in COMMANDS[name])
# The stops: they travel in a priority lane (a server applies them before anything queued, and a
# client retries them until they are acknowledged), and a Damp supersedes whatever came before it.
STOP_APIS = frozenset({DAMP, STOP_MOVE})

# -- WebRTC: the route of the Unitree app (every Go2: AIR, PRO, EDU) ---------------------------
# Facts about the robot's WebRTC service, as the Unitree app and unitree_webrtc_connect speak it
# (robots/go2/webrtc/ has the codec and the link; robots/go2_sim/webrtc_server.py the sim's side).
# The data channel carries the DDS topics under their DDS names ("rt/..."), as JSON.
RTC_SPORT_REQUEST = "rt/api/sport/request"
RTC_SPORT_RESPONSE = "rt/api/sport/response"
RTC_BASH_REQUEST = "rt/api/bashrunner/request"
RTC_BASH_RESPONSE = "rt/api/bashrunner/response"
RTC_SPORT_STATE = "rt/sportmodestate"
RTC_LF_SPORT_STATE = "rt/lf/sportmodestate"  # the low-rate copy the app reads
RTC_LOW_STATE = "rt/lowstate"
RTC_LF_LOW_STATE = "rt/lf/lowstate"
RTC_LIDAR_VOXELS = "rt/utlidar/voxel_map_compressed"  # LZ4 voxel bitmap, binary frame
RTC_LIDAR_SWITCH = "rt/utlidar/switch"  # "on" / "off"
# Data-channel message types ("type" of every JSON message).
DC_VALIDATION = "validation"
DC_SUBSCRIBE = "subscribe"
DC_UNSUBSCRIBE = "unsubscribe"
DC_MSG = "msg"
DC_REQUEST = "req"
DC_RESPONSE = "res"
DC_VIDEO = "vid"
DC_AUDIO = "aud"
DC_ERR = "err"
DC_HEARTBEAT = "heartbeat"
DC_RTC_INNER_REQ = "rtc_inner_req"
DC_ERRORS = frozenset({"errors", "add_error", "rm_error"})
VALIDATION_OK = "Validation Ok."
VALIDATION_NEEDED = "Validation Needed."
VALIDATION_PREFIX = "UnitreeGo2_"  # the answer is base64(md5(prefix + key)) of the robot's key
# Firmware version: the app runs this built-in script through the bashrunner service on connect.
BASH_RUN_SCRIPT = 1001
VERSION_SCRIPT = "get_whole_packet_version.sh"
# Signalling: HTTP on the robot. 9991 (con_notify, then con_ing_<path>) on firmware >= 1.1.x; 8081
# (/offer, plaintext) on older firmware. The robot as access point is always 192.168.12.1.
AES_KEY_ENV = "GO2VLM_AES_KEY"  # the robot's AES key (or a file: aes_key_file); never a parameter
SIGNAL_PORT = 9991
LEGACY_SIGNAL_PORT = 8081
AP_IP = "192.168.12.1"
# con_notify's "data2": how "data1" (the robot's RSA public key) is sealed. 1: plain; 2: AES-GCM with
# the app's static key (firmware 1.1.1 to 1.1.14); 3: AES-GCM with the robot's own AES-128 key, which
# Unitree's cloud hands to the robot's owner (firmware >= 1.1.15). Anything else: unknown protocol.
SEAL_PLAIN, SEAL_STATIC, SEAL_DEVICE = 1, 2, 3
SIGNAL_SEALS = frozenset({SEAL_PLAIN, SEAL_STATIC, SEAL_DEVICE})
STATIC_GCM_KEY = bytes.fromhex("e85682bd16549b008e04a6682bb3ebe3")  # the app's key for data2 == 2
# Firmware versions: the ones unitree_webrtc_connect 2.2 lists as working with its protocol (go2vlm
# speaks the same), and the ones go2vlm itself has met. None has met go2vlm yet: only the sim has.
FIRMWARE_KNOWN = ("1.0.19-1.0.25", "1.1.1-1.1.14 (data2=2)", "1.1.15+ (data2=3, needs the robot's AES key)")
FIRMWARE_TESTED: tuple[str, ...] = ()  # firmware versions go2vlm has been run against on a real Go2
SIM_FIRMWARE = "1.1.7-sim"  # what the simulator reports


def firmware_tuple(version: str) -> tuple[int, ...] | None:
    """ "1.1.7" (also "V1.1.7", "1.1.7-sim") -> (1, 1, 7); None when it is not a version."""
    text = version.strip().lstrip("vV").split("-")[0].split(" ")[0]
    parts = text.split(".")
    if not 2 <= len(parts) <= 4 or not all(part.isdigit() for part in parts):
        return None
    return tuple(int(part) for part in parts)


def firmware_note(version: str) -> str | None:
    """None for a firmware go2vlm has been tested on; else one line saying what is known of it."""
    if version in FIRMWARE_TESTED or version == SIM_FIRMWARE:
        return None
    v = firmware_tuple(version)
    if v is None:
        return f"firmware {version!r} is not a version go2vlm can read; untested"
    known = (1, 0, 19) <= v <= (1, 0, 25) or v >= (1, 1, 1)
    if not known:
        return f"firmware {version} is older than any known to speak this WebRTC protocol (1.0.19); untested"
    return f"firmware {version} is untested with go2vlm (known to speak this protocol: {', '.join(FIRMWARE_KNOWN)})"
