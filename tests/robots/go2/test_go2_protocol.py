"""The pure protocol layer: requests, responses, parameter parsing and error codes."""

from __future__ import annotations

import json

import pytest

from go2vlm.msgs.unitree import Request, Response
from go2vlm.robots.go2 import protocol as p


def test_ids_and_codes_match_unitree_sdk2() -> None:
    assert (p.DAMP, p.BALANCE_STAND, p.STOP_MOVE, p.STAND_UP, p.STAND_DOWN, p.RECOVERY_STAND) == (
        1001,
        1002,
        1003,
        1004,
        1005,
        1006,
    )
    assert (p.MOVE, p.SIT, p.RISE_SIT, p.HELLO, p.GET_IMAGE_SAMPLE) == (1008, 1009, 1010, 1016, 1001)
    assert (p.ERR_CLIENT_API_TIMEOUT, p.ERR_SERVER_API_NOT_IMPL, p.ERR_SERVER_API_PARAMETER) == (3104, 3203, 3204)
    assert p.request_topic("sport") == "/api/sport/request"
    assert p.response_topic("videohub") == "/api/videohub/response"
    assert "not implemented" in p.describe_code(3203)


def test_move_request_is_noreply_json() -> None:
    req = p.move_request(0.3, -0.1, 0.5)
    assert req.header.identity.api_id == p.MOVE and req.header.policy.noreply
    assert json.loads(req.parameter) == {"x": 0.3, "y": -0.1, "z": 0.5}
    assert Request.deserialize(req.serialize()) == req


def test_request_ids_are_unique_and_increasing() -> None:
    ids = [p.new_request_id() for _ in range(1000)]
    assert ids == sorted(ids) and len(set(ids)) == len(ids)


def test_response_echoes_identity() -> None:
    req = p.build_request(p.STAND_UP, {})
    ok = p.build_response(req, p.OK, "fine")
    assert ok.header.identity.id == req.header.identity.id and ok.header.identity.api_id == p.STAND_UP
    err = p.build_response(req, p.ERR_SERVER_API_PARAMETER, "ignored", b"ignored")
    assert err.header.status.code == 3204 and err.data == "" and err.binary == b""
    assert Response.deserialize(err.serialize()) == err


def test_result_checks_api_id() -> None:
    req = p.build_request(p.STAND_UP)
    resp = p.build_response(req, p.OK)
    assert p.result_from_response(p.STAND_UP, resp).ok
    assert p.result_from_response(p.SIT, resp).code == p.ERR_CLIENT_API_NOT_MATCH


@pytest.mark.parametrize(
    ("parameter", "binary"),
    [("{not json", b""), ("x" * (p.MAX_PARAMETER_CHARS + 1), b""), ("{}", b"\0" * (p.MAX_REQUEST_BINARY + 1))],
    ids=["malformed", "huge-parameter", "huge-binary"],
)
def test_bad_parameters_are_3204(parameter: str, binary: bytes) -> None:
    with pytest.raises(p.ProtocolError) as exc:
        p.parse_parameter(p.build_request(p.STAND_UP, parameter, binary))
    assert exc.value.code == p.ERR_SERVER_API_PARAMETER


def test_empty_parameter_is_an_empty_object() -> None:
    assert p.parse_parameter(p.build_request(p.GET_IMAGE_SAMPLE, "")) == {}


@pytest.mark.parametrize(
    "params",
    [
        [],
        {"x": 1, "y": 0},
        {"x": "fast", "y": 0, "z": 0},
        {"x": float("nan"), "y": 0, "z": 0},
        {"x": True, "y": 0, "z": 0},
    ],
    ids=["not-object", "missing-z", "string", "nan", "bool"],
)
def test_bad_move_parameters(params: object) -> None:
    with pytest.raises(p.ProtocolError) as exc:
        p.parse_move(params)
    assert exc.value.code == p.ERR_SERVER_API_PARAMETER


def test_move_is_clamped_to_sport_limits() -> None:
    assert p.parse_move({"x": 10, "y": -5, "z": 9}) == (3.8, -1.0, 4.0)
    assert p.parse_move({"x": -10, "y": 0.2, "z": -0.5}) == (-2.5, 0.2, -0.5)


def test_posture_commands() -> None:
    assert p.COMMANDS["stand"] == (p.STAND_UP, p.BALANCE_STAND)
    assert p.COMMANDS["damp"] == (p.DAMP,)
    assert "stand" not in p.ESTOP_ALLOWED and "recover" not in p.ESTOP_ALLOWED and "damp" in p.ESTOP_ALLOWED
