"""An episode with odometry drift runs the map's scan matching, and the object memory and the
commander read the corrected pose (/map/odom, frame map); without drift, the graph is as its file."""

from __future__ import annotations

from go2vlm.apps.episodes.episode import Episode
from go2vlm.apps.episodes.runner import RunOptions, episode_entries
from go2vlm.bus.topics import MAP_ODOM


def _params(ep: Episode) -> dict[str, dict]:
    return {e.name: e.params for e in episode_entries(ep, RunOptions())}


def test_drift_turns_scan_matching_on_and_points_the_world_at_it() -> None:
    goal = "go to the duck"
    drifting = _params(Episode(world="household", goal=goal, perception="oracle", params={"sim": {"odom_drift": 1.0}}))
    assert drifting["map"]["scan_matching"] is True and drifting["map"]["world"] == "household"
    assert drifting["object_memory"]["odom_topic"] == MAP_ODOM.name
    assert drifting["object_memory"]["world_frame"] == "map"
    assert drifting["commander"]["odom_topic"] == MAP_ODOM.name
    plain = _params(Episode(world="household", goal=goal, perception="oracle"))
    assert not plain["map"].get("scan_matching") and "odom_topic" not in plain["object_memory"]
    assert "odom_topic" not in plain["commander"] and plain["map"]["world"] == "household"
    # A person's own choice still wins.
    mine = _params(Episode(world="household", goal=goal, perception="oracle",
                           params={"sim": {"odom_drift": 1.0}, "map": {"scan_matching": False}}))  # fmt: skip
    assert mine["map"]["scan_matching"] is False
