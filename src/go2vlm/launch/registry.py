"""Node names -> classes, imported lazily so that `go2vlm run follower` never imports torch."""

from __future__ import annotations

import importlib
from typing import Any

from go2vlm.bus import Node, build_node_config, load_params_file

NODES: dict[str, str] = {
    "test_pattern": "go2vlm.sources.test_pattern_node:TestPatternNode",
    "video_source": "go2vlm.sources.video_source_node:VideoSourceNode",
    "color_detector": "go2vlm.perception.color_detector_node:ColorDetectorNode",
    "vlm": "go2vlm.perception.vlm.vlm_node:VlmNode",
    "target_tracker": "go2vlm.perception.tracker_node:TargetTrackerNode",
    "answer_delay": "go2vlm.perception.answer_delay_node:AnswerDelayNode",
    "way_oracle": "go2vlm.perception.way_oracle_node:WayOracleNode",
    "object_memory": "go2vlm.world.object_memory_node:ObjectMemoryNode",
    "map": "go2vlm.world.map_node:MapNode",
    "follower": "go2vlm.behavior.follower_node:FollowerNode",
    "commander": "go2vlm.behavior.commander_node:CommanderNode",
    "safety": "go2vlm.safety.gate_node:SafetyGateNode",
    "sim": "go2vlm.robots.go2_sim.sim_node:SimNode",
    "go2": "go2vlm.robots.go2.driver_node:Go2DriverNode",
    "recorder": "go2vlm.apps.bag.recorder_node:RecorderNode",
    "player": "go2vlm.apps.bag.player_node:PlayerNode",
    "view": "go2vlm.apps.view.view_node:ViewNode",
}


def node_class(name: str) -> type[Node]:
    if name not in NODES:
        raise ValueError(f"unknown node {name!r}; available: {', '.join(sorted(NODES))}")
    module, _, cls = NODES[name].partition(":")
    return getattr(importlib.import_module(module), cls)


def make_node(
    kind: str,
    *,
    params: dict[str, Any] | None = None,
    params_file: str | None = None,
    node_name: str | None = None,
    remap: dict[str, str] | None = None,
    **kwargs: Any,
) -> Node:
    """Build a node the way `go2vlm run` and `go2vlm launch` do: file params, then overrides. The
    base parameters every node has (`use_sim_time`) go to `Node`, the rest to the node's Config."""
    cls = node_class(kind)
    name = node_name or cls.name
    values: dict[str, Any] = {}
    if params_file:
        values.update(load_params_file(params_file, name))
    values.update(params or {})
    config, base = build_node_config(cls.Config, values, node=name)
    return cls(config, node_name=name, remap=remap, use_sim_time=base.use_sim_time, **kwargs)
