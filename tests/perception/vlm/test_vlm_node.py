"""The vlm node over real DDS: stamps, boxes in original pixels, freshness, errors it survives."""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from busutil import Recorder, wait_for

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node, build_config
from go2vlm.geometry.qwen import CoordSystem
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.image import numpy_to_image
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.msgs.vision_msgs import Detection2DArray
from go2vlm.perception.vlm.backend import BackendError, Generation, VlmOutOfMemory
from go2vlm.perception.vlm.prompts import DECISION_PROMPT, DEFAULT_PROMPT, detect_prompt, way_prompt
from go2vlm.perception.vlm.vlm_node import VlmConfig, VlmNode, image_to_rgb
from go2vlm.perception.way import parse_way_message
from testing_support.tiny_qwen import DEFAULT_ANSWER

EXPECTED_480x640 = {"red ball": (80.0, 120.0, 280.0, 360.0), "green box": (360.0, 40.0, 600.0, 240.0)}
_topic_seq = iter(range(1_000_000))


def unique_topic() -> str:
    """Each test its own image topic, so nodes of one test never see another's frames."""
    return f"/test_vlm/cam{next(_topic_seq)}/image_raw"


def image(index: int, h: int = 480, w: int = 640, stamp: float = 0.0) -> Image:
    """A bgr8 frame whose first pixel's blue value encodes ``index`` (read back by fakes)."""
    arr = np.zeros((h, w, 3), dtype=np.uint8)
    arr[0, 0, 0] = index % 256
    return numpy_to_image(arr, "bgr8", Header(stamp=Time.from_sec(stamp or 1000.0 + index), frame_id="cam"))


class GatedBackend:
    """A backend that blocks in generate() until the test lets it go: makes freshness deterministic."""

    name = "fake"
    description = "fake gated backend"

    def __init__(self, fail: list[Exception] | None = None) -> None:
        self.started: list[int] = []
        self.prompts: list[str] = []
        self.text = DEFAULT_ANSWER
        self.gate = threading.Semaphore(0)
        self.fail = list(fail or [])
        self.cond = threading.Condition()

    def load(self) -> None:
        pass

    def generate(self, rgb: np.ndarray, prompt: str) -> Generation:
        with self.cond:
            self.started.append(int(rgb[0, 0, 2]))  # RGB now: blue is channel 2
            self.prompts.append(prompt)
            self.cond.notify_all()
        assert self.gate.acquire(timeout=30), "test never released the gate"
        if self.fail:
            raise self.fail.pop(0)
        return Generation(
            text=self.text,
            original_hw=(int(rgb.shape[0]), int(rgb.shape[1])),
            resized_hw=(84, 112),
            coords=CoordSystem.RESIZED_PIXELS,
            visual_tokens=12,
            timings_ms={"preprocess": 1.0, "prefill": 2.0, "decode": 3.0, "total": 6.0},
        )

    def close(self) -> None:
        pass


def boxes_of(msg: Detection2DArray) -> dict[str, tuple[float, float, float, float]]:
    out = {}
    for d in msg.detections:
        cx, cy, sx, sy = d.bbox.center.position.x, d.bbox.center.position.y, d.bbox.size_x, d.bbox.size_y
        out[d.results[0].hypothesis.class_id] = (cx - sx / 2, cy - sy / 2, cx + sx / 2, cy + sy / 2)
    return out


def assert_expected(msg: Detection2DArray) -> None:
    got = boxes_of(msg)
    assert set(got) == set(EXPECTED_480x640)
    for label, box in EXPECTED_480x640.items():
        assert got[label] == pytest.approx(box, abs=1e-6), label


