"""The colour grounder's own answers leave the target_tracker like a VLM's (/target_tracker/detections:
the frame's stamp, the box it found for the query, or none), so that the object memory places them."""

from __future__ import annotations

import threading

from busutil import wait_for
from targetutil import Cam, frame

from go2vlm.bus import QOS_DEFAULT, running
from go2vlm.launch.registry import make_node
from go2vlm.msgs.vision_msgs import Detection2DArray, detection_boxes
from go2vlm.perception.tracking import TargetTracking, TrackingParams


def test_each_grounder_run_is_an_answer() -> None:
    t = TargetTracking(TrackingParams(grounding="color"))
    t.set_query("red ball")
    t.on_frame(1.0, frame(400))
    ((stamp, box),) = t.color_answers
    assert stamp == 1.0 and box is not None and abs((box[0] + box[2]) / 2 - 120) < 5  # the red ball at x 120
    t.color_answers.clear()
    t.set_query("yellow ball")
    t.on_frame(1.1, frame(400))
    assert t.color_answers == [(1.1, None)]  # looked, found none: an empty answer


def test_the_node_publishes_them() -> None:
    tracker = make_node("target_tracker", params={"grounding": "color", "query": "red ball"})
    cam = Cam()
    got: list[Detection2DArray] = []
    lock = threading.Lock()

    def on_answer(m: Detection2DArray) -> None:
        with lock:
            got.append(m)

    cam.create_subscription(Detection2DArray, "/target_tracker/detections", on_answer, QOS_DEFAULT)
    with running(cam, tracker):
        assert wait_for(lambda: len(got) >= 3, 15)
    with lock:
        m = got[-1]
    stamps = {h.stamp.to_sec() for h in cam.headers}
    assert m.header.stamp.to_sec() in stamps and m.header.frame_id == "camera"
    ((label, box, _),) = detection_boxes(m)
    assert label == "red ball" and abs((box[0] + box[2]) / 2 - 120) < 5
