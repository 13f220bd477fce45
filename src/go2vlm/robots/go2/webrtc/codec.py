"""The Go2's WebRTC protocol as data, pure (no sockets, no aiortc): both ends use it, the go2
driver's link and the simulator's server.

Signalling (HTTP on the robot, port 9991; protocol facts in robots/go2/protocol.py):
  1. POST /con_notify -> base64 of {"data1": D, "data2": seal}. D, once unsealed, is 10 characters,
     the robot's RSA public key (base64 DER), and 10 characters whose every second one (A..J) spells
     the digits of the next path.
  2. POST /con_ing_<path> {"data1": AES-256-ECB(offer JSON, K), "data2": RSA-PKCS1v1.5(K)}, K a fresh
     32-character hex string used as the key's bytes -> AES-256-ECB(answer JSON, K), base64.
  The legacy port 8081 takes the offer JSON in plain text on /offer and answers in plain text.
  Offer JSON: {"id": "STA_localNetwork" | "", "sdp", "type": "offer", "token"}; answer JSON
  {"sdp", "type": "answer"}, or {"sdp": "reject"} while another client holds the robot.
Data channel "data": one JSON object per text message, {"type", "topic", "data"} (protocol.DC_*);
binary messages carry a JSON header and a payload (the lidar's voxel map).
"""

from __future__ import annotations

import base64
import dataclasses
import hashlib
import json
import math
import os
import secrets
import struct
from typing import Any

import numpy as np

from go2vlm.msgs.unitree import LowState, SportModeState
from go2vlm.robots.go2 import protocol as p

MAX_SIGNAL_BYTES = 256 * 1024  # an SDP is a few kB
MAX_MESSAGE_BYTES = 4 * 1024 * 1024  # a voxel map is tens of kB


class SignalError(ValueError):
    """A signalling answer that cannot be used; the message is one line for the user."""


# -- ciphers ------------------------------------------------------------------------------------
def _aes_ecb(key: str) -> Any:
    from cryptography.hazmat.primitives.ciphers import Cipher, algorithms, modes

    return Cipher(algorithms.AES(key.encode("ascii")), modes.ECB())


def aes_encrypt(text: str, key: str) -> str:
    """AES-256-ECB with PKCS#7 padding, base64: the offer's and the answer's envelope."""
    from cryptography.hazmat.primitives import padding

    padder = padding.PKCS7(128).padder()
    data = padder.update(text.encode()) + padder.finalize()
    enc = _aes_ecb(key).encryptor()
    return base64.b64encode(enc.update(data) + enc.finalize()).decode("ascii")


def aes_decrypt(b64: str, key: str) -> str:
    from cryptography.hazmat.primitives import padding

    dec = _aes_ecb(key).decryptor()
    raw = dec.update(base64.b64decode(b64, validate=True)) + dec.finalize()
    unpadder = padding.PKCS7(128).unpadder()
    return (unpadder.update(raw) + unpadder.finalize()).decode()


def new_session_key() -> str:
    """K: 32 hex characters, used as the 32 bytes of an AES-256 key."""
    return secrets.token_hex(16)


def gcm_seal(text: str, key: bytes) -> str:
    """base64(ciphertext + nonce(12) + tag(16)): how con_notify seals data1 (data2 2 and 3)."""
    from cryptography.hazmat.primitives.ciphers.aead import AESGCM

    nonce = os.urandom(12)
    sealed = AESGCM(key).encrypt(nonce, text.encode(), None)  # ciphertext + tag
    return base64.b64encode(sealed[:-16] + nonce + sealed[-16:]).decode("ascii")


def gcm_open(b64: str, key: bytes) -> str:
    from cryptography.hazmat.primitives.ciphers.aead import AESGCM

    raw = base64.b64decode(b64, validate=True)
    if len(raw) < 28:
        raise ValueError("sealed data1 is too short")
    return AESGCM(key).decrypt(raw[-28:-16], raw[:-28] + raw[-16:], None).decode()


