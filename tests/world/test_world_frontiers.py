"""Frontiers (world/frontiers.py): free cells next to unknown, clustered, tiny ones dropped, each with
a goal cell the robot can stand on."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from go2vlm.world.frontiers import FrontierParams, find_frontiers, frontier_cells, gains

RES = 0.05


def test_known_room_with_an_open_door() -> None:
    g = np.full((100, 200), -1, np.int8)
    g[10:90, 10:100] = 0  # a known room
    g[10:90, 10] = g[10:90, 99] = 100
    g[10, 10:100] = g[89, 10:100] = 100
    g[40:60, 99] = 0  # its door, 1 m, onto the unknown
    fs = find_frontiers(g, RES, (-1.0, -2.0), FrontierParams())
    assert len(fs) == 1
    f = fs[0]
    assert f.size_m == pytest.approx(20 * RES)
    assert f.goal_cell[1] == 99 and 40 <= f.goal_cell[0] < 60
    assert f.goal == pytest.approx((-1.0 + 99.5 * RES, -2.0 + (f.goal_cell[0] + 0.5) * RES))
    assert g[f.goal_cell] == 0
    # A door narrower than min_size_m is no frontier.
    g[40:60, 99] = 100
    g[50:54, 99] = 0
    assert find_frontiers(g, RES, (0.0, 0.0), FrontierParams(min_size_m=0.5)) == []


def test_unreachable_or_unstandable_frontiers_are_dropped() -> None:
    g = np.full((50, 50), -1, np.int8)
    g[10:40, 10:40] = 99  # known, but all inscribed: nowhere to stand
    assert find_frontiers(g, RES, (0.0, 0.0), FrontierParams()) == []
    g[10:40, 10:40] = 0
    assert len(find_frontiers(g, RES, (0.0, 0.0), FrontierParams())) == 1
    none = np.zeros(g.shape, bool)
    assert find_frontiers(g, RES, (0.0, 0.0), FrontierParams(), reachable=none) == []
    with pytest.raises(ValueError):
        find_frontiers(g, RES, (0.0, 0.0), FrontierParams(), reachable=np.zeros((3, 3), bool))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from([-1, 0, 0, 30, 99, 100]), min_size=400, max_size=400), st.floats(0.0, 0.6))
def test_frontier_properties(cells, min_size) -> None:
    g = np.array(cells, np.int8).reshape(20, 20)
    p = FrontierParams(min_size_m=min_size)
    mask = frontier_cells(g)
    assert not (mask & ((g == -1) | (g == 100))).any()
    fs = find_frontiers(g, RES, (0.0, 0.0), p)
    for f in fs:
        r, c = f.goal_cell
        assert mask[r, c] and 0 <= g[r, c] < p.lethal  # a frontier cell to stand on
        assert (g[max(0, r - 1) : r + 2, max(0, c - 1) : c + 2] == -1).any()  # next to unknown
        assert f.size_m >= min_size - 1e-9 and f.size >= 1
    assert sum(f.size for f in fs) <= int(mask.sum())
    assert [f.size for f in fs] == sorted((f.size for f in fs), reverse=True)
    if not (g == -1).any() or not ((g >= 0) & (g < 99)).any():
        assert fs == []


def test_a_doorway_frontier_counts_its_inflated_cells() -> None:
    # A 1.2 m door whose middle 0.3 m only is free of the footprint's circumscribed radius (99 beside).
    g = np.full((60, 60), -1, np.int8)
    g[:, 30:] = 0
    g[:, 30] = 100
    g[18:42, 30] = 99
    g[28:34, 30] = 0
    fs = find_frontiers(g, RES, (0.0, 0.0), FrontierParams(min_size_m=0.5))
    assert len(fs) == 1 and fs[0].size_m >= 1.2 - 1e-9
    assert 28 <= fs[0].goal_cell[0] < 34 and fs[0].goal_cell[1] == 30


@settings(max_examples=50)
@given(seed=st.integers(0, 10_000), radius=st.floats(0.0, 1.0))
def test_a_frontiers_gain_is_the_area_of_its_window(seed: int, radius: float) -> None:
    """gains (an integral image) = the masked cells counted one by one in the square window, in m^2."""
    rng = np.random.default_rng(seed)
    mask, res = rng.random((30, 40)) < 0.3, 0.05
    cells = np.column_stack((rng.integers(0, 30, 12), rng.integers(0, 40, 12)))
    r = int(round(radius / res))
    brute = [mask[max(0, a - r) : a + r + 1, max(0, b - r) : b + r + 1].sum() * res**2 for a, b in cells]
    assert np.allclose(gains(mask, res, cells, radius), brute)
