"""Goal leases and goal bounds without any I/O: nothing outlives the order that started it.

A goal may carry a lease: its owner (the MCP server, a script) sends it as JSON on /goal and renews
it on /goal/lease; the commander stops the goal when no renewal came within the lease's seconds.
The commander enforces it, not the client, so an owner that dies (SIGKILL, a crash, a lost network)
leaves a still robot within one lease.

Only the goal's sender can renew it. The goal carries `key`, the SHA-256 of a secret only the sender
holds; a renewal shows that secret (`proof`) and the SHA-256 of the next one (`next`), which becomes
the key for the renewal after. Every secret is fresh (32 random bytes) and shown once: one seen on
the bus has already been used, and the next one cannot be worked out from its hash. A renewal whose
proof does not hash to the key changes nothing (the commander counts it). The bus proves no more
than that (docs/safety.md#what-the-bus-can-prove): anyone on it can still send a goal of its own.

    {"goal": "follow the red ball", "lease": {"key": "9f86...", "s": 2.0}}          on /goal
    {"proof": "<the secret, hex>", "next": "<sha256 of the next, hex>", "s": 2.0}   on /goal/lease

    keys = LeaseKeys()                       # the sender's side: keys.key, then keys.renewal(s) each time
    goal = parse_goal(text)                  # a plain text goal, or one with a lease (LeaseError if bad)
    lease = Lease.grant(goal.lease_key, goal.lease_s, now)
    lease.renew(renewal, now)                # True when it proved it comes from the goal's sender
    lease.expired(now)                       # a reason to stop, or None

A lease is at most MAX_LEASE_S, and no renewal asks for more than the goal's lease: an owner cannot
ask for a goal that outlives it by more. Plain text
goals carry none (a person at a terminal, a launch file's goal); they keep the goal timeout and the
go-to distance cap (`overdue`, `too_far`; `goal_end` puts them together), which bound every goal.
Teleop and the e-stop have their own watchdogs (safety/). Timestamps are the caller's: the commander
feeds wall time to leases (an owner's silence is wall time) and its own clock to the goal timeout.
Property tests: tests/behavior/test_behavior_lease.py.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import math
import re
import secrets
from dataclasses import dataclass, field

__all__ = ["MAX_LEASE_S", "Lease", "LeaseError", "LeaseKeys", "LeasedGoal", "Renewal", "goal_end", "overdue",
           "parse_goal", "parse_renewal", "too_far"]  # fmt: skip

MAX_LEASE_S = 60.0
MIN_LEASE_S = 0.1
MAX_GOAL_CHARS = 1000
_HEX32 = re.compile(r"[0-9a-f]{64}")  # 32 bytes, lower-case hex: a secret or its SHA-256


class LeaseError(ValueError):
    """A leased goal or a renewal that is not well formed; the message says why."""


@dataclass(frozen=True)
class LeasedGoal:
    text: str  # the goal itself ("follow the red ball")
    lease_key: bytes | None = None  # SHA-256 of the sender's first secret; None: no lease
    lease_s: float = 0.0


@dataclass(frozen=True)
class Renewal:
    proof: bytes  # the secret whose SHA-256 is the lease's key now
    next_key: bytes  # SHA-256 of the secret the next renewal shows
    lease_s: float


def _digest(secret: bytes) -> bytes:
    return hashlib.sha256(secret).digest()


@dataclass
class LeaseKeys:
    """The sender's side of a lease: a fresh secret per renewal; only their hashes go ahead of them."""

    _secret: bytes = field(default_factory=lambda: secrets.token_bytes(32), repr=False)

    @property
    def key(self) -> str:
        """What the goal carries as "key": the hash of the secret the first renewal will show."""
        return _digest(self._secret).hex()

    def renewal(self, lease_s: float) -> str:
        """The next /goal/lease message: this secret, and the hash of a fresh one for the next time."""
        proof, self._secret = self._secret, secrets.token_bytes(32)
        return json.dumps({"proof": proof.hex(), "next": self.key, "s": lease_s})


