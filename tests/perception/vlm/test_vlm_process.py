"""The model in a process of its own (process_backend.py) and the launch-bound stand-in model
(standin_backend.py): answers as in this process, frames of any size through shared memory, errors
of their own kind, a crashed process started again, nothing left behind."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from go2vlm.geometry.qwen import smart_resize
from go2vlm.perception.vlm.backend import BackendError, BackendSettings
from go2vlm.perception.vlm.factory import make_backend
from go2vlm.perception.vlm.process_backend import InferenceProcess, wants_process
from go2vlm.perception.vlm.standin_backend import StandinBackend, parse_spec

FAST = "tok_s=2000,tokens=4,prefill_ms=1"


def test_auto_gives_models_that_compute_here_a_process() -> None:
    assert wants_process(BackendSettings(model="m", backend="transformers"))
    assert wants_process(BackendSettings(model="m", backend="standin"))
    assert not wants_process(BackendSettings(model="m", backend="openai"))  # its wait holds no interpreter
    assert not wants_process(BackendSettings(model="m", backend="transformers", process="off"))
    assert wants_process(BackendSettings(model="m", backend="openai", process="on"))
    assert isinstance(make_backend(BackendSettings(model=FAST, backend="standin")), InferenceProcess)
    assert isinstance(make_backend(BackendSettings(model=FAST, backend="standin", process="off")), StandinBackend)


def test_standin_spec_defaults_are_the_3b_on_an_h100() -> None:
    spec = parse_spec("3b")
    assert (spec.tok_s, spec.tokens, spec.prefill_ms) == (39.3, 32, 80.0)
    assert spec.frame_ms == pytest.approx(80 + 32 / 39.3 * 1e3)
    assert parse_spec("tok_s=50.9,prefill_ms=76").tok_s == 50.9
    for bad in ("speed=3", "tok_s=fast", "tok_s=0"):
        with pytest.raises(BackendError):
            parse_spec(bad)


def test_frames_of_any_size_through_shared_memory_and_a_crash_survived() -> None:
    b = make_backend(BackendSettings(model=FAST, backend="standin"))
    assert isinstance(b, InferenceProcess)
    b.load()
    try:
        assert b.load_report["process_start_s"] > 0 and "own process" in b.description
        for h, w in ((48, 64), (480, 640), (720, 1280), (100, 100)):  # the block grows, then is reused
            gen = b.generate(np.full((h, w, 3), 7, np.uint8), "p")
            assert gen.original_hw == (h, w)
            assert gen.resized_hw == smart_resize(
                h, w, min_pixels=b.settings.min_pixels, max_pixels=b.settings.max_pixels
            )
            assert gen.new_tokens == 4 and gen.text == "[]"
        assert b._shm is not None
        block = b._shm.name
        assert b._proc is not None
        b._proc.kill()  # a crash (a driver fault, the OOM killer): the next frame starts it again
        b._proc.wait(10)
        gen = b.generate(np.zeros((48, 64, 3), np.uint8), "p")
        assert gen.new_tokens == 4
    finally:
        b.close()
    assert b._proc is None and not os.path.exists(f"/dev/shm/{block.lstrip('/')}")


def test_load_errors_come_back_with_their_message() -> None:
    b = make_backend(BackendSettings(model="tok_s=-1", backend="standin"))
    with pytest.raises(BackendError, match="tok_s > 0"):
        b.load()
    assert b._proc is None  # nothing left running


def test_transformers_in_its_own_process_answers_as_in_this_process(tiny_ckpt: Path) -> None:
    from testing_support.tiny_qwen import TINY_MAX_PIXELS, TINY_MIN_PIXELS

    def settings(process: str) -> BackendSettings:
        return BackendSettings(
            model=str(tiny_ckpt), process=process, max_pixels=TINY_MAX_PIXELS, min_pixels=TINY_MIN_PIXELS
        )

    here, there = make_backend(settings("off")), make_backend(settings("on"))
    here.load()
    there.load()
    try:
        frame = np.random.default_rng(0).integers(0, 256, (90, 120, 3), dtype=np.uint8)
        a, b = here.generate(frame, "find the red ball"), there.generate(frame, "find the red ball")
        assert (b.text, b.resized_hw, b.visual_tokens, b.prompt_tokens) == (
            a.text,
            a.resized_hw,
            a.visual_tokens,
            a.prompt_tokens,
        )
        assert there.settings.max_pixels == TINY_MAX_PIXELS
    finally:
        here.close()
        there.close()


def test_node_with_its_model_in_another_process_answers_and_reports_the_load() -> None:
    """The vlm node with the stand-in model (inference_process=auto: its own process) over real DDS:
    every answer carries its frame's stamp; the status reports the load and the process."""
    from busutil import Recorder, wait_for

    from go2vlm.bus import QOS_DEFAULT, QOS_SENSOR, Node, build_config
    from go2vlm.msgs.builtin_interfaces import Time
    from go2vlm.msgs.image import numpy_to_image
    from go2vlm.msgs.sensor_msgs import Image
    from go2vlm.msgs.std_msgs import Header
    from go2vlm.msgs.vision_msgs import Detection2DArray
    from go2vlm.perception.vlm.vlm_node import VlmConfig, VlmNode

    topic = "/test_vlm_process/image_raw"
    cfg = build_config(
        VlmConfig,
        {"backend": "standin", "model": FAST, "mode": "detect", "image_topic": topic, "period_s": 0.0},
        node="vlm",
    )
    node = VlmNode(cfg)
    assert isinstance(node.backend, InferenceProcess)
    harness = Node(node_name="vlm_process_harness")
    cam = harness.create_publisher(Image, topic, QOS_SENSOR)
    dets = Recorder()
    harness.create_subscription(Detection2DArray, "/vlm/detections", dets, QOS_DEFAULT)
    harness.start()
    node.start()
    try:
        assert wait_for(lambda: node.state == "ready", 60)
        stamps = set()
        for i in range(50):
            stamp = 2000.0 + i
            stamps.add(stamp)
            frame = numpy_to_image(np.zeros((120, 160, 3), np.uint8), "bgr8", Header(stamp=Time.from_sec(stamp)))
            cam.publish(frame)
            if wait_for(lambda: len(dets.msgs()) >= 2, 0.1):
                break
        assert wait_for(lambda: len(dets.msgs()) >= 2, 30)
        for msg in dets.msgs():
            assert msg.header.stamp.to_sec() in stamps and not msg.detections  # "[]": nothing found
        status = node.status()
        assert status["state"] == "ready" and status["inferences"] >= 2
        assert status["load"]["process_start_s"] > 0 and "own process" in status["backend_detail"]
    finally:
        node.shutdown()
        harness.shutdown()
    assert node.backend._proc is None  # closed with the node
