"""A domain of one's own (bus/domain.py claim_free_domain): one that Cyclone cannot start, because
another socket on this host holds one of its fixed ports, is not free."""

from __future__ import annotations

import random
import socket

import pytest

from go2vlm.bus.domain import claim_free_domain
from go2vlm.bus.params import ParamError


def test_a_domain_whose_port_another_socket_holds_is_not_claimed() -> None:
    """From domain 102 on, a domain's discovery port (7400 + 250 x id) lies in the ephemeral range,
    where any process's UDP socket may hold it; Cyclone then cannot start the domain at all. The claim
    passes it by (here: no other in the range, ParamError), where it raised DDS_RETCODE_ERROR out of a
    Ray eval task."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for d in random.Random().sample(range(200, 231), 31):
            try:
                s.bind(("0.0.0.0", 7400 + 250 * d))
                break
            except OSError:  # held already: try another
                continue
        with pytest.raises(ParamError, match="no free DDS domain"):
            claim_free_domain(d, d, "lo")
