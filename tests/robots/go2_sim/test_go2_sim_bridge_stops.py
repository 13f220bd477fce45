"""Stops through the sim's Unitree bridge are never dropped, as real processes over real DDS: a
Damp followed at once by a burst of 5,000 Moves holds every time (an answer "ok" means applied),
and while the sim's e-stop is latched no raw sport request moves it (Move at 3.8 m/s ignored,
StandUp answered 3205)."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from typing import Any

import pytest
from busutil import Procs, Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_UNITREE_READER, QOS_UNITREE_WRITER, Node
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.msgs.unitree import Request, Response
from go2vlm.robots.go2 import protocol as p

SIM = [
    "run", "sim",
    *("--param", "unitree=true", "--param", "mode=kinematic", "--param", "world=vision_test"),
    *("--param", "camera=false", "--param", "world_camera=false"),
]  # fmt: skip
BURST = 5000
TRIALS = 5


# Slow: the sim runs as a process for the module, and the burst test runs five trials.
pytestmark = pytest.mark.slow


class Client(Node):
    """A raw sport client (as any unitree_sdk2 program is), plus what the sim says about itself."""

    name = "raw_sport_client"

    def __init__(self) -> None:
        super().__init__()
        self.odom, self.status, self.responses = Recorder(), Recorder(), Recorder()
        self.create_subscription(Odometry, "/odom", self.odom, QOS_DEFAULT)
        self.create_subscription(String, "/sim/status", lambda m: self.status(json.loads(m.data)), QOS_LATCHED)
        self.create_subscription(Response, p.response_topic(p.SPORT_SERVICE), self.responses, QOS_UNITREE_READER)
        self.requests = self.create_publisher(Request, p.request_topic(p.SPORT_SERVICE), QOS_UNITREE_WRITER)
        self.estop = self.create_publisher(Bool, "/emergency_stop", QOS_LATCHED)
        self.release = self.create_publisher(String, "/emergency_stop/release", QOS_DEFAULT)

    def answer(self, req: Request, timeout: float) -> Response | None:
        rid = req.header.identity.id
        found: list[Response] = []

        def answered() -> bool:
            found[:] = [r for r in self.responses.msgs() if r.header.identity.id == rid]
            return bool(found)

        return found[0] if wait_for(answered, timeout, period=0.01) else None

    def call(self, api: int, timeout: float = 5.0) -> Response | None:
        req = p.build_request(api)
        self.requests.publish(req)
        return self.answer(req, timeout)

    def mode(self) -> str:
        items = self.status.msgs()
        return items[-1]["mode"] if items else ""

    def x(self) -> float:
        return self.odom.msgs()[-1].pose.pose.position.x

    def last_status(self) -> dict[str, Any]:
        return self.status.msgs()[-1]


@pytest.fixture(scope="module")
def sim() -> Iterator[Client]:
    procs = Procs()
    client = Client().start()
    try:
        procs.start(*SIM)
        assert wait_for(lambda: len(client.odom) > 5 and client.mode() == "standing", 60), "the sim did not start"
        assert wait_for(lambda: client.requests.matched > 0, 10)
        yield client
    finally:
        client.shutdown()
        procs.stop_all()


def stand(c: Client) -> None:
    resp = c.call(p.RECOVERY_STAND) or c.call(p.RECOVERY_STAND)
    assert resp is not None and resp.header.status.code == p.OK
    assert wait_for(lambda: c.mode() == "standing", 20), c.mode()


def test_a_damp_holds_under_a_burst_of_moves(sim: Client) -> None:
    c = sim
    first_time = 0
    for trial in range(TRIALS):
        stand(c)
        for _ in range(5):  # walking when the Damp comes
            c.requests.publish(p.move_request(0.5, 0.0, 0.0))
            time.sleep(0.02)
        damp = p.build_request(p.DAMP)
        c.requests.publish(damp)
        for _ in range(BURST):
            c.requests.publish(p.move_request(3.8, 0.0, 0.0))
        resp = c.answer(damp, 10.0)
        if resp is not None and resp.header.status.code == p.OK:
            first_time += 1
        else:  # not acknowledged means not applied: the client retries (the go2 driver does)
            resp = c.call(p.DAMP, 10.0)
            assert resp is not None and resp.header.status.code == p.OK, f"trial {trial}: no Damp at all"
        # Acknowledged means applied: damped now, and the burst (still arriving) moves nothing.
        assert c.mode() in ("damped", "damping") or wait_for(lambda: c.mode() == "damped", 2), c.mode()
        x0 = c.x()
        time.sleep(1.0)
        assert c.mode() == "damped", f"trial {trial}: the Damp did not hold ({c.mode()})"
        assert abs(c.x() - x0) < 0.01, f"trial {trial}: moved {c.x() - x0:.3f} m after an acknowledged Damp"
    assert first_time >= 1, "the first Damp of a trial is acknowledged at least once in five"
    print(f"Damp acknowledged at the first try in {first_time} of {TRIALS} trials (burst of {BURST} Moves)")


def test_the_sim_estop_refuses_raw_sport_requests(sim: Client) -> None:
    c = sim
    stand(c)
    c.estop.publish(Bool(data=True))
    assert wait_for(lambda: c.last_status()["estop"] is True and c.mode() == "damped", 10)
    x0 = c.x()
    for api in (p.STAND_UP, p.RECOVERY_STAND, p.BALANCE_STAND):
        resp = c.call(api)
        assert resp is not None and resp.header.status.code == p.ERR_SERVER_LEASE_DENIED, api
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        c.requests.publish(p.move_request(3.8, 0.0, 0.0))
        time.sleep(0.01)
    assert c.mode() == "damped" and abs(c.x() - x0) < 0.01
    resp = c.call(p.DAMP)  # what the e-stop allows is still obeyed and answered
    assert resp is not None and resp.header.status.code == p.OK
    c.release.publish(String(data="RELEASE"))
    assert wait_for(lambda: c.last_status()["estop"] is False, 10)
    stand(c)
