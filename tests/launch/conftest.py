"""Fixtures for the launched-pipeline tests: the in-process probe."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from pipeutil import Probe


@pytest.fixture
def probe() -> Iterator[Probe]:
    """The in-process pipeline probe (pipeutil.Probe), started before a test and shut down after it."""
    p = Probe()
    p.start()
    yield p
    p.shutdown()