class Harness:
    """A camera publisher and recorders for the node's outputs, on a second node."""

    def __init__(self, topic: str) -> None:
        self.node = Node(node_name="vlm_test_harness")
        self.cam = self.node.create_publisher(Image, topic, QOS_SENSOR)
        self.text, self.dets, self.status, self.decision = Recorder(), Recorder(), Recorder(), Recorder()
        self.query = self.node.create_publisher(String, "/target/query", QOS_LATCHED)
        self.node.create_subscription(String, "/vlm/detection", self.text, QOS_DEFAULT)
        self.node.create_subscription(String, "/vlm/decision", self.decision, QOS_DEFAULT)
        self.node.create_subscription(Detection2DArray, "/vlm/detections", self.dets, QOS_DEFAULT)
        self.node.create_subscription(String, "/vlm/status", self.status, QOS_DEFAULT)
        self.node.start()

    def statuses(self) -> list[dict[str, Any]]:
        return [json.loads(m.data) for m in self.status.msgs()]

    def close(self) -> None:
        self.node.shutdown()


@pytest.fixture
def harness():
    topic = unique_topic()
    h = Harness(topic)
    h.topic = topic  # type: ignore[attr-defined]
    yield h
    h.close()


def make_node(topic: str, backend: Any, **params: Any) -> VlmNode:
    values = {"model": "fake", "image_topic": topic, "period_s": 0.0, "status_period_s": 0.1, **params}
    cfg = build_config(VlmConfig, values, node="vlm")
    node = VlmNode(cfg, backend=backend)
    node.start()
    return node


def test_config_defaults_and_validation() -> None:
    cfg = VlmConfig(model="m")
    assert cfg.prompt == DEFAULT_PROMPT == "描述图片中的场景,指出物体颜色、形状和位置。"
    assert cfg.image_topic == "/camera/image_raw" and cfg.mode == "describe" and cfg.backend == "transformers"
    from go2vlm.bus import ParamError

    with pytest.raises(ParamError, match="model"):
        build_config(VlmConfig, {}, node="vlm")
    with pytest.raises(ParamError):
        build_config(VlmConfig, {"model": "m", "min_pixels": 10_000, "max_pixels": 5_000}, node="vlm")
    with pytest.raises(ParamError):
        build_config(VlmConfig, {"model": "m", "quantization": "fp8"}, node="vlm")
    cfg = build_config(VlmConfig, {"model": "m", "labels": "[red ball, dog]"}, node="vlm")
    assert cfg.labels == ["red ball", "dog"]


def test_image_to_rgb_encodings() -> None:
    bgr = np.zeros((2, 3, 3), np.uint8)
    bgr[..., 0] = 255  # blue
    assert image_to_rgb(numpy_to_image(bgr, "bgr8"))[0, 0].tolist() == [0, 0, 255]
    assert image_to_rgb(numpy_to_image(bgr, "rgb8"))[0, 0].tolist() == [255, 0, 0]
    mono = np.full((2, 3), 7, np.uint8)
    assert image_to_rgb(numpy_to_image(mono, "mono8")).shape == (2, 3, 3)
    bad = Image(height=10, width=10, encoding="bgr8", step=30, data=b"short")
    with pytest.raises(ValueError):
        image_to_rgb(bad)


