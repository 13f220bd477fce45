"""Goal leases and goal bounds (behavior/lease.py): a lease lasts exactly as long as it is renewed,
never past MAX_LEASE_S from the newest renewal; another lease's renewal changes nothing; a /goal
message is a plain goal or a well-formed leased one, and anything else is refused with the reason."""

from __future__ import annotations

import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from go2vlm.behavior.lease import (
    MAX_LEASE_S,
    Lease,
    LeasedGoal,
    LeaseError,
    Renewal,
    goal_end,
    overdue,
    parse_goal,
    parse_renewal,
    too_far,
)

SECONDS = st.floats(0.1, MAX_LEASE_S)
GAPS = st.lists(st.floats(0.0, 5.0), max_size=20)


@given(SECONDS, st.floats(0.0, 1e6), GAPS, SECONDS)
def test_a_lease_lasts_as_long_as_it_is_renewed(lease_s: float, t0: float, gaps: list[float], renew_s: float) -> None:
    lease = Lease.grant("a", lease_s, t0)
    assert lease.expired(t0) is None and lease.expired(t0 + lease_s) is not None
    t = t0
    for gap in gaps:
        t += gap
        alive = lease.expired(t) is None
        assert alive == (t < lease.until)
        if alive:
            assert lease.renew(Renewal("a", renew_s), t)
            assert lease.until == t + renew_s
    # Once renewals stop, it ends within the newest renewal's seconds, never later than MAX_LEASE_S.
    assert lease.expired(t + MAX_LEASE_S) is not None
    assert "stopped renewing" in (lease.expired(lease.until) or "")


@given(SECONDS, st.text(min_size=1, max_size=10, alphabet="abcXYZ019_-"))
def test_another_leases_renewal_changes_nothing(lease_s: float, other: str) -> None:
    lease = Lease.grant("mine", lease_s, 0.0)
    until = lease.until
    if other != "mine":
        assert not lease.renew(Renewal(other, MAX_LEASE_S), 0.05)
        assert lease.until == until and lease.renewals == 0


@given(st.text(max_size=200).filter(lambda t: not t.lstrip().startswith("{")))
def test_plain_text_is_a_goal_without_a_lease(text: str) -> None:
    assert parse_goal(text) == LeasedGoal(text)


@given(st.text(min_size=1, max_size=100).filter(lambda t: t.strip() and not t.lstrip().startswith("{")),
       st.from_regex(r"[A-Za-z0-9_.:-]{1,64}", fullmatch=True), SECONDS)  # fmt: skip
def test_a_leased_goal_round_trips(text: str, lease_id: str, s: float) -> None:
    msg = json.dumps({"goal": text, "lease": {"id": lease_id, "s": s}})
    assert parse_goal(msg) == LeasedGoal(text, lease_id, s)
    assert parse_renewal(json.dumps({"id": lease_id, "s": s})) == Renewal(lease_id, s)


@pytest.mark.parametrize(
    "msg, why",
    [
        ('{"goal": "follow the red ball", "lease": {"id": "x", "s": 1e9}}', "outside"),
        ('{"goal": "follow the red ball", "lease": {"id": "x", "s": NaN}}', "not a number"),
        ('{"goal": "follow the red ball", "lease": {"id": "x", "s": true}}', "not a number"),
        ('{"goal": "follow the red ball", "lease": {"id": "", "s": 2}}', "lease id"),
        ('{"goal": "follow the red ball", "lease": {"id": "a b", "s": 2}}', "lease id"),
        ('{"goal": "follow the red ball", "lease": 5}', "'lease'"),
        ('{"lease": {"id": "x", "s": 2}}', "needs 'goal'"),
        ('{"goal": "{\\"goal\\": 1}"}', "needs 'goal'"),
        ("{not json", "not JSON"),
        ("[" * 100_000, "at most"),
        ("{" + '"a":' * 300 + "1" + "}" * 300, "at most"),
        ('["follow"]', "not JSON"),
    ],
)
def test_a_bad_goal_message_is_refused_with_the_reason(msg: str, why: str) -> None:
    if msg.startswith("["):  # not '{': a plain (unparseable) goal for the commander to reject, or too long
        if len(msg) > 1000:
            with pytest.raises(LeaseError, match=why):
                parse_goal(msg)
        else:
            assert parse_goal(msg).lease_id is None
        return
    with pytest.raises(LeaseError, match=why):
        parse_goal(msg)


def test_deep_json_renewals_are_refused() -> None:
    with pytest.raises(LeaseError):
        parse_renewal("[" * 900 + "]" * 900)
    with pytest.raises(LeaseError, match="lease id"):
        parse_renewal('{"id": ' + "[" * 400 + "]" * 400 + "}")


@given(st.floats(0.0, 1e6), st.floats(0.0, 1e4), st.floats(1.0, 1e4))
def test_overdue_exactly_after_max_goal_s(t0: float, ran: float, max_s: float) -> None:
    assert (overdue(t0, t0 + ran, max_s) is not None) == ((t0 + ran) - t0 >= max_s)


@given(st.sampled_from(["go_to", "follow", "look_for", None]), st.none() | st.floats(0.0, 1e7), st.floats(0.5, 500))
def test_too_far_refuses_only_a_go_to_beyond_the_cap(kind: str | None, d: float | None, cap: float) -> None:
    why = too_far(kind, d, cap)
    assert (why is not None) == (kind == "go_to" and d is not None and d > cap)
    if why:
        assert "max_go_to_m" in why


@given(
    st.none() | st.just("the goal's lease 'x' expired"), st.floats(0.0, 1e4), st.floats(1.0, 1e4),
    st.sampled_from(["go_to", "follow", "look_for", None]), st.none() | st.floats(0.0, 1e3), st.floats(0.5, 500),
)  # fmt: skip
def test_a_goal_ends_stopped_before_it_is_refused(
    lease_why: str | None, ran: float, max_s: float, kind: str | None, d: float | None, cap: float
) -> None:
    """An expired lease or an overdue goal stops it (and says why); only a goal that may go on is
    refused for its distance; a goal within every bound goes on."""
    end = goal_end(lease_why, 0.0, ran, max_s, kind, d, cap)
    stop = lease_why or overdue(0.0, ran, max_s)
    if stop:
        assert end == ("stopped", f"stopped: {stop}")
    elif too_far(kind, d, cap):
        assert end is not None and end[0] == "rejected" and "max_go_to_m" in end[1]
    else:
        assert end is None


def test_a_lease_reports_its_id_and_what_is_left() -> None:
    assert Lease.grant("x", 2.0, 10.0).status(11.0) == {"id": "x", "left_s": 1.0}
    assert Lease.grant("x", 2.0, 10.0).status(13.0) == {"id": "x", "left_s": 0.0}
