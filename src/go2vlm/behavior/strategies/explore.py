"""The search that leaves the room: when the goal's object is neither remembered nor found by the
look-around where the robot stands, walk to a frontier (world/frontiers.py: free space next to
unknown), look around there, and repeat. Pure and timestamp-driven: `Explorer` is the core (where to
walk next); `Explore` (strategies/explore_search.py) the SearchStrategy (strategies/base.py) that the
mission asks once turn-and-look is exhausted (Mission.searches).

    ex = Explorer(ExploreParams())
    ex.set_map(costmap)                 # each new /map/costmap (behavior/planner/global_path.Costmap)
    step = ex.step(x, y, yaw, now)      # walk (to step.goal: the navigator's job) | look | wait | done
    ex.arrived()                        # the navigator is there: look
    ex.looked(now)                      # the host's look-around at the frontier is over

Rules
- Frontiers (world/frontiers.py) of the newest costmap, less those given up on (within
  `visited_radius_m`) and those looked at: a map frontier where the robot stood to look (within
  `arrive_m`), unseen free space within `visited_radius_m` of a place looked from.
  `frontier_choice`: `gain` (the default) takes the one
  that reveals most for its walk: its gain (world/frontiers.py `gains`: the unknown and the unseen
  free area within `gain_radius_m` of it) less `gain_per_m` times its path cost (one search of the
  global planner to every goal, the navigator's `costs`), so a room through a door
  outranks a corner of this one the scan has not reached; `nearest` takes the nearest by
  path cost (one search of the global planner to all their goals at once, crossing unknown space at
  `unknown_cost`); `vlm` takes, of the frontiers the model's value map scores highest (VLFM:
  world/value_map.py, each whitelisted answer about a view, behavior/view_scores.py, spread over
  what that view could see, `values.observe(...)`; a frontier's value is the map's round it), the
  nearest by path cost; a frontier no view covered counts as maybe, so without answers it is `nearest`.
- Walk there: the chosen frontier's goal is handed to the navigator (behavior/navigate/: it follows
  the plan it made to choose it, `choose`, replans, checks progress and runs its recoveries). A frontier the
  lidar has seen past on the way is still walked to and looked from (the lidar reaches 10 m, the
  camera's answers less: the look is what finds the object); one whose goal is no place to stand on
  the new map, or that the navigator gives up on (`failed`: no route, or no progress after every
  recovery), is given up. A frontier given up comes back once the map round it has changed (more
  than `regrown_share` more cells known within `visited_radius_m`), or when no other is reachable.
- Within `arrive_m` of the goal (or the navigator arrived: its route ends within `arrive_m` less the
  navigator's own `arrive_m` of the goal, `route_params`, so the robot stands within `arrive_m` of
  it): `look` (the host turns and looks), then `looked(at)`: where it stood is a place looked from,
  and the next frontier is chosen.
- None reachable (and none given up to bring back): first `refresh`, a whole turn where it stands
  (the host turns, then `looked()`): the map round the robot is seen again, from every side, before
  its gaps are taken for walls (standing still, the map the plan failed on does not change).
- `done` (the goal ends not_found, with the reason) when no frontier is left, or none has been
  reachable, after that turn, for `unreachable_wait_s` (planned again on each new map meanwhile,
  holding still), or `timeout_s` after the goal began (an open world has frontiers without end).
  `wait` (hold still) without a map or a pose; after `map_timeout_s` without any map: done.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from go2vlm.behavior.navigate import Navigator
from go2vlm.behavior.planner.global_path import Costmap, GlobalParams
from go2vlm.behavior.strategies.explore_params import FRONTIER_CHOICES, ExploreParams
from go2vlm.world.coverage import Coverage
from go2vlm.world.frontiers import Frontier, FrontierParams, clusters, find_frontiers, gains
from go2vlm.world.occupancy import UNKNOWN
from go2vlm.world.value_map import ValueMap

__all__ = ["FRONTIER_CHOICES", "ExploreParams", "ExploreStep", "Explorer"]


@dataclass(frozen=True)
class ExploreStep:
    action: str  # walk | look | refresh | wait | done
    reason: str
    goal: tuple[float, float] = (0.0, 0.0)  # walk: the frontier's goal, for the navigator


class Explorer:
    def __init__(self, params: ExploreParams | None = None, navigator: Navigator | None = None) -> None:
        self.params = params or ExploreParams()
        self.navigator = navigator or Navigator()  # plans and costs every way (the host's, which walks it)
        self.costmap: Costmap | None = None
        self.coverage: Coverage | None = None  # where the camera has looked (the host's; None: the map only)
        self.reset(0.0)

    def reset(self, now: float) -> None:
        """A new search: forget the frontiers visited and given up (the map stays)."""
        self.t0 = now
        self.phase = "choose"  # choose | walk | look | done
        self.frontier: Frontier | None = None
        self.frontiers: list[Frontier] = []  # the newest map's, less the visited
        self.visited: list[tuple[float, float]] = []  # places looked from
        self.dropped: list[tuple[tuple[float, float], int]] = []  # given up: (goal, the map round it then)
        self.given_up = 0
        self.retried = 0  # times the given-up frontiers were brought back
        self.values = ValueMap()  # vlm: the model's scores of the views it was shown, placed in the world
        self.reveal: np.ndarray | None = None  # gain: the cells a look could reveal (unknown, or unseen free)
        self._frontier_stamp: float | None = None
        self._no_way: tuple[float, float] | None = None  # no frontier reachable: since when, on which map
        self._refreshed = False  # ... and the turn round where it stands made since a frontier was last reachable
        self.refreshes = 0
        self.reason = ""

    def set_map(self, cm: Costmap) -> None:
        self.costmap = cm

    # -- status ---------------------------------------------------------------------------------
    def status(self) -> dict[str, object]:
        return {
            "exploring": self.phase in ("choose", "walk", "look", "refresh"),
            "phase": self.phase,
            "frontier": None if self.frontier is None else self.frontier.to_dict(),
            "frontiers_left": len(self.frontiers),
            "unseen_left": sum(f.kind == "view" for f in self.frontiers),
            "visited": len(self.visited),
            "given_up": self.given_up,
            "retried_given_up": self.retried,
            "refreshes": self.refreshes,  # whole turns where it stood, no frontier reachable
            "views_scored": self.values.views,  # vlm: the scored views placed on the value map
        }

    # -- the search -----------------------------------------------------------------------------
    def arrived(self) -> None:
        """The navigator is at the chosen frontier: look around there."""
        if self.phase == "walk":
            self.phase = "look"

    def looked(self, now: float, at: tuple[float, float] | None = None) -> None:
        """The look-around at the chosen frontier is over: where the robot stood, `at` (else the
        frontier's goal), is a place looked from. (Or the turn of a `refresh` is: nothing marked.)"""
        if self.phase == "look" and self.frontier is not None:
            self.visited.append(at if at is not None else self.frontier.goal)
        self.frontier, self.phase = None, "choose"
        self._frontier_stamp = None  # what the look saw changes the unseen regions

    def _known_round(self, cm: Costmap, xy: tuple[float, float]) -> int:
        """How many cells within `visited_radius_m` of `xy` the map knows (free or not)."""
        r = max(1, int(math.ceil(self.params.visited_radius_m / cm.resolution)))
        row, col = cm.cell(*xy)
        win = cm.data[max(0, row - r) : row + r + 1, max(0, col - r) : col + r + 1]
        return int((win >= 0).sum())

    def _skip(self, f: Frontier) -> bool:
        """Given up near its goal (until the map round it grows), or looked at: a map frontier where the
        robot stood to look (within `arrive_m` of its goal: that look showed nothing past it, no look
        will), unseen free space within `visited_radius_m` of a place looked from (the look covered it).
        A map frontier only near a place looked from stays: a room seen past its door's jamb from
        beside the door is still unknown."""
        p = self.params
        near = p.arrive_m if f.kind == "map" else p.visited_radius_m
        return any(math.dist(f.goal, g) < near for g in self.visited) or any(
            math.dist(f.goal, g) < p.visited_radius_m for g, _ in self.dropped
        )

    def _refresh(self) -> None:
        cm = self.costmap
        if cm is None or self._frontier_stamp == cm.stamp:
            return
        self._frontier_stamp = cm.stamp if self.coverage is None or self.coverage.frames else None
        p = self.params
        # A frontier given up comes back once the map round it has changed (a door seen open, a way found).
        grown = 1.0 + p.regrown_share
        self.dropped = [(g, n) for g, n in self.dropped if self._known_round(cm, g) <= n * grown]
        fp = FrontierParams(lethal=p.planner.lethal, min_size_m=p.min_frontier_m)
        standable = (cm.data >= 0) & (cm.data < p.planner.lethal)
        found = find_frontiers(cm.data, cm.resolution, cm.origin, fp, reachable=standable)
        self.reveal = cm.data == UNKNOWN
        if self.coverage is not None and self.coverage.frames:  # and the free space the camera has not looked at
            unseen = self.coverage.unlooked(cm.data, cm.resolution, cm.origin, p.planner.lethal)
            self.reveal = self.reveal | unseen
            block = max(2, int(self.coverage.params.range_m / cm.resolution))  # one region per camera range
            unseen[::block, :] = unseen[:, ::block] = False
            found += clusters(unseen, cm.data, cm.resolution, cm.origin, p.planner.lethal,
                              p.min_view_m2 / cm.resolution**2, kind="view")  # fmt: skip
        self.frontiers = [f for f in found if not self._skip(f)]

    def seen(self, f: Frontier) -> bool:
        """A region of unseen free space the camera has looked at since (on the way there): done."""
        return f.kind == "view" and self.coverage is not None and self.coverage.looked_at(*f.goal)

    def unseen_visible(self, x: float, y: float, yaw: float, view: float) -> tuple[float, float, float]:
        """m^2 of free space in sight of (x, y) within the camera's range that it has not looked at (inf:
        unknown), and the turn left and right that would see all of it (Coverage.unseen_visible)."""
        cm, cov = self.costmap, self.coverage
        if cm is None or cov is None or not cov.frames:  # no answered frame yet: nothing known
            return math.inf, 0.0, 0.0
        return cov.unseen_visible(cm.data, cm.resolution, cm.origin, self.params.planner.lethal, x, y, yaw, view)

    def give_up(self, why: str) -> None:
        """The chosen frontier cannot be reached now (the navigator's reason): choose another."""
        if self.frontier is not None:
            cm = self.costmap
            self.dropped.append((self.frontier.goal, self._known_round(cm, self.frontier.goal) if cm else 0))
            self.frontiers = [f for f in self.frontiers if not self._skip(f)]
        self.given_up += 1
        self.reason = why
        self.frontier, self.phase = None, "choose"

    def route_params(self) -> GlobalParams:
        """The planner's settings for a walk to a frontier: its route ends within `arrive_m` less the
        navigator's own `arrive_m` of the goal, so that wherever the navigator calls it there the
        robot stands within `arrive_m` of the goal, which is where a look counts for a map frontier;
        and, where it can, on a cell where it may turn in place to look round (`goal_turnable`)."""
        p = self.params
        end = max(p.arrive_m - self.navigator.params.arrive_m, 0.0)
        return replace(p.global_params, goal_tolerance_m=end, goal_turnable=True)

    def _standable(self, cm: Costmap, xy: tuple[float, float]) -> bool:
        """Is there a cell within `arrive_m` of `xy` that the robot may stand on, on `cm`?"""
        r = max(1, int(math.ceil(self.params.arrive_m / cm.resolution)))
        row, col = cm.cell(*xy)
        win = cm.data[max(0, row - r) : row + r + 1, max(0, col - r) : col + r + 1]
        return bool(((win >= 0) & (win < self.params.planner.lethal)).any())

    def _choose(self, x: float, y: float, now: float) -> ExploreStep | None:
        cm = self.costmap
        assert cm is not None
        p = self.params
        cov = self.coverage
        if cov is not None and not cov.frames and cov.params != cov.base:
            return ExploreStep("wait", self.reason)  # the second pass begins with its first answered frame
        if not self.frontiers:
            if self.dropped:  # nothing else left: those given up may be reachable now
                return self._retry_given_up("no other frontier left")
            if cov is not None and cov.frames and cov.params.range_m > p.second_pass_m:
                # Everything seen from up to range_m, and time left: a small object is missed at
                # that range (a duck at 4 m is 15 pixels), so look at it all again from closer.
                cov.closer(p.second_pass_m)
                self.visited.clear()
                self._frontier_stamp = None
                self.reason = f"a second pass: looking at it all again from within {p.second_pass_m:g} m"
                return ExploreStep("wait", self.reason)
            self.phase = "done"
            self.reason = "no frontier left: every reachable part of the map has been looked at"
            return ExploreStep("done", self.reason)
        cands = self.frontiers
        gp = self.route_params()
        if p.frontier_choice == "vlm":
            scored = [self.values.at(*f.centroid) for f in cands]
            cands = [f for f, sc in zip(cands, scored, strict=True) if sc >= max(scored)]
        elif p.frontier_choice == "gain" and len(cands) > 1 and self.reveal is not None:
            cost = self.navigator.costs(cm, (x, y), [f.goal for f in cands], gp)
            gain = gains(self.reveal, cm.resolution, np.array([f.goal_cell for f in cands]), p.gain_radius_m)
            worth = np.where(np.isfinite(cost), gain - p.gain_per_m * cost, -np.inf)
            if np.isfinite(worth).any():
                cands = [cands[int(np.argmax(worth))]]
        plan = self.navigator.choose(cm, (x, y), [f.goal for f in cands], gp, now)
        if not plan.ok and cands is not self.frontiers:
            plan = self.navigator.choose(cm, (x, y), [f.goal for f in self.frontiers], gp, now)
            cands = self.frontiers
        if not plan.ok:
            if self.dropped:  # none reachable now: those given up may be, from here
                return self._retry_given_up(f"no reachable frontier of those left ({plan.reason})")
            if not self._refreshed:
                self._refreshed, self._no_way, self.phase = True, None, "refresh"
                self.refreshes += 1
                self.reason = f"no reachable frontier now ({plan.reason}): turning round where it stands to see again"
                return ExploreStep("refresh", self.reason)
            since = now if self._no_way is None else self._no_way[0]
            if now - since < p.unreachable_wait_s:  # one plan is not the last word: plan again on new maps
                self._no_way = (since, cm.stamp)
                self.reason = f"no reachable frontier now ({plan.reason}): planning again on new maps"
                return ExploreStep("wait", self.reason)
            self.phase = "done"
            self.reason = f"no reachable frontier ({len(self.frontiers)} left) for {now - since:.0f} s: {plan.reason}"
            return ExploreStep("done", self.reason)
        self._no_way, self._refreshed = None, False
        self.frontier = cands[plan.goal_index]
        self.phase = "walk"
        return None

    def _retry_given_up(self, why: str) -> ExploreStep:
        """Bring back every frontier given up (the search never ends while one may be reachable)."""
        self.dropped.clear()
        self.retried += 1
        self._frontier_stamp = None
        self.reason = f"{why}: trying the given-up again"
        return ExploreStep("wait", self.reason)

    def step(self, x: float | None, y: float | None, yaw: float | None, now: float) -> ExploreStep:
        """What to do now: walk to `goal` (the navigator's job), look there, wait, or done."""
        p = self.params
        if self.phase == "done":
            return ExploreStep("done", self.reason)
        if now - self.t0 > p.timeout_s:
            self.phase = "done"
            self.reason = f"explored for {p.timeout_s:g} s without finding it ({len(self.visited)} places looked from)"
            return ExploreStep("done", self.reason)
        cm = self.costmap
        if cm is None:
            if now - self.t0 > p.map_timeout_s:
                self.phase = "done"
                self.reason = f"no map (/map/costmap) after {p.map_timeout_s:g} s: cannot explore"
                return ExploreStep("done", self.reason)
            return ExploreStep("wait", "waiting for the map to explore")
        if x is None or y is None or yaw is None or not all(math.isfinite(v) for v in (x, y, yaw)):
            return ExploreStep("wait", "no fresh pose: holding still")
        if self.phase == "look":
            return ExploreStep("look", self.where())
        if self.phase == "refresh":
            return ExploreStep("refresh", self.reason)
        if self._no_way is not None and self.phase == "choose" and self._no_way[1] == cm.stamp:
            since = self._no_way[0]
            if now - since < p.unreachable_wait_s:
                return ExploreStep("wait", self.reason)  # no new map yet: nothing to plan again on
        self._refresh()
        for _ in range(8):  # a few frontiers may be dropped in one step (gone, seen on the way)
            if self.phase == "choose":
                done = self._choose(x, y, now)
                if done is not None:
                    return done
            f = self.frontier
            assert f is not None
            if self.seen(f):  # the camera saw that region on the way: nothing to walk there for
                self.visited.append(f.goal)
                self.frontiers = [g for g in self.frontiers if not self._skip(g)]
                self.frontier, self.phase = None, "choose"
                continue
            if not self._standable(cm, f.goal):
                self.give_up(f"the frontier at ({f.goal[0]:.1f}, {f.goal[1]:.1f}) is no place to stand on the new map")
                continue
            if math.hypot(f.goal[0] - x, f.goal[1] - y) <= p.arrive_m:
                self.phase = "look"
                return ExploreStep("look", self.where())
            reason = (
                f"exploring: walking to the frontier at ({f.goal[0]:.1f}, {f.goal[1]:.1f}) "
                f"({len(self.frontiers)} frontiers left)"
            )
            return ExploreStep("walk", reason, f.goal)
        return ExploreStep("wait", "exploring: choosing a frontier")

    def where(self) -> str:
        f = self.frontier
        where = "" if f is None else f" at ({f.goal[0]:.1f}, {f.goal[1]:.1f})"
        return f"exploring: looking around from the frontier{where} ({len(self.frontiers)} frontiers left)"

    def frontier_points(self) -> np.ndarray:
        """(N, 2) the goals of the frontiers left (for a plot or the status)."""
        return np.array([f.goal for f in self.frontiers]).reshape(-1, 2)
