"""The target_tracker node over real DDS on synthetic camera frames: a late VLM answer seeds the tracker
on its own frame and is caught up to the present, the tracker follows the object between answers,
a lost target has no box, and bad images, camera infos, answers and queries are counted and survived."""

from __future__ import annotations

import math

import pytest
from busutil import wait_for
from targetutil import Cam, det

from go2vlm.bus import ParamError, running
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.launch.registry import make_node
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.go2vlm_msgs import LOST, SEARCHING, TRACKING, UNGROUNDABLE
from go2vlm.msgs.sensor_msgs import CameraInfo, Image
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.msgs.vision_msgs import Detection2DArray, ObjectHypothesis, ObjectHypothesisWithPose, detection_boxes
from go2vlm.perception.tracker_node import grounding_of


def _state(cam: Cam) -> int | None:
    m = cam.last()
    return None if m is None else int(m.state)


def test_a_late_vlm_answer_is_caught_up_and_bad_inputs_are_counted() -> None:
    tracker = make_node("target_tracker", params={"grounding": "vlm", "query": "blue cylinder"})
    cam = Cam()
    with running(cam, tracker):
        assert wait_for(lambda: cam.dets.matched >= 1 and cam.img.matched >= 1 and len(cam.headers) > 12, 10)
        assert wait_for(lambda: _state(cam) == SEARCHING, 5)  # no answer yet: nothing reported
        # Garbage first: an image of no known encoding (a truncated one never gets past the bus's size
        # check: msgs/sizes.py), a CameraInfo with fx = 0, a detection with a NaN box.
        cam.img.publish(Image(height=4, width=4, encoding="yuv_weird", step=12, data=b"\x00" * 48))
        cam.info.publish(CameraInfo(width=640, height=480, k=[0.0] * 9))
        h = cam.header_back(1)
        bad = det("blue cylinder", 0, 0, 10, 10, h)
        bad.bbox.size_x = float("nan")
        cam.dets.publish(Detection2DArray(header=h, detections=[bad]))
        cam.dets.publish(Detection2DArray(header=h, detections=[]))  # an empty answer
        assert wait_for(lambda: cam.counter("bad_images") >= 1 and cam.counter("refused.bad_box") >= 1, 5)
        assert wait_for(lambda: cam.counter("bad_camera_info") >= 1 and cam.counter("empty_answers") >= 1, 5)
        assert _state(cam) == SEARCHING
        # An answer about a frame 1 s old: the red ball is no match, the blue cylinder is.
        old = cam.header_back(10)
        cam.dets.publish(Detection2DArray(header=old, detections=[
            det("red ball", 70, 280, 170, 380, old), det("blue cylinder", 370, 150, 430, 400, old)]))  # fmt: skip
        assert wait_for(lambda: _state(cam) == TRACKING, 5)
        m = cam.last()
        assert m.label == "blue cylinder" and (m.image_width, m.image_height) == (640, 480)
        assert abs(m.bbox.center.position.x - 400) < 5 and abs(m.bbox.size_y - 250) < 8
        assert 0.7 < m.distance_m < 2.7 and m.range_method == "bottom"  # camera -> surface, from the CameraInfo
        assert 0.9 < m.grounding_age_s < 3.0 and m.confidence > 0.5
        # The bearing comes from the CameraInfo (Cam: 1.274 rad wide), not from any field of view of the reader's.
        assert m.hfov_rad == pytest.approx(1.274, abs=1e-6)
        real = PinholeCamera.from_hfov(640, 480, 1.274)
        assert m.bearing_rad == pytest.approx(real.bearing(m.bbox.center.position.x), abs=1e-9) and m.bearing_rad < 0
        assert cam.counter("accepted") == 1
        # The tracker follows the object (no new answer) as it moves across the image...
        cam.cx = 330
        assert wait_for(lambda: abs(cam.last().bbox.center.position.x - 330) < 5, 5)
        # ...and reports it lost, with no box, when it is gone; back in view it stays lost until grounded.
        cam.cx = None
        assert wait_for(lambda: _state(cam) == LOST, 5)
        m = cam.last()
        assert m.bbox.size_x == 0 and m.confidence == 0 and math.isnan(m.distance_m) and math.isnan(m.bearing_rad)
        cam.cx = 330
        n = len(cam.tracked)
        assert wait_for(lambda: len(cam.tracked) > n + 5, 5)
        assert _state(cam) == LOST


