"""vlm: a vision-language model (Qwen2.5-VL) looks at the camera and says what it sees.

Topics
  subscribes  <image_topic> (default /camera/image_raw)  sensor_msgs/Image, sensor-data QoS
              /target/query    std_msgs/String, latched (transient-local) QoS; mode=detect: the label
                               to ground, e.g. "blue cylinder" (the commander publishes its goal's
                               object): while it is non-empty the model grounds exactly that label,
                               else the `labels` parameter
              /explore/way_query  std_msgs/String, latched; mode=way: the object the commander searches
                               for ('' = no question: frames are skipped)
  publishes   /vlm/detection   std_msgs/String            describe/detect: the model's answer text
                               (length-capped)
              /vlm/detections  vision_msgs/Detection2DArray  mode=detect: boxes in the ORIGINAL
                               image's pixels, class_id = label (the query's or the requested
                               spelling), score = the model's score or 1.0, header = the source
                               image's header (stamp and frame_id); an empty array when it found none
              /vlm/decision    std_msgs/String            mode=decide: the model's raw answer to the
                               scene question (perception/vlm/prompts.py DECISION_PROMPT: stop /
                               continue / turn <= 30 deg / sit as JSON); untrusted text, the commander
                               maps it onto the whitelist of behavior/decisions.py
              /vlm/way         std_msgs/String            mode=way: JSON {"stamp", "object", "answer"}
                               (perception/way.py): the raw answer to "is this way likely to lead to
                               the object?" about one frame (its stamp); the commander keeps only a
                               whitelisted word (behavior/view_scores.py)
              /vlm/status      std_msgs/String (latched JSON, every status_period_s): model, backend, mode,
                               state, latency_ms of the last inference, result_age_ms, frames
                               received/dropped/processed, error and parse counters

Modes: describe (the `prompt`), detect (Qwen grounding JSON -> boxes), decide (the scene decision
question), way (which way to the commander's object, while it asks). One model serves one mode per
node; run a second vlm node (--name vlm_decide --param mode=decide) for decisions, sharing one
server with backend=openai.

Freshness: the image callback only stores the newest frame; a worker thread runs inference on
the newest frame at most every period_s. Frames replaced before the worker got to them are
dropped and counted. Every result carries its source frame's stamp; result_age_ms is
now - source stamp when the result is published.
Time: period_s, max_age_s and result_age_ms are in the node's clock, so with use_sim_time (and a
camera stamping sim time, as the sim does then) ages are sim seconds; latency_ms is wall time (how
long the model took) in both modes.

Backends: transformers (the model in this process; nf4/int8 via bitsandbytes) or openai (any
OpenAI-compatible server: vLLM, SGLang, Ollama, llama.cpp, `transformers serve`). The API key
comes from api_key or $GO2VLM_API_KEY / $OPENAI_API_KEY and is never logged or reported.

Parameters at runtime (`go2vlm param set vlm ...`): prompt, labels (the prompt is rebuilt; the next
inference uses it), period_s and max_age_s; the rest is set up at start-up and read-only.
"""

from __future__ import annotations

import json
import threading
import time
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from go2vlm.bus import Node, param
from go2vlm.bus.topics import (
    CAMERA_IMAGE,
    EXPLORE_WAY_QUERY,
    TARGET_QUERY,
    VLM_DECISION,
    VLM_DETECTIONS,
    VLM_STATUS,
    VLM_TEXT,
    VLM_WAY,
)
from go2vlm.errors import ConfigError
from go2vlm.geometry.qwen import DEFAULT_MAX_PIXELS, DEFAULT_MIN_PIXELS, QWEN_FACTOR
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.image import image_to_numpy
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.msgs.vision_msgs import Detection2DArray, detection_array
from go2vlm.perception.vlm.backend import (
    Backend,
    BackendError,
    BackendSettings,
    Generation,
    Secret,
    VlmOutOfMemory,
    visual_token_mismatch,
)
from go2vlm.perception.vlm.factory import make_backend
from go2vlm.perception.vlm.latest import LatestSlot, Stamped
from go2vlm.perception.vlm.prompts import DEFAULT_PROMPT, build_prompt, detect_prompt, way_prompt
from go2vlm.perception.way import way_message
from go2vlm.vocabulary.answers import Box, answer_boxes, sanitize_text

