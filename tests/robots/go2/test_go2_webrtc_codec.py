"""The Go2's WebRTC protocol as data (robots/go2/webrtc/codec.py): signalling both ways, the
data-channel framing, the lidar's voxel map and the state messages' JSON, with bad input."""

from __future__ import annotations

import base64
import hashlib
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.msgs.unitree import LowState, SportModeState
from go2vlm.robots.go2 import protocol as p
from go2vlm.robots.go2.webrtc import codec

pytest.importorskip("cryptography", reason="the webrtc extra: pip install 'go2vlm[webrtc]'")
pytest.importorskip("lz4", reason="the webrtc extra: pip install 'go2vlm[webrtc]'")

ROBOT_KEY = codec.new_robot_key()  # 2048-bit RSA: made once, it takes a moment
DEVICE_KEY = bytes(range(16))


@pytest.mark.parametrize("seal", [p.SEAL_PLAIN, p.SEAL_STATIC, p.SEAL_DEVICE])
def test_signalling_round_trip(seal: int) -> None:
    body = codec.con_notify_body(ROBOT_KEY, "07319", seal, DEVICE_KEY)
    public, path, got_seal = codec.parse_con_notify(body, DEVICE_KEY)
    assert path == "07319" and got_seal == seal and public == codec.public_key_b64(ROBOT_KEY)
    offer = {"id": "STA_localNetwork", "sdp": "v=0\r\n" * 400, "type": "offer", "token": ""}
    sealed, key = codec.offer_body(offer, public)
    opened, key2 = codec.open_offer(sealed.encode(), ROBOT_KEY)
    assert opened == offer and key2 == key and len(key) == 32
    answer = codec.parse_answer(codec.aes_encrypt(json.dumps({"sdp": "v=0", "type": "answer"}), key), key)
    assert answer == {"sdp": "v=0", "type": "answer"}
    assert codec.parse_answer(json.dumps({"sdp": "reject"}), None)["sdp"] == "reject"  # the legacy port: plain


def test_static_seal_is_the_apps_key() -> None:
    """data2=2 is AES-GCM under the app's key, laid out ciphertext + nonce + tag (what the robot sends)."""
    from cryptography.hazmat.primitives.ciphers.aead import AESGCM

    nonce = bytes(12)
    sealed = AESGCM(p.STATIC_GCM_KEY).encrypt(nonce, b"hello", None)
    b64 = base64.b64encode(sealed[:-16] + nonce + sealed[-16:]).decode()
    assert codec.gcm_open(b64, p.STATIC_GCM_KEY) == "hello"


def _notify(envelope: object) -> str:
    return base64.b64encode(json.dumps(envelope).encode()).decode()


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("<html>not base64</html>", "not base64 JSON"),
        (base64.b64encode(b"not json").decode(), "not base64 JSON"),
        (_notify({"data2": 2}), "no data1"),
        (_notify({"data1": "x" * 40, "data2": 7}), "data2=7, a protocol go2vlm does not know"),
        (_notify({"data1": "AAAA", "data2": 2}), "cannot unseal"),
        (_notify({"data1": "k" * 40, "data2": 1}), "path code"),
        (_notify({"data1": "short", "data2": 1}), "too short"),
    ],
)
def test_bad_signalling_answers_are_one_clear_error(text: str, says: str) -> None:
    with pytest.raises(codec.SignalError, match=says) as err:
        codec.parse_con_notify(text)
    assert "\n" not in str(err.value)


def test_device_seal_needs_the_right_key() -> None:
    body = codec.con_notify_body(ROBOT_KEY, "00001", p.SEAL_DEVICE, DEVICE_KEY)
    with pytest.raises(codec.SignalError, match="needs its AES-128 key"):
        codec.parse_con_notify(body)
    with pytest.raises(codec.SignalError, match="wrong AES key"):
        codec.parse_con_notify(body, bytes(16))


@pytest.mark.parametrize("text", ["", "garbage", base64.b64encode(b"x" * 16).decode(), json.dumps({"sdp": 3})])
def test_bad_sdp_answers(text: str) -> None:
    with pytest.raises(codec.SignalError):
        codec.parse_answer(text, codec.new_session_key() if text.startswith(("Z", "e")) else None)


def test_validation_reply() -> None:
    want = base64.b64encode(hashlib.md5(b"UnitreeGo2_abc123").digest()).decode()
    assert codec.validation_reply("abc123") == want


