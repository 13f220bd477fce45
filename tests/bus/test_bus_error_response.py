"""bus/service.py's error reply: the response a caller gets when a handler fails (the raising handler over
real DDS is tests/attack/test_attack_service.py): defaults everywhere, the reason where the type has text."""

from __future__ import annotations

from go2vlm.bus.service import error_response
from go2vlm.msgs import rcl_interfaces as rcl
from go2vlm.msgs.go2vlm_msgs import MemoryFile, WhereIs


def test_the_reason_goes_where_the_type_has_text() -> None:
    rep = error_response(MemoryFile.Response, "error: boom")
    assert (rep.success, rep.message, rep.objects) == (False, "error: boom", 0)
    rep2 = error_response(WhereIs.Response, "error: boom")
    assert (rep2.found, rep2.message, rep2.objects) == (False, "error: boom", [])
    atomically = error_response(rcl.SetParametersAtomically_Response, "error: boom")
    assert not atomically.result.successful and atomically.result.reason == "error: boom"  # one level down
    assert error_response(rcl.GetParameters_Response, "error: boom") == rcl.GetParameters_Response()  # no text: empty
