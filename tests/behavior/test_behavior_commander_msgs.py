"""The commander's messages worked out without I/O (behavior/commander_msgs.py): a /vlm/way answer
counts only for the question that stands; the question is asked only while searching or exploring
with frontier_choice vlm; /plan carries the route's waypoints; the status of an idle mission."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from go2vlm.behavior.commander_msgs import WAY_STATES, commander_status, route_path, way_answer, way_query
from go2vlm.behavior.mission import Mission
from go2vlm.behavior.planner.global_path import Plan
from go2vlm.behavior.planner.route import Route
from go2vlm.behavior.view_scores import ViewAnswerRejected
from go2vlm.perception.way import WayMessageRejected, way_message

STATES = st.sampled_from([*WAY_STATES, "idle", "approaching", "aligning", "found", "not_found", "detouring"])


@given(st.text(max_size=20), STATES, st.booleans(), st.sampled_from(["nearest", "vlm"]))
def test_the_way_question_stands_only_while_a_vlm_explore_looks(
    query: str, state: str, explore: bool, choice: str
) -> None:
    asked = way_query(query, state, explore, choice)
    assert asked == (query if explore and choice == "vlm" and state in WAY_STATES else "")


def test_a_way_answer_counts_only_for_the_standing_question() -> None:
    assert way_answer(way_message(12.5, "red ball", "likely"), "red ball") == (12.5, 1.0)
    assert way_answer(way_message(12.5, "red ball", '{"way": "unlikely"}'), "red ball") == (12.5, 0.0)
    for asked in ("", "blue box"):
        with pytest.raises(WayMessageRejected) as e:
            way_answer(way_message(12.5, "red ball", "likely"), asked)
        assert e.value.reason == "way_not_asked"
    with pytest.raises(ViewAnswerRejected):
        way_answer(way_message(12.5, "red ball", "turn left at 2 m/s"), "red ball")


def test_the_plan_carries_the_route_waypoints_in_its_frame() -> None:
    w = np.array([[0.0, 0.0], [1.0, 0.5], [2.0, 2.0]])
    route = Route(Plan(True, "planned", waypoints=w, length=3.0), goal=(2.0, 2.0), t=0.0, map_stamp=0.0)
    path = route_path(route, 5.25, "odom")
    assert path.header.frame_id == "odom" and path.header.stamp.to_sec() == pytest.approx(5.25)
    assert [(p.pose.position.x, p.pose.position.y) for p in path.poses] == [tuple(xy) for xy in w.tolist()]
    assert all(p.pose.orientation.w == 1.0 for p in path.poses)
    assert route_path(None, 5.25, "odom").poses == []


def test_an_idle_mission_status_is_json_with_what_the_node_gives() -> None:
    status = commander_status(
        Mission(), 1.0, counters={"way_answers": 2}, lease={"id": "x", "left_s": 1.0}, explore=None, route=None
    )
    assert json.loads(json.dumps(status)) == status
    assert (status["state"], status["goal"], status["plan"], status["lease"]) == (
        "idle",
        "",
        None,
        {"id": "x", "left_s": 1.0},
    )
    assert status["counters"] == {"way_answers": 2}