def test_messages_both_framings() -> None:
    msg, payload = codec.decode(codec.message(p.DC_MSG, "rt/x", {"a": 1}))
    assert msg == {"type": "msg", "topic": "rt/x", "data": {"a": 1}} and payload is None
    frame = codec.encode_binary({"type": "msg", "topic": "rt/utlidar/voxel_map_compressed"}, b"\x01\x02")
    msg, payload = codec.decode(frame)
    assert msg["topic"].endswith("compressed") and payload == b"\x01\x02"
    head = json.dumps({"type": "msg", "topic": "rt/y"}).encode()  # the other framing: u16 length, 2 reserved
    msg, payload = codec.decode(len(head).to_bytes(2, "little") + b"\0\0" + head + b"tail")
    assert msg["topic"] == "rt/y" and payload == b"tail"


@pytest.mark.parametrize(
    "raw",
    ["", "not json", "[1, 2]", '{"topic": "no type"}', b"\x01", b"\xff\x00\x00\x00{}", b"\x02\x00\x00\x00\xff\xff"],
)
def test_malformed_messages_raise(raw: str | bytes) -> None:
    with pytest.raises(ValueError):
        codec.decode(raw)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-4, 4), st.floats(-4, 4), st.floats(-1, 2)).map(list), min_size=0, max_size=200),
    st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(0.1, 0.5)),
)
def test_voxel_map_round_trip(points: list[list[float]], center: tuple[float, float, float]) -> None:
    """Every point inside the map comes back as the centre of its cell; points outside are left out."""
    pts = np.array(points, dtype=float).reshape(-1, 3) + np.array(center) * [1, 1, 0]
    header, payload = codec.voxelize(pts, np.array(center), 12.5)
    back = codec.voxel_points(header, payload)
    r = header["resolution"]
    origin = np.array(header["origin"])
    cells = np.floor((pts - origin) / r)
    inside = np.all((cells >= 0) & (cells < codec.VOXEL_DIMS), axis=1)
    want = {tuple(c) for c in cells[inside].astype(int)}
    got = {tuple(c) for c in np.floor((back - origin) / r).astype(int)}
    assert got == want
    if len(back):
        assert np.abs(back - (np.floor((back - origin) / r) + 0.5) * r - origin).max() < 1e-9


@pytest.mark.parametrize(
    "header",
    [{}, {"src_size": 10, "resolution": 0.05, "origin": [0, 0, 0]}, {"src_size": 2048, "resolution": 0, "origin": [0]}],
)
def test_bad_voxel_maps_raise(header: dict) -> None:
    with pytest.raises(ValueError):
        codec.voxel_points(header, b"\x00" * 8)


def test_voxel_map_that_does_not_decompress() -> None:
    with pytest.raises(ValueError, match="decompress"):
        codec.voxel_points({"src_size": codec.VOXEL_BYTES, "resolution": 0.05, "origin": [0, 0, 0]}, b"\xff" * 5)


def test_state_json_round_trip() -> None:
    s = SportModeState(mode=3, position=[1.0, -2.0, 0.3], velocity=[0.5, 0.0, 0.0], yaw_speed=0.25)
    s.imu_state.quaternion = [0.9, 0.0, 0.0, 0.4359]
    assert codec.sport_state_from_json(json.loads(json.dumps(codec.to_jsonable(s)))) == s
    low = LowState(power_v=29.5)
    low.motor_state[5].temperature = 81
    low.bms_state.soc = 42
    back = codec.low_state_from_json(json.loads(json.dumps(codec.to_jsonable(low))))
    assert back == low and back.motor_state[5].temperature == 81


def test_state_json_as_the_robot_sends_it() -> None:
    """Fields the robot leaves out keep their defaults; what it sends is taken."""
    s = codec.sport_state_from_json({"mode": 1, "position": [1, 2, 0.3], "imu_state": {"rpy": [0, 0, 1.5]}})
    assert s.mode == 1 and s.position == [1.0, 2.0, 0.3] and s.imu_state.rpy == [0.0, 0.0, 1.5]
    assert s.imu_state.quaternion == [1.0, 0.0, 0.0, 0.0]


@pytest.mark.parametrize(
    "data",
    [
        "a string",
        {"position": "here"},
        {"position": [1, 2, 3, 4]},
        {"mode": "walking"},
        {"yaw_speed": math.nan},
        {"yaw_speed": True},
        {"imu_state": [1, 2]},
        {"mode": 1.5},
    ],
)
def test_state_json_that_does_not_fit_raises(data: object) -> None:
    with pytest.raises(ValueError):
        codec.sport_state_from_json(data)


def test_firmware_notes() -> None:
    assert p.firmware_note(p.SIM_FIRMWARE) is None
    assert "untested" in (p.firmware_note("1.1.7") or "")
    assert "untested" in (p.firmware_note("V1.0.21") or "")
    assert "older than any known" in (p.firmware_note("1.0.3") or "")
    assert "not a version" in (p.firmware_note("banana") or "")
    assert p.firmware_tuple("1.1.15-beta") == (1, 1, 15)
