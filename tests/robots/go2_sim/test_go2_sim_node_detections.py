"""The sim node's ground-truth detections (`detections: true`), as a real process: every head frame
gets a vision_msgs/Detection2DArray on /sim/detections with the frame's stamp, labelled with the
body names, boxing exactly what the camera sees (the oracle perception variant of `go2vlm eval`)."""

from __future__ import annotations

from busutil import Procs, Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_SENSOR, Node
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.vision_msgs import Detection2DArray, detection_boxes


def test_sim_publishes_ground_truth_boxes_of_each_head_frame(procs: Procs) -> None:
    probe = Node(node_name="detections_probe")
    images, dets = Recorder(), Recorder()
    probe.create_subscription(Image, "/camera/image_raw", images, QOS_SENSOR)
    probe.create_subscription(Detection2DArray, "/sim/detections", dets, QOS_DEFAULT)
    probe.start()
    try:
        # vision_test from its spawn (0, -1.5) facing +x: the red sphere at (2, 0) is in view, ahead
        # and to the left; the green box and the blue cylinder are behind the camera.
        procs.start(
            "run", "sim", "--param", "world=vision_test", "--param", "mode=kinematic", "--param", "detections=true",
            "--param", "use_sim_time=true", "--param", "world_camera=false",
        )  # fmt: skip
        assert wait_for(lambda: len(dets) >= 5 and len(images) >= 5, 90.0), (len(dets), len(images))
        frames = {m.header.stamp.to_sec() for m in images.msgs()}
        msgs = dets.msgs()
        assert sum(m.header.stamp.to_sec() in frames for m in msgs) >= 3, "each array carries its frame's stamp"
        boxes = {label: box for label, box, _ in detection_boxes(msgs[-1])}
        assert set(boxes) == {"red_sphere"}, boxes
        x1, y1, x2, y2 = boxes["red_sphere"]
        assert 0 <= x1 < x2 <= 640 and 0 <= y1 < y2 <= 480
        assert (x1 + x2) / 2 < 320, "left of centre: the sphere is at +y of the robot's heading"
        assert x2 - x1 > 60 and y2 - y1 > 60, "a 1 m sphere 2.5 m away is large"
        assert msgs[-1].detections[0].results[0].hypothesis.score == 1.0
    finally:
        probe.shutdown()