def test_newest_frame_wins_and_drops_are_counted(harness: Harness) -> None:
    fake = GatedBackend()
    node = make_node(harness.topic, fake, mode="detect", labels=["red ball", "green box"])  # type: ignore[attr-defined]
    try:
        # frame 1 starts an inference that blocks...
        assert wait_for(lambda: (harness.cam.publish(image(1)), bool(fake.started))[1], 20, period=0.2)
        first = fake.started[0]
        received_before = node.slot.received
        # ...while frames 2..6 arrive; only the newest may be inferred next
        for i in range(2, 7):
            harness.cam.publish(image(i))
        assert wait_for(lambda: node.slot.received >= received_before + 5, 10)
        # Late copies of frame 1 count as received too: wait until frame 6 is the one waiting.
        assert wait_for(lambda: (m := node.slot.peek()) is not None and m.header.stamp.sec == 1006, 10)
        fake.gate.release()
        assert wait_for(lambda: len(fake.started) >= 2, 10)
        assert fake.started[1] == 6
        assert node.slot.dropped >= 4
        fake.gate.release()
        assert wait_for(lambda: len(harness.dets) >= 2 and len(harness.text) >= 2, 10)
        stamps = [m.header.stamp.to_sec() for m in harness.dets.msgs()]
        assert stamps[:2] == [pytest.approx(1000.0 + first), pytest.approx(1006.0)]  # the source frames' stamps
        for msg in harness.dets.msgs()[:2]:
            assert msg.header.frame_id == "cam"
            assert_expected(msg)
            assert all(d.header.stamp == msg.header.stamp for d in msg.detections)
        assert harness.text.msgs()[0].data == DEFAULT_ANSWER
        assert wait_for(lambda: any(s["inferences"] >= 2 for s in harness.statuses()), 5)
        st = [s for s in harness.statuses() if s["inferences"] >= 2][-1]
        assert st["frames_dropped"] >= 4 and st["frames_received"] >= 6
        assert st["backend"] == "transformers" and st["mode"] == "detect" and st["state"] == "ready"
        assert st["latency_ms"]["total"] == 6.0 and "postprocess" in st["latency_ms"]
        assert st["result_age_ms"] is not None and st["source_stamp"] == pytest.approx(1006.0)
    finally:
        for _ in range(5):
            fake.gate.release()
        node.shutdown()


def test_detect_grounds_the_query_and_decide_publishes_raw_answers(harness: Harness) -> None:
    """mode=detect grounds exactly the /target/query label (else its `labels`); mode=decide asks the
    decision question and publishes the answer, untouched, on /vlm/decision only."""
    fake = GatedBackend()
    node = make_node(harness.topic, fake, mode="detect", labels=["green box"])  # type: ignore[attr-defined]
    try:

        def until(labels: set[str]) -> None:
            """Let inferences run on new frames until the newest answer has exactly these labels."""

            def step() -> bool:
                fake.gate.release()
                harness.cam.publish(image(len(fake.started)))
                msgs = harness.dets.msgs()
                return bool(msgs) and set(boxes_of(msgs[-1])) == labels

            assert wait_for(step, 20, 0.2), (labels, [boxes_of(m) for m in harness.dets.msgs()[-3:]])

        until({"green box"})
        assert fake.prompts[0] == detect_prompt(["green box"])
        harness.query.publish(String(data="  red   ball\x07"))  # spaces and a control character cleaned
        assert wait_for(lambda: node.query == "red ball", 10)
        until({"red ball"})  # the query, not `labels`
        assert detect_prompt(["red ball"]) in fake.prompts
        harness.query.publish(String(data="blue cylinder"))
        until(set())  # the model named no blue cylinder: an empty answer
        assert detect_prompt(["blue cylinder"]) in fake.prompts
        harness.query.publish(String(data=""))
        until({"green box"})
        assert fake.prompts[-1] == detect_prompt(["green box"])
        assert wait_for(lambda: any(s.get("query") == "" for s in harness.statuses()), 5)
        assert len(harness.decision) == 0
    finally:
        for _ in range(5):
            fake.gate.release()
        node.shutdown()
    fake = GatedBackend()
    fake.text = 'RUN FORWARD {"action": "forward"}'
    node = make_node(harness.topic, fake, mode="decide")  # type: ignore[attr-defined]
    try:
        n_text = len(harness.text)
        fake.gate.release()
        assert wait_for(lambda: (harness.cam.publish(image(1)), len(harness.decision) >= 1)[1], 20, 0.2)
        assert fake.prompts == [DECISION_PROMPT]
        assert harness.decision.msgs()[0].data == 'RUN FORWARD {"action": "forward"}'  # raw: the commander judges
        assert len(harness.text) == n_text
    finally:
        for _ in range(5):
            fake.gate.release()
        node.shutdown()


