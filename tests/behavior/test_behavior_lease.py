"""Goal leases and goal bounds (behavior/lease.py): a lease lasts exactly as long as its sender renews
it, never past the goal's own lease seconds from the newest renewal; anyone else's renewal (a stranger's, a replayed
one, one out of turn) changes nothing; a /goal
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
    LeaseKeys,
    goal_end,
    overdue,
    parse_goal,
    parse_renewal,
    too_far,
)

SECONDS = st.floats(0.1, MAX_LEASE_S)
GAPS = st.lists(st.floats(0.0, 5.0), max_size=20)


def _grant(keys: LeaseKeys, lease_s: float, now: float) -> Lease:
    goal = parse_goal(json.dumps({"goal": "follow the red ball", "lease": {"key": keys.key, "s": lease_s}}))
    assert goal.lease_key is not None
    return Lease.grant(goal.lease_key, goal.lease_s, now)


@given(SECONDS, st.floats(0.0, 1e6), GAPS, SECONDS)
def test_a_lease_lasts_as_long_as_its_sender_renews_it(
    lease_s: float, t0: float, gaps: list[float], renew_s: float
) -> None:
    keys = LeaseKeys()
    lease = _grant(keys, lease_s, t0)
    assert lease.expired(t0) is None and lease.expired(t0 + lease_s) is not None
    t = t0
    for gap in gaps:
        t += gap
        alive = lease.expired(t) is None
        assert alive == (t < lease.until)
        if alive:
            assert lease.renew(parse_renewal(keys.renewal(renew_s)), t)
            assert lease.until == t + min(renew_s, lease_s)
    # Once renewals stop, it ends within the newest renewal's seconds, never later than the goal's lease.
    assert lease.expired(t + MAX_LEASE_S) is not None
    assert "stopped renewing" in (lease.expired(lease.until) or "")


@given(SECONDS, st.integers(0, 5), st.integers(0, 3))
def test_only_the_goals_sender_renews_it(lease_s: float, before: int, replayed: int) -> None:
    """A stranger's renewal (its own secrets), a renewal seen on the bus and sent again, a proof out of
    turn, or one that is its own key: none changes anything."""
    keys, stranger = LeaseKeys(), LeaseKeys()
    lease = _grant(keys, lease_s, 0.0)
    seen = [keys.renewal(lease_s) for _ in range(before + 1)]
    for text in seen[:-1]:
        assert lease.renew(parse_renewal(text), 0.01)
    until, n = lease.until, lease.renewals
    ahead = keys.renewal(MAX_LEASE_S)  # the one after next: out of turn
    forged = json.loads(ahead)
    forged["proof"] = lease.key.hex()  # the key itself is no proof
    for text in (stranger.renewal(MAX_LEASE_S), ahead, json.dumps(forged), *seen[: min(replayed, before)]):
        assert not lease.renew(parse_renewal(text), 0.05)
    assert lease.until == until and lease.renewals == n
    assert lease.renew(parse_renewal(seen[-1]), 0.05)  # its sender's, in turn


@given(SECONDS)
def test_a_copied_renewal_that_wins_the_race_is_worth_no_more_than_the_original(lease_s: float) -> None:
    """A renewal copied off the bus, asking for 60 s and arriving before the original, takes the
    original's place: the lease runs to the goal's seconds, and the sender's next renewal still works."""
    keys = LeaseKeys()
    lease = _grant(keys, lease_s, 0.0)
    original = json.loads(keys.renewal(lease_s))
    assert lease.renew(parse_renewal(json.dumps({**original, "s": MAX_LEASE_S})), 1.0)
    assert lease.until == 1.0 + lease_s
    assert not lease.renew(parse_renewal(json.dumps(original)), 1.01)  # the original: already spent
    assert lease.renew(parse_renewal(keys.renewal(lease_s)), 1.02)


@given(st.text(max_size=200).filter(lambda t: not t.lstrip().startswith("{")))
def test_plain_text_is_a_goal_without_a_lease(text: str) -> None:
    assert parse_goal(text) == LeasedGoal(text)


@given(st.text(min_size=1, max_size=100).filter(lambda t: t.strip() and not t.lstrip().startswith("{")), SECONDS)
def test_a_leased_goal_round_trips(text: str, s: float) -> None:
    keys = LeaseKeys()
    msg = json.dumps({"goal": text, "lease": {"key": keys.key, "s": s}})
    assert parse_goal(msg) == LeasedGoal(text, bytes.fromhex(keys.key), s)
    r = parse_renewal(keys.renewal(s))
    assert r.lease_s == s and r.next_key == bytes.fromhex(keys.key)


KEY = "ab" * 32


@pytest.mark.parametrize(
    "msg, why",
    [
        ('{"goal": "follow the red ball", "lease": {"key": "KEY", "s": 1e9}}', "outside"),
        ('{"goal": "follow the red ball", "lease": {"key": "KEY", "s": NaN}}', "not a number"),
        ('{"goal": "follow the red ball", "lease": {"key": "KEY", "s": true}}', "not a number"),
        ('{"goal": "follow the red ball", "lease": {"key": "", "s": 2}}', "64 lower-case hex"),
        ('{"goal": "follow the red ball", "lease": {"key": "%s", "s": 2}}' % KEY.upper(), "64 lower-case hex"),  # noqa: UP031
        ('{"goal": "follow the red ball", "lease": {"id": "mcp-5f3a", "s": 2}}', "the lease's key"),
        ('{"goal": "follow the red ball", "lease": 5}', "'lease'"),
        ('{"lease": {"key": "KEY", "s": 2}}', "needs 'goal'"),
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
            assert parse_goal(msg).lease_key is None
        return
    with pytest.raises(LeaseError, match=why):
        parse_goal(msg.replace("KEY", KEY))


def test_bad_renewals_are_refused_with_the_reason() -> None:
    with pytest.raises(LeaseError):
        parse_renewal("[" * 900 + "]" * 900)
    with pytest.raises(LeaseError, match="proof"):
        parse_renewal('{"proof": ' + "[" * 400 + "]" * 400 + "}")
    with pytest.raises(LeaseError, match="proof"):
        parse_renewal('{"id": "mcp-5f3a", "s": 2}')  # the old form: an id proves nothing
    with pytest.raises(LeaseError, match="next key"):
        parse_renewal(json.dumps({"proof": KEY, "s": 2}))


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


def test_a_lease_reports_what_is_left_never_its_key() -> None:
    assert Lease.grant(bytes(32), 2.0, 10.0).status(11.0) == {"left_s": 1.0, "renewals": 0}
    assert Lease.grant(bytes(32), 2.0, 10.0).status(13.0) == {"left_s": 0.0, "renewals": 0}