def test_wrong_answers_are_refused_and_queries_switch_the_target() -> None:
    tracker = make_node("target_tracker", params={"grounding": "vlm"})
    cam = Cam()
    with running(cam, tracker):
        assert wait_for(lambda: cam.dets.matched >= 1 and cam.query.matched >= 1 and len(cam.headers) > 3, 10)
        assert wait_for(lambda: cam.last() is not None and cam.last().state == 0 and cam.last().label == "", 5)
        cam.query.publish(String(data="blue cylinder"))
        assert wait_for(lambda: cam.last().label == "blue cylinder", 5)
        h = cam.header_back(1)
        # The right label on the wrong object, a wrong label on the right object, a box on the floor.
        for d in (det("blue cylinder", 70, 280, 170, 380, h), det("red ball", 370, 150, 430, 400, h),
                  det("blue cylinder", 500, 420, 600, 470, h)):  # fmt: skip
            cam.dets.publish(Detection2DArray(header=h, detections=[d]))
        assert wait_for(lambda: cam.counter("refused.color_mismatch") == 2 and cam.counter("refused.no_match") == 1, 5)
        n = len(cam.tracked)
        assert wait_for(lambda: len(cam.tracked) > n + 3, 5)
        assert all(m.state != TRACKING for m in cam.tracked)
        # A new query: the red ball, grounded on the current frame.
        cam.query.publish(String(data="red ball"))
        assert wait_for(lambda: cam.last().label == "red ball", 5)
        h = cam.header_back(1)
        cam.dets.publish(Detection2DArray(header=h, detections=[det("red ball", 70, 280, 170, 380, h)]))
        assert wait_for(lambda: _state(cam) == TRACKING and cam.last().label == "red ball", 5)
        assert abs(cam.last().bbox.center.position.x - 120) < 5


def test_colour_grounding_and_an_ungroundable_query() -> None:
    tracker = make_node("target_tracker", params={"query": "blue cylinder"})  # grounding=color, no model
    cam = Cam()
    with running(cam, tracker):
        assert wait_for(lambda: _state(cam) == TRACKING, 10)
        assert abs(cam.last().bbox.center.position.x - 400) < 5
        cam.query.publish(String(data="person"))
        assert wait_for(lambda: _state(cam) == UNGROUNDABLE and cam.last().label == "person", 5)
        assert cam.last().bbox.size_x == 0


def test_an_answer_counts_its_best_hypothesis_as_every_reader_does() -> None:
    """The tracker reads a detection's label as the metrics and the memory do (msgs/vision_msgs.py)."""
    h = Header(stamp=Time(sec=3, nanosec=0))
    d = det("red ball", 10, 20, 110, 220, h)
    d.results = [ObjectHypothesisWithPose(hypothesis=ObjectHypothesis("red ball", 0.2)),
                 ObjectHypothesisWithPose(hypothesis=ObjectHypothesis("blue cylinder", 0.9))]  # fmt: skip
    msg = Detection2DArray(header=h, detections=[d])
    ((label, box, score),) = detection_boxes(msg)
    assert (label, score) == ("blue cylinder", 0.9) and box == pytest.approx((10, 20, 110, 220))
    assert grounding_of(msg).boxes == ((label, box),) and grounding_of(msg).stamp == 3.0


def test_bad_parameters_are_clear_errors() -> None:
    with pytest.raises(ParamError, match="object_sizes"):
        make_node("target_tracker", params={"object_sizes": {"pyramid": 1.0}})
    with pytest.raises(ParamError, match="grounding"):
        make_node("target_tracker", params={"grounding": "lidar"})