def rsa_encrypt(text: str, public_key_b64: str) -> str:
    """RSA PKCS#1 v1.5 in chunks of (key size - 11) bytes, base64 of the concatenation."""
    from cryptography.hazmat.primitives.asymmetric import padding as apad
    from cryptography.hazmat.primitives.serialization import load_der_public_key

    key: Any = load_der_public_key(base64.b64decode(public_key_b64, validate=True))
    size = key.key_size // 8
    data = text.encode()
    out = b"".join(key.encrypt(data[i : i + size - 11], apad.PKCS1v15()) for i in range(0, len(data), size - 11))
    return base64.b64encode(out).decode("ascii")


def rsa_decrypt(b64: str, private_key: Any) -> str:
    from cryptography.hazmat.primitives.asymmetric import padding as apad

    raw = base64.b64decode(b64, validate=True)
    size = private_key.key_size // 8
    if not raw or len(raw) % size:
        raise ValueError(f"RSA payload of {len(raw)} bytes is not whole blocks of {size}")
    return b"".join(private_key.decrypt(raw[i : i + size], apad.PKCS1v15()) for i in range(0, len(raw), size)).decode()


# -- signalling: the robot's side -----------------------------------------------------------------
def new_robot_key() -> Any:
    from cryptography.hazmat.primitives.asymmetric import rsa

    return rsa.generate_private_key(public_exponent=65537, key_size=2048)


def public_key_b64(private_key: Any) -> str:
    from cryptography.hazmat.primitives.serialization import Encoding, PublicFormat

    der = private_key.public_key().public_bytes(Encoding.DER, PublicFormat.SubjectPublicKeyInfo)
    return base64.b64encode(der).decode("ascii")


def con_notify_body(private_key: Any, path: str, seal: int = p.SEAL_STATIC, device_key: bytes | None = None) -> str:
    """What the robot answers on /con_notify: its key and the next path (5 digits), sealed."""
    if len(path) != 5 or not path.isdigit():
        raise ValueError(f"path must be 5 digits, got {path!r}")
    letters = "ABCDEFGHIJ"
    tail = "".join(secrets.choice("abcdefghij") + letters[int(d)] for d in path)
    data1 = secrets.token_hex(5) + public_key_b64(private_key) + tail
    if seal == p.SEAL_STATIC:
        data1 = gcm_seal(data1, p.STATIC_GCM_KEY)
    elif seal == p.SEAL_DEVICE:
        if device_key is None:
            raise ValueError("seal 3 needs the device's AES-128 key")
        data1 = gcm_seal(data1, device_key)
    return base64.b64encode(json.dumps({"data1": data1, "data2": seal}).encode()).decode("ascii")


def open_offer(body: bytes, private_key: Any) -> tuple[dict[str, Any], str]:
    """The robot reads a con_ing body: (offer JSON, the session key K)."""
    try:
        envelope = json.loads(body.decode())
        key = rsa_decrypt(envelope["data2"], private_key)
        offer = json.loads(aes_decrypt(envelope["data1"], key))
    except Exception as exc:
        raise SignalError(f"malformed offer: {type(exc).__name__}: {exc}") from None
    return check_offer(offer), key


def check_offer(offer: Any) -> dict[str, Any]:
    if not isinstance(offer, dict) or offer.get("type") != "offer" or not isinstance(offer.get("sdp"), str):
        raise SignalError("the offer is not {'type': 'offer', 'sdp': ...}")
    return offer