def _seconds(v: object, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise LeaseError(f"{what} is not a number of seconds: {v!r}")
    if not MIN_LEASE_S <= v <= MAX_LEASE_S:
        raise LeaseError(f"{what} = {v:g} s is outside {MIN_LEASE_S:g}..{MAX_LEASE_S:g} s")
    return float(v)


def _hex32(v: object, what: str) -> bytes:
    if not isinstance(v, str) or not _HEX32.fullmatch(v):
        raise LeaseError(f"{what} is 64 lower-case hex digits (32 bytes); got {str(v)[:80]!r}")
    return bytes.fromhex(v)


def _json_object(text: str, what: str) -> dict[str, object]:
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise LeaseError(f"{what} is not JSON: {str(exc)[:80]}") from None
    if not isinstance(doc, dict):
        raise LeaseError(f"{what} is not a JSON object")
    return doc


def parse_goal(text: str) -> LeasedGoal:
    """A /goal message: plain text (no lease), or a JSON object {"goal": ..., "lease": {"key", "s"}}."""
    if len(text) > MAX_GOAL_CHARS:
        raise LeaseError(f"a goal of {len(text)} characters; at most {MAX_GOAL_CHARS}")
    if not text.lstrip().startswith("{"):
        return LeasedGoal(text)
    doc = _json_object(text, "a goal that starts with '{'")
    goal, lease = doc.get("goal"), doc.get("lease")
    if not isinstance(goal, str) or not goal.strip() or goal.lstrip().startswith("{"):
        raise LeaseError("a JSON goal needs 'goal': the goal's text")
    if lease is None:
        return LeasedGoal(goal)
    if not isinstance(lease, dict):
        raise LeaseError("'lease' is not {'key': sha256 hex, 's': seconds}")
    return LeasedGoal(goal, _hex32(lease.get("key"), "the lease's key"), _seconds(lease.get("s"), "the lease"))


def parse_renewal(text: str) -> Renewal:
    """A /goal/lease message: {"proof": secret hex, "next": sha256 hex, "s": seconds}."""
    if len(text) > MAX_GOAL_CHARS:
        raise LeaseError(f"a renewal of {len(text)} characters")
    doc = _json_object(text, "a renewal")
    return Renewal(
        _hex32(doc.get("proof"), "a renewal's proof"),
        _hex32(doc.get("next"), "a renewal's next key"),
        _seconds(doc.get("s"), "the renewal"),
    )


@dataclass
class Lease:
    """One goal's lease: it lasts until `until` unless renewed by the goal's sender."""

    key: bytes = field(repr=False)  # the SHA-256 the next renewal's proof must hash to
    until: float
    lease_s: float  # as granted with the goal: no renewal asks for more
    renewals: int = 0

    @classmethod
    def grant(cls, key: bytes, lease_s: float, now: float) -> Lease:
        s = min(max(lease_s, MIN_LEASE_S), MAX_LEASE_S)
        return cls(key, now + s, s)

    def renew(self, r: Renewal, now: float) -> bool:
        """Extend the lease to now + r.lease_s (never past the seconds granted with the goal) if the
        renewal proves it comes from the goal's sender: its proof hashes to the key; its next key is the
        one after. The cap makes a renewal copied off the bus and sent faster than the original worth
        no more than the original."""
        if not hmac.compare_digest(_digest(r.proof), self.key):
            return False
        self.key = r.next_key
        self.until = now + min(max(r.lease_s, MIN_LEASE_S), self.lease_s)
        self.renewals += 1
        return True

    def left(self, now: float) -> float:
        return max(0.0, self.until - now)

    def expired(self, now: float) -> str | None:
        if now < self.until:
            return None
        return f"the goal's lease expired: its owner stopped renewing it ({self.renewals} renewals)"

    def status(self, now: float) -> dict[str, object]:
        """What /commander/status says of it: how long it has left, never its key."""
        return {"left_s": round(self.left(now), 2), "renewals": self.renewals}


def overdue(started: float, now: float, max_goal_s: float) -> str | None:
    """A reason to end a goal that has run longer than max_goal_s (0 = no limit), or None."""
    if max_goal_s <= 0 or now - started < max_goal_s:
        return None
    return f"the goal ran {now - started:.0f} s, the limit is max_goal_s = {max_goal_s:g} s"


def too_far(kind: str | None, distance_m: float | None, max_go_to_m: float) -> str | None:
    """A reason to refuse a go to whose object is farther than max_go_to_m (0 = no limit), or None."""
    if kind != "go_to" or distance_m is None or max_go_to_m <= 0 or not math.isfinite(distance_m):
        return None
    if distance_m <= max_go_to_m:
        return None
    return f"refused: the object is {distance_m:.1f} m away, beyond max_go_to_m = {max_go_to_m:g} m"


def goal_end(
    lease_why: str | None,
    started: float,
    now: float,
    max_goal_s: float,
    kind: str | None,
    distance_m: float | None,
    max_go_to_m: float,
) -> tuple[str, str] | None:
    """How a running goal ends now, as (state, reason): `stopped` when its lease ran out (`lease_why`,
    from Lease.expired) or it ran past max_goal_s; else `rejected` when it is a go to whose object is
    beyond max_go_to_m; None: it goes on."""
    why = lease_why or overdue(started, now, max_goal_s)
    if why:
        return "stopped", f"stopped: {why}"
    refused = too_far(kind, distance_m, max_go_to_m)
    return None if refused is None else ("rejected", refused)
