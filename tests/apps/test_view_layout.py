"""The shipped Foxglove layout opens what `go2vlm view` serves, and its publish panels stay inside
the view's publish whitelist (the safety gate's inputs, never /cmd_vel)."""

from __future__ import annotations

import json
from pathlib import Path

from go2vlm.apps.view.view_node import CLIENT_TOPICS, ROBOT_TOPIC
from go2vlm.bus.topics import MAP, MAP_COSTMAP, PLAN
from go2vlm.msgs.msgdef import ros_type

LAYOUT = Path(__file__).resolve().parents[2] / "docs" / "foxglove" / "go2vlm_layout.json"


def test_layout_panels() -> None:
    doc = json.loads(LAYOUT.read_text())
    panels = doc["configById"]
    image = panels["Image!camera"]["imageMode"]
    assert image["imageTopic"] == "/camera/image_raw/compressed"
    assert set(image["annotations"]) == {"/detected_target/annotations", "/vlm/detections/annotations"}
    assert ROBOT_TOPIC in panels["3D!robot"]["topics"]
    assert {MAP.name, MAP_COSTMAP.name} <= set(panels["3D!robot"]["topics"])  # the map node's, decoded natively
    assert panels["3D!robot"]["topics"][PLAN.name]["visible"]  # the commander's global route, nav_msgs/Path
    plotted = {p["value"] for k, v in panels.items() if k.startswith("Plot!") for p in v["paths"]}
    assert {"/detected_target.point.x", "/cmd_vel.linear.x", "/cmd_vel.angular.z"} <= plotted
    assert {panels["RawMessages!safety"]["topicPath"], panels["RawMessages!vlm"]["topicPath"]} == {
        "/safety/status.data",
        "/vlm/status.data",
    }
    for key, cfg in panels.items():
        if key.startswith("Publish!"):
            assert ros_type(CLIENT_TOPICS[cfg["topicName"]]) == cfg["datatype"]
        if key.startswith("Teleop!"):
            assert cfg["topic"] in CLIENT_TOPICS and cfg["topic"] != "/cmd_vel"

    def leaves(node: object) -> list[str]:
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])  # type: ignore[index]

    assert sorted(leaves(doc["layout"])) == sorted(panels)