# -- signalling: the client's side --------------------------------------------------------------
def parse_con_notify(text: str, device_key: bytes | None = None) -> tuple[str, str, int]:
    """The robot's /con_notify answer -> (its public key, base64 DER; the con_ing path; the seal)."""
    try:
        envelope = json.loads(base64.b64decode(text.strip(), validate=True).decode())
    except Exception:
        raise SignalError(f"the signalling answer is not base64 JSON: {text[:60]!r}") from None
    if not isinstance(envelope, dict) or not isinstance(envelope.get("data1"), str):
        raise SignalError(f"the signalling answer has no data1: {str(envelope)[:80]}")
    seal = envelope.get("data2", p.SEAL_PLAIN)
    if seal not in p.SIGNAL_SEALS:
        raise SignalError(
            f"the robot seals its key with data2={seal!r}, a protocol go2vlm does not know (1, 2, 3): "
            "its firmware is newer than this go2vlm"
        )
    data1 = envelope["data1"]
    try:
        if seal == p.SEAL_STATIC:
            data1 = gcm_open(data1, p.STATIC_GCM_KEY)
        elif seal == p.SEAL_DEVICE:
            if device_key is None:
                raise SignalError(
                    "this robot (firmware >= 1.1.15, data2=3) needs its AES-128 key: $GO2VLM_AES_KEY or "
                    "--param aes_key_file=<a file holding its 32 hex chars> (Unitree's cloud gives it to the owner)"
                )
            data1 = gcm_open(data1, device_key)
    except SignalError:
        raise
    except Exception:
        raise SignalError(f"cannot unseal the robot's key (data2={seal}): wrong AES key?") from None
    if len(data1) <= 20:
        raise SignalError("the robot's key in the signalling answer is too short")
    letters = "ABCDEFGHIJ"
    tail = data1[-10:]
    if any(tail[i] not in letters for i in range(1, 10, 2)):
        raise SignalError(f"the signalling answer's path code {tail!r} is not in the known form")
    path = "".join(str(letters.index(tail[i])) for i in range(1, 10, 2))
    return data1[10:-10], path, seal


def offer_body(offer: dict[str, Any], robot_key_b64: str) -> tuple[str, str]:
    """(the con_ing body, K): the offer sealed for the robot."""
    key = new_session_key()
    body = {"data1": aes_encrypt(json.dumps(offer), key), "data2": rsa_encrypt(key, robot_key_b64)}
    return json.dumps(body), key


def parse_answer(text: str, key: str | None) -> dict[str, Any]:
    """The robot's answer (sealed with K, or plain on the legacy port) -> {"sdp", "type"}.
    SignalError for anything else; {"sdp": "reject"} is returned as is (another client holds it)."""
    try:
        answer = json.loads(aes_decrypt(text.strip(), key) if key is not None else text)
    except Exception:
        raise SignalError(f"the robot's SDP answer cannot be read: {text[:60]!r}") from None
    if not isinstance(answer, dict) or not isinstance(answer.get("sdp"), str):
        raise SignalError(f"the robot's SDP answer has no sdp: {str(answer)[:80]}")
    if answer["sdp"] != "reject" and answer.get("type") != "answer":
        raise SignalError(f"the robot's SDP answer is of type {answer.get('type')!r}, not 'answer'")
    return answer


# -- data channel -----------------------------------------------------------------------------
def validation_reply(key: str) -> str:
    """The answer to the robot's validation key: base64 of md5("UnitreeGo2_" + key)."""
    return base64.b64encode(hashlib.md5((p.VALIDATION_PREFIX + key).encode()).digest()).decode("ascii")


def message(kind: str, topic: str = "", data: Any = None, **extra: Any) -> str:
    msg: dict[str, Any] = {"type": kind, "topic": topic}
    if data is not None:
        msg["data"] = data
    msg.update(extra)
    return json.dumps(msg, separators=(",", ":"))


