"""The global planner's types: the costmap it plans on, its settings, a plan, and a search's cell path.
Pure (no DDS)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from go2vlm.geometry.footprint import Clearance
from go2vlm.robot_profile.go2 import FOOTPRINT_LENGTH, FOOTPRINT_WIDTH
from go2vlm.world.occupancy import INSCRIBED

__all__ = ["Costmap", "Found", "GlobalParams", "Plan"]


@dataclass(frozen=True)
class Costmap:
    """An inflated costmap: `data` int8 (rows = y, cols = x), `resolution` m per cell, `origin` the
    world (x, y) of cell (0, 0)'s corner, `stamp` when it was made (s, the bus clock)."""

    data: np.ndarray
    resolution: float
    origin: tuple[float, float]
    stamp: float = 0.0

    def __post_init__(self) -> None:
        if self.data.ndim != 2 or self.data.size == 0:
            raise ValueError(f"a costmap is a non-empty 2-D grid, got shape {self.data.shape}")
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"costmap resolution must be a positive number, got {self.resolution}")

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.data.shape[0]), int(self.data.shape[1])

    def cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the world point (x, y) (may lie outside the grid)."""
        return int(math.floor((y - self.origin[1]) / self.resolution)), int(
            math.floor((x - self.origin[0]) / self.resolution)
        )

    def inside(self, rc: tuple[int, int]) -> bool:
        return 0 <= rc[0] < self.shape[0] and 0 <= rc[1] < self.shape[1]

    def world(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """(N, 2) world (x, y) of cell centres."""
        r = self.resolution
        return np.column_stack(
            (self.origin[0] + (np.asarray(cols) + 0.5) * r, self.origin[1] + (np.asarray(rows) + 0.5) * r)
        )


@dataclass(frozen=True)
class GlobalParams:
    lethal: int = INSCRIBED  # a cell this costly or more is never entered (99 inscribed, 100 an obstacle)
    cost_scale: float = 10.0  # a cell of cost v (0..98) costs 1 + cost_scale * v / 100 per cell crossed
    unknown_cost: float = math.inf  # per unknown cell crossed; inf: never
    max_cells: int = 160_000  # larger grids are planned coarse first, then at full resolution round that path
    goal_tolerance_m: float = 0.6  # any passable cell this near the goal (and in sight of it, if asked) is the goal
    goal_in_sight: bool = False  # a place to look at (an object): only cells that see it are near it
    goal_body_m: float = 0.0  # ... and obstacle cells this near it are its own (an object's radius): they hide nothing
    goal_own_m: float = 0.0  # ... and a piece of obstacle wholly within goal_body_m plus this (the place's error)
    # a stand to look round from (a frontier): only cells where the footprint turns in place (cost under
    # CIRCUMSCRIBED), where any is near the goal; the last turn_reach of a path is left unchecked, and a
    # route that ended in the band, 0.3 m from a bathtub, was never reached
    goal_turnable: bool = False
    escape_m: float = 0.6  # a start on a lethal cell plans from the nearest passable cell this near
    off_path_m: float = 0.8  # the robot this far from the route: replan
    replan_period_s: float = 2.0  # a new costmap replans at most this often (a blocked route at once)
    half_length: float = FOOTPRINT_LENGTH / 2  # the footprint checked in the band (m)
    half_width: float = FOOTPRINT_WIDTH / 2
    clearance_m: float = Clearance().creep  # kept round it there: the clearance at a creep
    tight_clearance_m: float = Clearance().creep_m  # where no way keeps that: a crawl's, the rule standing
    # in the band, a turn in place of 45 degrees (where the rectangle sweeps clear) costs as much as
    # walking this far there: a path among furniture weaves where it must, and not for a few cm less
    turn_cost_m: float = 0.25

    def __post_init__(self) -> None:
        if not 1 <= self.lethal <= 100:
            raise ValueError(f"lethal must be within 1..100, got {self.lethal}")
        for name in ("cost_scale", "goal_tolerance_m", "goal_body_m", "goal_own_m", "escape_m", "off_path_m",
                     "replan_period_s", "half_length", "half_width", "clearance_m", "tight_clearance_m",
                     "turn_cost_m"):  # fmt: skip
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v}")
        if not (self.unknown_cost >= 1.0):  # also refuses NaN
            raise ValueError(f"unknown_cost must be >= 1 (or inf: never cross), got {self.unknown_cost}")
        if self.max_cells < 100:
            raise ValueError(f"max_cells must be at least 100, got {self.max_cells}")


@dataclass(frozen=True)
class Plan:
    ok: bool
    reason: str  # why not (a refusal), or what was planned
    waypoints: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (M, 2) world x, y; [0] the start
    cost: float = math.inf  # the search's cost (m, weighted)
    length: float = math.inf  # m along the waypoints
    goal: tuple[float, float] | None = None  # the goal cell reached (world x, y)
    goal_index: int = -1  # plan_path's goals: which one was reached
    stride: int = 1  # the coarsening factor it was planned at
    cells: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=int))  # dense (row, col) path, fine grid
    tight: bool = False  # it keeps tight_clearance_m only: no way kept clearance_m (walked at a crawl)


@dataclass
class Found:
    dense: np.ndarray  # (N, 2) cells from the start cell to the goal cell
    start: tuple[int, int]  # the robot's cell
    escaped: bool  # the search began at a passable cell near it
    goal: tuple[int, int]
    cost: float
    goal_index: int
    ends: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=int))  # every goal cell (row, col)
    owners: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # ... and its goal's index
