"""The approach law: turn first, then walk, stop at the distance, never walk blind."""

from __future__ import annotations

import pytest

from go2vlm.behavior.approach import approach_command
from go2vlm.behavior.mission import MissionParams


def test_approach_command_turns_first_then_walks_and_stops_at_the_distance() -> None:
    p = MissionParams(max_linear=0.4, max_angular=0.8).approach(0.8)
    vx, wz, done = approach_command(0.8, 3.0, p)
    assert vx == 0.0 and wz < 0 and not done  # target on the right: turn right, do not walk yet
    vx, wz, done = approach_command(0.0, 3.0, p)
    assert vx == pytest.approx(0.4) and wz == 0.0 and not done
    assert approach_command(0.0, 0.84, p) == (0.0, 0.0, True)
    vx, _, _ = approach_command(0.0, None, p)
    assert vx == 0.0  # unknown distance: never walk blind