def decode(raw: str | bytes) -> tuple[dict[str, Any], bytes | None]:
    """One data-channel message -> (its JSON object, the binary payload or None). ValueError if malformed."""
    if len(raw) > MAX_MESSAGE_BYTES:
        raise ValueError(f"message of {len(raw)} bytes (max {MAX_MESSAGE_BYTES})")
    payload: bytes | None = None
    if isinstance(raw, str):
        text = raw
    else:
        if len(raw) < 4:
            raise ValueError(f"binary message of {len(raw)} bytes has no header")
        a, b = struct.unpack_from("<HH", raw, 0)
        if a == 2 and b == 0:  # the lidar's framing: u16 2, u16 0, u32 JSON length, 4 reserved bytes
            if len(raw) < 12:
                raise ValueError("lidar frame shorter than its header")
            (n,) = struct.unpack_from("<I", raw, 4)
            start = 12
        else:  # u16 JSON length, 2 reserved bytes
            n, start = a, 4
        if start + n > len(raw):
            raise ValueError(f"binary message header says {n} bytes of JSON, it has {len(raw) - start}")
        text, payload = raw[start : start + n].decode(), bytes(raw[start + n :])
    try:
        msg = json.loads(text)
    except (ValueError, RecursionError):
        raise ValueError(f"not JSON: {text[:60]!r}") from None
    if not isinstance(msg, dict) or not isinstance(msg.get("type"), str):
        raise ValueError(f"not a message object: {text[:60]!r}")
    return msg, payload


def encode_binary(msg: dict[str, Any], payload: bytes) -> bytes:
    """A binary message in the lidar's framing (u16 2, u16 0, u32 length, 4 reserved, JSON, payload)."""
    head = json.dumps(msg, separators=(",", ":")).encode()
    return struct.pack("<HHII", 2, 0, len(head), 0) + head + payload


# -- lidar: the voxel map -----------------------------------------------------------------------
VOXEL_RESOLUTION = 0.05  # m
VOXEL_DIMS = (128, 128, 38)  # x, y, z cells: 6.4 x 6.4 x 1.9 m around the robot
VOXEL_BYTES = VOXEL_DIMS[0] * VOXEL_DIMS[1] * VOXEL_DIMS[2] // 8  # 77,824: the only size a map may declare


