"""A parameter declared once, on a pure core's field (go2vlm/declare.py `param`), and taken over by a
node's config with `from_core`, under the core's name or the node's own: the same default, help,
bounds and live flag, and `core_params` builds the core (nested cores too) from the node's values."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import pytest
from hypothesis import given
from hypothesis import strategies as st

from go2vlm.behavior.commander_config import CommanderConfig
from go2vlm.bus import ParamError, build_config, core_params, core_values, describe_params, from_core, param
from go2vlm.robot_profile import PROFILES


@dataclass(frozen=True)
class Inner:
    margin: float = param(0.35, help="free space each side (m)", min=0.1, max=1.5, live=True)
    step: float = 0.1  # not a parameter: the core's own


@dataclass(frozen=True)
class Core:
    gain: float = param(1.5, help="P gain", min=0.0, max=10.0)
    cost: float = param(3.0, help="cost per unknown cell", min=1.0)
    inner: Inner = field(default_factory=Inner)
    derived: float = 0.0  # the node's to give


@dataclass
class NodeCfg:
    gain: float = from_core(Core, "gain")
    core_cost: float = from_core(Core, "cost")  # the node's public name differs from the core's
    inner_margin_m: float = from_core(Inner, "margin")
    rate_hz: float = param(20.0, help="the node's own", min=1.0)

    def core(self) -> Core:
        return core_params(Core, self, inner=core_params(Inner, self), derived=2 * self.rate_hz)


def test_a_renamed_parameter_keeps_the_core_declaration() -> None:
    by_name = {f.name: f for f in dataclasses.fields(NodeCfg)}
    core = {f.name: f for f in dataclasses.fields(Core)}
    for node_name, core_name in (("gain", "gain"), ("core_cost", "cost")):
        f = by_name[node_name]
        assert f.default == core[core_name].default
        assert {k: v for k, v in f.metadata.items() if k != "core"} == dict(core[core_name].metadata)
    rows = {r[0]: r for r in describe_params(NodeCfg)}
    assert rows["core_cost"][2] == "3.0" and rows["core_cost"][3] == "cost per unknown cell"
    assert rows["inner_margin_m"][3].endswith("(live)")


def test_core_values_map_the_node_names_back_to_the_core_names() -> None:
    cfg = build_config(NodeCfg, {"core_cost": 7.0, "inner_margin_m": 0.5})
    assert core_values(Core, cfg) == {"gain": 1.5, "cost": 7.0}
    assert core_values(Inner, cfg) == {"margin": 0.5}
    assert cfg.core() == Core(gain=1.5, cost=7.0, inner=Inner(margin=0.5), derived=40.0)


def test_the_core_bounds_hold_under_the_node_name() -> None:
    with pytest.raises(ParamError, match="'core_cost'.*below the minimum 1.0"):
        build_config(NodeCfg, {"core_cost": 0.5})
    with pytest.raises(ParamError, match="'inner_margin_m'.*above the maximum 1.5"):
        build_config(NodeCfg, {"inner_margin_m": 2.0})


def test_from_core_refuses_a_field_that_is_no_parameter() -> None:
    with pytest.raises(TypeError, match="not declared with param"):
        from_core(Inner, "step")
    with pytest.raises(TypeError, match="no field 'nope'"):
        from_core(Core, "nope")


@given(
    margin=st.floats(0.1, 1.5),
    unknown=st.floats(1.0, 1000.0),
    timeout=st.floats(10.0, 3600.0),
    stop=st.floats(0.2, 5.0),
    robot=st.sampled_from(sorted(PROFILES)),
)
def test_the_commander_builds_its_cores_from_its_public_names(
    margin: float, unknown: float, timeout: float, stop: float, robot: str
) -> None:
    """The commander's documented names (planner_margin_m, explore_unknown_cost, explore_timeout_s)
    reach the cores' fields; the camera mount is the robot profile's."""
    cfg = build_config(
        CommanderConfig,
        {"planner_margin_m": margin, "explore_unknown_cost": unknown, "explore_timeout_s": timeout,
         "stop_distance_m": stop, "robot": robot, "nav_progress_s": min(timeout / 10, 100.0),
         "explore_gain_per_m": stop},
    )  # fmt: skip
    mp, ep = cfg.mission_params(), cfg.explore_params()
    assert (mp.planner.margin, mp.stop_distance_m, mp.nav.progress_s) == (margin, stop, min(timeout / 10, 100.0))
    assert (ep.unknown_cost, ep.timeout_s, ep.frontier_choice, ep.gain_per_m) == (unknown, timeout, "gain", stop)
    assert mp.camera_forward_m == PROFILES[robot].head_camera.pos[0]


def test_the_commander_refuses_inconsistent_memory_confidences_at_start_up() -> None:
    with pytest.raises(ParamError, match="memory_min_confidence <= memory_confirm_confidence"):
        build_config(CommanderConfig, {"memory_min_confidence": 0.9, "memory_confirm_confidence": 0.5})


# -- safety limits only tighten at runtime (declare.py `bound=`, bus/params.py `loosened`) ------------
@dataclass
class Bounded:
    top: float = param(1.0, help="a ceiling", min=0.0, max=10.0, live=True, bound="max")
    floor: float = param(0.3, help="a margin", min=0.0, max=3.0, live=True, bound="min")
    gain: float = param(1.0, help="no limit", min=0.0, max=10.0, live=True)


@given(st.floats(0.0, 10.0), st.floats(0.0, 10.0), st.floats(0.0, 3.0), st.floats(0.0, 3.0), st.floats(0.0, 10.0))
def test_a_limit_is_loosened_exactly_when_a_ceiling_rises_or_a_floor_falls(
    top0: float, top1: float, floor0: float, floor1: float, gain: float
) -> None:
    from go2vlm.bus.params import loosened

    old, new = Bounded(top0, floor0, 1.0), Bounded(top1, floor1, gain)
    got = loosened(old, new, ["top", "floor", "gain"])
    assert [g.split()[0] for g in got] == [n for n, up in (("top", top1 > top0), ("floor", floor1 < floor0)) if up]
    assert loosened(old, new, []) == []


def test_bound_is_a_known_kind() -> None:
    with pytest.raises(TypeError, match="bound='down'"):
        param(1.0, help="x", bound="down")
    rows = {r[0]: r[3] for r in describe_params(Bounded)}
    assert rows["top"].endswith("(live, lowered only)") and rows["floor"].endswith("(live, raised only)")


def test_every_live_ceiling_of_every_node_only_goes_down() -> None:
    """Every node's live parameter named as a ceiling (max_*) or a speed, time or distance limit is
    declared bound="max": one rule refuses raising it while the node runs."""
    import importlib

    from go2vlm.launch.registry import NODES

    # Named max_ but no motion limit: how old a frame the model may still answer about (a slow machine raises it).
    freshness = {"vlm.max_age_s"}
    unbound = []
    for kind, where in NODES.items():
        module, _, cls = where.partition(":")
        try:
            config = getattr(importlib.import_module(module), cls).Config
        except ImportError:  # an extra that is not installed
            continue
        for f in dataclasses.fields(config):
            if f.metadata.get("live") and f.name.startswith(("max_", "accel_")) and f.metadata.get("bound") != "max":
                unbound.append(f"{kind}.{f.name}")
    assert set(unbound) == freshness, unbound