def test_way_mode_answers_the_commanders_question_about_each_frame(harness: Harness) -> None:
    """mode=way: no question, no inference; with one on /explore/way_query, the raw answer about each
    frame goes out on /vlm/way with that frame's stamp and the object asked about (perception/way.py)."""
    ways = Recorder()
    harness.node.create_subscription(String, "/vlm/way", ways, QOS_DEFAULT)
    ask = harness.node.create_publisher(String, "/explore/way_query", QOS_LATCHED)
    fake = GatedBackend()
    fake.text = "Likely, through the door"
    node = make_node(harness.topic, fake, mode="way")  # type: ignore[attr-defined]
    try:
        for k in range(5):  # frames without a question: skipped
            harness.cam.publish(image(k))
        assert wait_for(lambda: node.status()["frames_processed"] >= 1, 10), node.status()  # taken, not asked
        assert fake.started == []
        ask.publish(String(data="duck"))
        assert wait_for(lambda: node.query == "duck", 10)

        def answered() -> bool:
            fake.gate.release()
            harness.cam.publish(image(7, stamp=1234.5))
            return len(ways) >= 1

        assert wait_for(answered, 20, 0.2)
        first = fake.started[0]  # the newest frame when the question came (one left in the slot), or frame 7
        stamp = 1234.5 if first == 7 else 1000.0 + first
        assert parse_way_message(ways.msgs()[0].data) == (stamp, "duck", "Likely, through the door")
        assert fake.prompts[0] == way_prompt("duck") and len(harness.text) == 0
    finally:
        for _ in range(5):
            fake.gate.release()
        node.shutdown()


def test_errors_are_counted_and_node_keeps_running(harness: Harness) -> None:
    fake = GatedBackend(fail=[VlmOutOfMemory("CUDA out of memory ... Try: quantization=nf4"), BackendError("down")])
    node = make_node(harness.topic, fake)  # type: ignore[attr-defined]
    try:
        # No known encoding (a truncated one never gets past the bus's size check: msgs/sizes.py).
        bad = Image(header=Header(frame_id="cam"), height=4, width=4, encoding="yuv_weird", step=12, data=bytes(48))
        for i in range(3):
            fake.gate.release()
            n = len(fake.started)
            assert wait_for(lambda n=n, i=i: (harness.cam.publish(image(10 + i)), len(fake.started) > n)[1], 20, 0.2)
        assert wait_for(lambda: len(harness.text) >= 1, 10)
        for _ in range(20):  # from here on generate() never blocks
            fake.gate.release()
        assert wait_for(lambda: (harness.cam.publish(bad), node.errors["bad_images"] >= 1)[1], 10, 0.2)
        assert node.errors["oom_errors"] == 1 and node.errors["backend_errors"] == 1
        assert wait_for(lambda: any(s["errors"].get("oom_errors") == 1 for s in harness.statuses()), 5)
        assert node.running
    finally:
        for _ in range(5):
            fake.gate.release()
        node.shutdown()


def test_load_failure_is_reported(harness: Harness) -> None:
    class Broken(GatedBackend):
        def load(self) -> None:
            raise BackendError("cannot read a model config from 'nope'")

    node = make_node(harness.topic, Broken())  # type: ignore[attr-defined]
    try:
        assert wait_for(lambda: any(s["state"] == "error" for s in harness.statuses()), 10)
        st = [s for s in harness.statuses() if s["state"] == "error"][-1]
        assert "nope" in st["last_error"] and st["errors"]["load_errors"] == 1
    finally:
        node.shutdown()