__all__ = ["VlmConfig", "VlmNode", "detections_msg", "image_to_rgb"]

MAX_QUERY_CHARS = 200
MAX_ANSWER_CHARS = 8192


@dataclass
class VlmConfig:
    model: str = param("", help="local checkpoint dir or hub id (openai: the served model name)")
    backend: str = param(
        "transformers",
        choices=("transformers", "openai", "standin"),
        help="standin: no model, a launch-bound eager decode's timing (benchmarks; perception/vlm/standin_backend.py)",
    )
    prompt: str = param(DEFAULT_PROMPT, help="describe-mode prompt (the VLM article's scene description)", live=True)
    mode: str = param(
        "describe",
        choices=("describe", "detect", "decide", "way"),
        help="detect: Qwen grounding JSON -> boxes; decide: the scene decision question -> /vlm/decision; "
        "way: is this way likely to lead to /explore/way_query's object -> /vlm/way",
    )
    labels: list[str] = param(
        list, help="detect: object categories to ground while /target/query is empty (empty: all objects)", live=True
    )
    max_pixels: int = param(
        DEFAULT_MAX_PIXELS,
        help="max H'*W' after smart resize (visual tokens = /784); 0 = the checkpoint's processor limits, min too",
        min=0,
    )
    min_pixels: int = param(DEFAULT_MIN_PIXELS, help="min H'*W' after smart resize", min=784)
    max_new_tokens: int = param(256, help="generation budget per frame", min=1, max=8192)
    dtype: str = param("auto", choices=("auto", "fp16", "bf16", "fp32"))
    device: str = param("auto", help="auto, cpu, cuda or cuda:N")
    quantization: str = param("none", choices=("none", "nf4", "int8"), help="bitsandbytes, CUDA only")
    compile: str = param(
        "auto",
        choices=("auto", "on", "off"),
        help="transformers: static KV cache + compiled decode, warmed up at load (auto: CUDA bf16/fp16, no bnb)",
    )
    inference_process: str = param(
        "auto",
        choices=("auto", "on", "off"),
        help="run the model in a process of its own, so that bus work cannot slow it (auto: transformers, standin)",
    )
    period_s: float = param(1.0, help="min time between inference starts", min=0.0, live=True)
    image_topic: str = param(CAMERA_IMAGE.name, help="sensor_msgs/Image input")
    max_age_s: float = param(
        0.0, help="skip frames older than this (receive time) at pickup; 0: off", min=0.0, live=True
    )
    coords: str = param("auto", choices=("auto", "resized_pixels", "norm_1000"), help="box convention override")
    base_url: str = param("http://127.0.0.1:8000/v1", help="openai: server URL")
    api_key: str = param("", help="openai: key (prefer $GO2VLM_API_KEY / $OPENAI_API_KEY); never logged")
    timeout_s: float = param(30.0, help="openai: request timeout", min=0.1)
    retries: int = param(2, help="openai: retries on connection errors/5xx, with backoff", min=0, max=10)
    status_period_s: float = param(1.0, help="period of /vlm/status", min=0.05)

    def __post_init__(self) -> None:
        # Mask the key in every repr/str (the CLI logs the parameters at start-up).
        if not isinstance(self.api_key, Secret):
            self.api_key = Secret(self.api_key or "")

    def validate(self) -> None:
        if not self.model.strip():
            raise ValueError("parameter 'model' is required (checkpoint dir, hub id or served model name)")
        if 0 < self.max_pixels < 784:
            raise ValueError(f"max_pixels ({self.max_pixels}) must be 0 (the checkpoint's limits) or >= 784")
        if self.max_pixels and self.min_pixels > self.max_pixels:
            raise ValueError(f"min_pixels ({self.min_pixels}) must not exceed max_pixels ({self.max_pixels})")
        dev = self.device
        if not (dev in ("auto", "cpu", "cuda") or (dev.startswith("cuda:") and dev[5:].isdigit())):
            raise ValueError(f"parameter 'device': {dev!r} is not auto, cpu, cuda or cuda:N")

    def backend_settings(self) -> BackendSettings:
        return BackendSettings(
            model=self.model,
            backend=self.backend,
            dtype=self.dtype,
            device=self.device,
            quantization=self.quantization,
            compile=self.compile,
            process=self.inference_process,
            max_pixels=self.max_pixels,
            min_pixels=self.min_pixels,
            max_new_tokens=self.max_new_tokens,
            coords=self.coords,
            base_url=self.base_url,
            api_key=Secret(self.api_key),
            timeout_s=self.timeout_s,
            retries=self.retries,
        )