def voxelize(points: np.ndarray, center: np.ndarray, stamp: float) -> tuple[dict[str, Any], bytes]:
    """Points in the odom frame -> (the voxel map's header, LZ4 block of its bitmap). The map is
    VOXEL_DIMS cells of VOXEL_RESOLUTION round `center`; bit x of byte (z*2048 + y*16 + x//8),
    most significant bit first, is the cell (x, y, z)."""
    import lz4.block

    nx, ny, nz = VOXEL_DIMS
    r = VOXEL_RESOLUTION
    origin = np.round(np.round((np.asarray(center, dtype=float) - [nx * r / 2, ny * r / 2, 0.6]) / r) * r, 4)
    cells = np.floor((np.asarray(points, dtype=float).reshape(-1, 3) - origin) / r).astype(np.int64)
    inside = np.all((cells >= 0) & (cells < [nx, ny, nz]), axis=1)
    cells = cells[inside]
    grid = np.zeros(nx * ny * nz // 8, dtype=np.uint8)
    index = cells[:, 2] * (nx * ny // 8) + cells[:, 1] * (nx // 8) + cells[:, 0] // 8
    np.bitwise_or.at(grid, index, (0x80 >> (cells[:, 0] % 8)).astype(np.uint8))
    raw = grid.tobytes()
    header = {
        "stamp": stamp,
        "frame_id": "odom",
        "resolution": r,
        "src_size": len(raw),
        "origin": [float(v) for v in origin],
        "width": list(VOXEL_DIMS),
    }
    return header, lz4.block.compress(raw, store_size=False)


def voxel_points(header: dict[str, Any], payload: bytes) -> np.ndarray:
    """A voxel map -> the centres of its occupied cells (N x 3, odom frame). ValueError if malformed,
    or if it declares any size but the real map's (VOXEL_BYTES): a 64 MiB "voxel bomb" is refused
    before anything is decompressed."""
    import lz4.block

    try:
        size = int(header["src_size"])
        r = float(header["resolution"])
        origin = np.array([float(v) for v in header["origin"]], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"voxel map header is incomplete: {exc}") from None
    if size != VOXEL_BYTES:
        raise ValueError(f"voxel map declares {size} bytes; the map is {VOXEL_BYTES}")
    width = header.get("width", list(VOXEL_DIMS))
    if width != list(VOXEL_DIMS):
        raise ValueError(f"voxel map width {str(width)[:40]}; the map is {list(VOXEL_DIMS)}")
    if origin.shape != (3,) or not np.all(np.isfinite(origin)) or not 0 < r < 10:
        raise ValueError(f"voxel map header out of range: resolution {r}, origin {origin}")
    if len(payload) > VOXEL_BYTES + VOXEL_BYTES // 255 + 16:  # LZ4's worst case for the map
        raise ValueError(f"voxel map payload of {len(payload)} bytes for a {VOXEL_BYTES}-byte map")
    try:
        raw = lz4.block.decompress(payload, uncompressed_size=size)
    except Exception as exc:
        raise ValueError(f"voxel map does not decompress: {exc}") from None
    if len(raw) != size:
        raise ValueError(f"voxel map decompresses to {len(raw)} bytes, not {size}")
    grid = np.frombuffer(raw, dtype=np.uint8)
    idx = np.nonzero(grid)[0]
    bits = np.unpackbits(grid[idx]).reshape(-1, 8).astype(bool)
    z, rest = np.divmod(idx, 2048)
    y, xb = np.divmod(rest, 16)
    xs = (xb[:, None] * 8 + np.arange(8)[None, :])[bits]
    ys = np.repeat(y, 8).reshape(-1, 8)[bits]
    zs = np.repeat(z, 8).reshape(-1, 8)[bits]
    return (np.column_stack([xs, ys, zs]).astype(float) + 0.5) * r + origin


# -- state messages: IDL <-> JSON -----------------------------------------------------------------
def to_jsonable(msg: Any) -> Any:
    """An IDL struct as the robot's JSON: field names as in the IDL, byte arrays as lists of ints."""
    if dataclasses.is_dataclass(msg) and not isinstance(msg, type):
        return {f.name: to_jsonable(getattr(msg, f.name)) for f in dataclasses.fields(msg)}
    if isinstance(msg, (bytes, bytearray)):
        return list(msg)
    if isinstance(msg, (list, tuple)):
        return [to_jsonable(v) for v in msg]
    if isinstance(msg, float):
        return round(msg, 6) if math.isfinite(msg) else None
    return msg


def _fill(template: Any, value: Any, where: str) -> Any:
    """`value` (JSON) shaped like `template` (an IDL default); ValueError naming the field if it is not."""
    if dataclasses.is_dataclass(template):
        if not isinstance(value, dict):
            raise ValueError(f"{where} is not an object")
        out = type(template)()  # type: ignore[misc]  # an IDL struct: every field has a default
        for f in dataclasses.fields(template):
            if f.name in value:
                setattr(out, f.name, _fill(getattr(out, f.name), value[f.name], f"{where}.{f.name}"))
        return out
    if isinstance(template, (bytes, list)):
        if not isinstance(value, list) or len(value) > len(template):
            raise ValueError(f"{where} is not a list of at most {len(template)}")
        items = [_fill(template[i], v, f"{where}[{i}]") for i, v in enumerate(value)]
        items += list(template[len(items) :])
        return bytes(items) if isinstance(template, bytes) else items
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{where} = {str(value)[:40]} is not a finite number")
    if isinstance(template, bool):
        return bool(value)
    if isinstance(template, int):
        if isinstance(value, float) and not value.is_integer():
            raise ValueError(f"{where} = {value} is not an integer")
        return int(value) & 0xFF if where.endswith(("temperature", "mode", "gait_type")) else int(value)
    return float(value)


def sport_state_from_json(data: Any) -> SportModeState:
    return _fill(SportModeState(), data, "sportmodestate")


def low_state_from_json(data: Any) -> LowState:
    return _fill(LowState(), data, "lowstate")