@pytest.mark.slow
def test_cli_node_with_tiny_model_over_dds(tiny_ckpt: Path, procs, harness: Harness, tmp_path: Path) -> None:  # noqa: ANN001
    """`go2vlm run vlm` as a real process: camera at 10 Hz, answers for recent frames, drops counted."""
    topic = harness.topic  # type: ignore[attr-defined]
    log_path = tmp_path / "vlm.log"
    log_file = open(log_path, "w")  # noqa: SIM115 - a file, not a pipe nobody reads while the node runs
    proc = procs.start(
        "run",
        "vlm",
        "--param",
        f"model={tiny_ckpt}",
        "--param",
        "mode=detect",
        "--param",
        "labels=[red ball, green box]",
        "--param",
        "max_pixels=12544",
        "--param",
        "max_new_tokens=96",
        "--param",
        "period_s=0.0",
        "--param",
        "status_period_s=0.5",
        "--param",
        f"image_topic={topic}",
        "--param",
        "api_key=sk-cli-SECRET",
        stdout=log_file,
    )
    published: list[float] = []
    stop = threading.Event()

    def camera() -> None:
        i = 0
        while not stop.is_set():
            i += 1
            t = harness.node.now()
            harness.cam.publish(image(i, stamp=t))
            published.append(t)
            stop.wait(0.1)  # 10 Hz

    def mine() -> list[dict[str, Any]]:
        # Only this process's node: other tests' nodes share the session's domain and status topic.
        return [s for s in harness.statuses() if s["model"] == str(tiny_ckpt)]

    cam = threading.Thread(target=camera, daemon=True)
    cam.start()
    try:
        ok = wait_for(lambda: len(harness.dets) >= 3 or proc.poll() is not None, 180, 0.2)
        assert proc.poll() is None, log_path.read_text()[-3000:]
        assert ok
        # Frames are dropped while the model loads too: wait for a status published after answers.
        assert wait_for(lambda: bool(mine()) and mine()[-1]["inferences"] > 0 and mine()[-1]["frames_dropped"] > 0, 30)
    finally:
        stop.set()
        cam.join(2)
    msgs = harness.dets.msgs()
    stamps = [m.header.stamp.to_sec() for m in msgs]
    assert all(any(abs(s - p) < 1e-6 for p in published) for s in stamps), "stamps are source frame stamps"
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
    for m in msgs:
        assert_expected(m)
    assert harness.text.msgs()[-1].data == DEFAULT_ANSWER
    st = mine()[-1]
    assert st["state"] == "ready" and st["visual_tokens"] == 12 and st["resized_hw"] == [84, 112]
    assert st["frames_dropped"] > 0 and st["frames_received"] > st["inferences"]
    assert set(st["latency_ms"]) >= {"preprocess", "prefill", "decode", "postprocess", "total"}
    procs.stop(proc)
    log_file.close()
    log = log_path.read_text()
    assert "SECRET" not in log and all("SECRET" not in m.data for m in harness.status.msgs())
    assert "model ready" in log


@pytest.mark.slow
def test_node_with_openai_backend_over_dds(
    tiny_server: str, tiny_ckpt: Path, harness: Harness, capfd: pytest.CaptureFixture[str]
) -> None:
    """The node built from parameters alone, talking to `transformers serve`; the key never shows."""
    values = {
        "model": str(tiny_ckpt),
        "backend": "openai",
        "base_url": tiny_server,
        "api_key": "sk-node-SECRET",
        "mode": "detect",
        "max_pixels": 12544,
        "period_s": 0.0,
        "status_period_s": 0.2,
        "image_topic": harness.topic,  # type: ignore[attr-defined]
    }
    node = VlmNode(build_config(VlmConfig, values, node="vlm"))
    node.start()
    try:
        i = 0

        def publish_and_check() -> bool:
            nonlocal i
            i += 1
            harness.cam.publish(image(i, stamp=2000.0 + i))
            return len(harness.dets) >= 1

        assert wait_for(publish_and_check, 60, 0.2)
        msg = harness.dets.msgs()[0]
        assert 2000.0 < msg.header.stamp.to_sec() <= 2000.0 + i
        assert_expected(msg)
        assert wait_for(lambda: any(s["inferences"] >= 1 for s in harness.statuses()), 5)
        st = [s for s in harness.statuses() if s["inferences"] >= 1][-1]
        assert st["backend"] == "openai" and st["resized_hw"] == [84, 112] and st["visual_tokens"] == 12
        node.log.info(f"params: {node.params()} config: {node.config}")
    finally:
        node.shutdown()
    out = capfd.readouterr()
    assert "SECRET" not in out.out + out.err
    assert all("SECRET" not in m.data for m in harness.status.msgs())