def image_to_rgb(msg: Image) -> np.ndarray:
    """Any supported encoding as (H, W, 3) uint8 RGB. Raises ValueError on a bad image."""
    arr = image_to_numpy(msg)
    enc = msg.encoding
    if arr.dtype == np.uint16:
        arr = (arr >> 8).astype(np.uint8)
    if arr.ndim == 2:
        return np.repeat(arr[:, :, None], 3, axis=2)
    if enc in ("bgr8", "bgra8", "8UC3"):  # 8UC3 is OpenCV data, so BGR
        return np.ascontiguousarray(arr[:, :, 2::-1])
    return np.ascontiguousarray(arr[:, :, :3])


def detections_msg(boxes: list[Box], header: Header) -> Detection2DArray:
    """Boxes (original pixels) -> Detection2DArray with the source image's header."""
    # VLM grounding has no calibrated confidence: 1.0 means "reported", unless it gave one
    return detection_array(header, ((b.label, b.box, 1.0 if b.score is None else b.score) for b in boxes))


class VlmNode(Node):
    """The ``vlm`` node; its contract (topics, parameters, freshness) is the module docstring."""

    name = "vlm"
    Config = VlmConfig

    def __init__(self, config: VlmConfig, *, backend: Backend | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        self.config: VlmConfig
        cfg = self.config
        self.prompt = build_prompt(cfg.mode, cfg.prompt, cfg.labels)
        self.query = ""  # detect: the label /target/query asks for ('' = the labels parameter)
        self.backend: Backend = backend if backend is not None else make_backend(cfg.backend_settings())
        self.slot: LatestSlot[Image] = LatestSlot(self.clock)
        self._stats = threading.Lock()
        self.state = "loading"
        self.last_error = ""
        self.errors: Counter[str] = Counter()
        self.parse_counters: Counter[str] = Counter()
        self.inferences = 0
        self.last_gen: Generation | None = None
        self.last_latency_ms: dict[str, float] = {}
        self.last_result_age_ms: float | None = None
        self.last_source_stamp: float | None = None
        self.last_source_seq = 0
        self.last_detections = 0
        self.load_report: dict[str, float] = {}  # the backend's: load_s, compile_warmup_s, process_start_s
        self.pub_text = VLM_TEXT.publisher(self)
        self.pub_dets = VLM_DETECTIONS.publisher(self)
        self.pub_decision = VLM_DECISION.publisher(self)
        self.pub_status = VLM_STATUS.publisher(self)
        CAMERA_IMAGE.subscription(self, self.on_image, name=cfg.image_topic)
        if cfg.mode == "detect":
            TARGET_QUERY.subscription(self, self.on_query)
        if cfg.mode == "way":
            self.pub_way = VLM_WAY.publisher(self)
            EXPLORE_WAY_QUERY.subscription(self, self.on_query)
        self.create_timer(cfg.status_period_s, self.publish_status)
        self.log.info(
            f"{self.backend.name} backend, model {cfg.model}, mode {cfg.mode}, "
            f"max_pixels {cfg.max_pixels or 'from the checkpoint'} "
            f"(<= {cfg.max_pixels // (QWEN_FACTOR * QWEN_FACTOR) or '?'} visual tokens), "
            f"listening on {self.resolve(cfg.image_topic)}"
        )
        self._halt = threading.Event()
        self._worker = threading.Thread(target=self._work, name=f"{self.node_name}:inference", daemon=True)
        self._worker.start()

    # -- subscription: never blocks ------------------------------------------------------------
    def on_params_changed(self, old: Any, changed: frozenset[str]) -> None:
        if changed & {"prompt", "labels"}:
            cfg = self.config
            self.prompt = build_prompt(cfg.mode, cfg.prompt, cfg.labels)

    def on_image(self, msg: Image) -> None:
        self.slot.put(msg)

    def on_query(self, msg: String) -> None:
        query = " ".join(sanitize_text(msg.data, MAX_QUERY_CHARS, Counter()).split())
        with self._stats:
            changed, self.query = query != self.query, query
        if changed:
            fallback = self.config.labels or "all objects"
            self.log.info(f"grounding {query!r}" if query else f"query cleared: grounding {fallback}")

    def _task(self) -> tuple[str, list[str]]:
        """The prompt and the labels for the next inference (the query wins over `labels`)."""
        with self._stats:
            query = self.query
        if self.config.mode == "detect" and query:
            return detect_prompt([query]), [query]
        if self.config.mode == "way":
            return way_prompt(query), [query]
        return self.prompt, list(self.config.labels)

    # -- worker --------------------------------------------------------------------------------
    def _bump(self, name: str, n: int = 1) -> None:
        with self._stats:
            self.errors[name] += n

    def _work(self) -> None:
        try:
            self.backend.load()
        except Exception as exc:  # noqa: BLE001 - reported on /vlm/status, node stays up
            with self._stats:
                self.state = "error"
                self.last_error = f"load failed: {type(exc).__name__}: {exc}"
                self.errors["load_errors"] += 1
            self.log.error(f"cannot load the model: {type(exc).__name__}: {exc}")
            # At start a model that cannot load never will: end the node, not idle without one (a
            # wrong model, device or dtype is a configuration error, exit 2; out of memory exit 1).
            oom = isinstance(exc, VlmOutOfMemory)
            self.fail(exc if oom else ConfigError(f"cannot load the model {self.config.model!r}: {exc}"))
            return
        with self._stats:
            self.state = "ready"
        limits = getattr(self.backend, "settings", None)
        pixels = f", pixels {limits.min_pixels}..{limits.max_pixels}" if limits is not None else ""
        report = dict(getattr(self.backend, "load_report", {}))
        with self._stats:
            self.load_report = report
        took = ", ".join(f"{k} {v:g}" for k, v in report.items())
        self.log.info(f"model ready: {self.backend.description}{pixels}" + (f" ({took})" if took else ""))
        next_start = 0.0
        while not self._halt.is_set():
            if self.clock.monotonic() < next_start:
                self.clock.wait_until(next_start, self._halt)
                continue
            frame = self.slot.take(timeout_s=0.2)
            if frame is None:
                continue
            cfg = self.config
            if cfg.mode == "way" and not self._task()[1][0]:
                continue  # no question stands: no answer wanted
            if cfg.max_age_s > 0 and self.clock.monotonic() - frame.received_t > cfg.max_age_s:
                self._bump("stale_frames")
                continue
            next_start = self.clock.monotonic() + cfg.period_s
            self._infer(frame)

    def _infer(self, frame: Stamped[Image]) -> None:
        msg = frame.item
        try:
            rgb = image_to_rgb(msg)
        except ValueError as exc:
            self._bump("bad_images")
            self.log.throttled("warning", 5.0, f"dropping a bad image: {exc}", key="bad_image")
            return
        prompt, labels = self._task()
        try:
            gen = self.backend.generate(rgb, prompt)
        except VlmOutOfMemory as exc:
            self._record_error(exc.counter, str(exc))
            self.log.throttled("error", 10.0, str(exc), key="oom")
            return
        except BackendError as exc:
            self._record_error(exc.counter, str(exc))
            self.log.throttled("error", 5.0, f"inference failed: {exc}", key="backend")
            return
        except Exception as exc:  # noqa: BLE001 - a model bug must not kill the robot's perception node
            self._record_error("inference_errors", f"{type(exc).__name__}: {exc}")
            self.log.throttled("error", 5.0, f"inference failed: {type(exc).__name__}: {exc}", key="infer")
            return
        self._publish(frame, gen, labels)

    def _record_error(self, counter: str, text: str) -> None:
        with self._stats:
            self.errors[counter] += 1
            self.last_error = text[:500]

    def _publish(self, frame: Stamped[Image], gen: Generation, labels: list[str]) -> None:
        t0 = time.perf_counter()  # wall time: a compute latency, reported as latency_ms
        cfg = self.config
        src = frame.item.header
        header = Header(stamp=Time(sec=src.stamp.sec, nanosec=src.stamp.nanosec), frame_id=src.frame_id)
        counters: Counter[str] = Counter()
        text = sanitize_text(gen.text, MAX_ANSWER_CHARS, counters)
        boxes: list[Box] = []
        if cfg.mode == "detect":
            _, boxes = answer_boxes(gen, labels, counters)
        src_t = src.stamp.to_sec() if (src.stamp.sec or src.stamp.nanosec) else frame.received_stamp
        if cfg.mode == "decide":
            self.pub_decision.publish(String(data=text))
        elif cfg.mode == "way":
            self.pub_way.publish(String(data=way_message(src_t, labels[0], text)))
        else:
            self.pub_text.publish(String(data=text))
        if cfg.mode == "detect":
            self.pub_dets.publish(detections_msg(boxes, header))
        mismatch = visual_token_mismatch(gen)
        if mismatch is not None:
            counters["visual_token_mismatch"] += 1
            self.log.throttled("warning", 10.0, mismatch, key="visual_tokens")
        post_ms = (time.perf_counter() - t0) * 1e3
        age_ms = (self.now() - src_t) * 1e3
        with self._stats:
            self.inferences += 1
            self.parse_counters.update(counters)
            self.last_gen = gen
            self.last_latency_ms = {k: round(v, 2) for k, v in gen.timings_ms.items()}
            self.last_latency_ms["postprocess"] = round(post_ms, 2)
            self.last_result_age_ms = round(age_ms, 1)
            self.last_source_stamp = src_t
            self.last_source_seq = frame.seq
            self.last_detections = len(boxes)
        self.log.debug(f"answer ({gen.timings_ms.get('total', 0.0):.0f} ms, age {age_ms:.0f} ms): {text[:80]!r}")

    # -- status --------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        cfg = self.config
        with self._stats:
            gen = self.last_gen
            last_age = None if self.last_source_stamp is None else round((self.now() - self.last_source_stamp) * 1e3, 1)
            return {
                "node": self.node_name,
                "model": cfg.model,
                "backend": cfg.backend,
                "backend_detail": self.backend.description,
                "mode": cfg.mode,
                "query": self.query,
                "state": self.state,
                "load": dict(self.load_report),
                "last_error": self.last_error,
                "latency_ms": dict(self.last_latency_ms),
                "result_age_ms": self.last_result_age_ms,
                "last_result_age_ms": last_age,
                "source_stamp": self.last_source_stamp,
                "source_seq": self.last_source_seq,
                "frames_received": self.slot.received,
                "frames_dropped": self.slot.dropped,
                "frames_processed": self.slot.taken,
                "inferences": self.inferences,
                "detections": self.last_detections,
                "visual_tokens": gen.visual_tokens if gen else None,
                "resized_hw": list(gen.resized_hw) if gen else None,
                "errors": dict(self.errors),
                "parse": dict(self.parse_counters),
            }

    def publish_status(self) -> None:
        self.pub_status.publish(String(data=json.dumps(self.status(), ensure_ascii=False)))

    def close(self) -> None:
        self._halt.set()
        self.slot.close()
        # Generation cannot be interrupted; a daemon worker finishing its frame is harmless.
        self._worker.join(timeout=5.0)
        try:
            self.backend.close()
        except Exception as exc:  # noqa: BLE001
            self.log.warning(f"backend close failed: {exc}")
