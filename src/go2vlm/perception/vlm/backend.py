"""What a VLM backend is: settings in, (image, prompt) -> answer text + geometry + timings out.

Two implementations: ``transformers`` (the model in this process, :mod:`.hf_backend`)
and ``openai`` (any OpenAI-compatible chat-completions server, :mod:`.openai_backend`);
:func:`go2vlm.perception.vlm.factory.make_backend` picks one.
Both return the size of the image the model actually saw, so boxes can be mapped back
to camera pixels the same way (:mod:`.geometry`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from go2vlm.geometry.qwen import DEFAULT_MAX_PIXELS, DEFAULT_MIN_PIXELS, CoordSystem

__all__ = [
    "API_KEY_ENV",
    "Backend",
    "BackendError",
    "BackendSettings",
    "Generation",
    "Secret",
    "VlmOutOfMemory",
    "checkpoint_pixel_limits",
    "pixel_limits_of",
    "resolve_api_key",
    "visual_token_mismatch",
]

API_KEY_ENV = ("GO2VLM_API_KEY", "OPENAI_API_KEY")


class Secret(str):
    """A string that prints as ``***`` (repr, str, format), so a key never reaches a log line.

    ``reveal()`` gives the real value to the one place that needs it (the HTTP client).
    """

    __slots__ = ()

    def __repr__(self) -> str:
        return "'***'" if self else "''"

    def __str__(self) -> str:
        return "***" if self else ""

    def __format__(self, spec: str) -> str:
        return str(self)

    def reveal(self) -> str:
        return str.__str__(self)


def checkpoint_pixel_limits(model: str) -> tuple[int, int] | None:
    """(min_pixels, max_pixels) of a local checkpoint's image processor (processor_config.json or
    preprocessor_config.json: `size` shortest_edge/longest_edge, or min_pixels/max_pixels); None when
    `model` is not a local directory that says."""
    import json
    from pathlib import Path

    root = Path(model).expanduser()
    for name in ("preprocessor_config.json", "processor_config.json"):
        try:
            cfg = json.loads((root / name).read_text())
        except (OSError, ValueError):
            continue
        limits = pixel_limits_of(cfg.get("image_processor", cfg))
        if limits is not None:
            return limits
    return None


def pixel_limits_of(image_processor: Any) -> tuple[int, int] | None:
    """(min_pixels, max_pixels) from a Qwen image processor or its config dict; None if it does not say."""

    def get(obj: Any, key: str) -> Any:  # a config dict, or the processor / its SizeDict (attributes)
        return obj.get(key) if isinstance(obj, dict) else getattr(obj, key, None)

    size = get(image_processor, "size") or {}
    lo = get(size, "shortest_edge") or get(image_processor, "min_pixels")
    hi = get(size, "longest_edge") or get(image_processor, "max_pixels")
    if isinstance(lo, int) and isinstance(hi, int) and 0 < lo <= hi:
        return lo, hi
    return None


TOKEN_TOLERANCE = 4  # chat templates differ by a token or two; a different resize differs by tens


def visual_token_mismatch(gen: Generation) -> str | None:
    """Why the server's token count says it saw another image size than the one whose pixels the boxes
    are mapped from (its own smart resize with a smaller max_pixels, ...), or None when it agrees or
    cannot tell. Boxes are then silently wrong: the caller counts and warns."""
    if not gen.prompt_tokens or not gen.expected_prompt_tokens:
        return None
    if abs(gen.prompt_tokens - gen.expected_prompt_tokens) <= TOKEN_TOLERANCE:
        return None
    h, w = gen.resized_hw
    return (
        f"the server counted {gen.prompt_tokens} prompt tokens, expected {gen.expected_prompt_tokens} for a {w}x{h} "
        f"image ({gen.visual_tokens} visual tokens): it resized the image itself, so boxes are mapped from the wrong "
        "size; set max_pixels to the server's (or max_pixels=0 for a local checkpoint it serves)"
    )


def resolve_api_key(param_value: str | None) -> Secret:
    """The API key: the parameter if set, else ``$GO2VLM_API_KEY``, else ``$OPENAI_API_KEY``."""
    if param_value:
        return Secret(param_value.reveal() if isinstance(param_value, Secret) else param_value)
    for name in API_KEY_ENV:
        value = os.environ.get(name)
        if value:
            return Secret(value)
    return Secret("")


class BackendError(RuntimeError):
    """Inference failed in a way the node reports and survives (server down, bad reply, ...)."""

    counter = "backend_errors"


class VlmOutOfMemory(BackendError):
    """CUDA ran out of memory; the message says what to change."""

    counter = "oom_errors"


@dataclass
class BackendSettings:
    model: str
    backend: str = "transformers"
    dtype: str = "auto"  # auto|fp16|bf16|fp32
    device: str = "auto"  # auto|cuda|cpu|cuda:N
    quantization: str = "none"  # none|nf4|int8
    compile: str = "auto"  # auto|on|off: transformers, static KV cache + compiled decode (auto: CUDA bf16/fp16)
    process: str = "auto"  # auto|on|off: the model in a process of its own (auto: transformers, standin)
    max_pixels: int = DEFAULT_MAX_PIXELS  # 0: the checkpoint's own processor limits (min_pixels too)
    min_pixels: int = DEFAULT_MIN_PIXELS
    max_new_tokens: int = 256
    min_new_tokens: int = 0  # benchmarks: force a fixed number of generated tokens (random weights)
    coords: str = "auto"  # auto|resized_pixels|norm_1000
    base_url: str = "http://127.0.0.1:8000/v1"
    api_key: Secret = field(default_factory=lambda: Secret(""))
    timeout_s: float = 30.0
    retries: int = 2
    jpeg_quality: int = 90


@dataclass
class Generation:
    """One answer, with what is needed to interpret it."""

    text: str
    original_hw: tuple[int, int]
    resized_hw: tuple[int, int]  # the image the model saw (H', W')
    coords: CoordSystem
    visual_tokens: int = 0
    prompt_tokens: int = 0
    new_tokens: int = 0
    # openai: the prompt tokens the server should count for this prompt and an image of resized_hw (its
    # text-only count + visual tokens + vision start/end); 0 = unknown. See visual_token_mismatch().
    expected_prompt_tokens: int = 0
    # milliseconds: preprocess, prefill (to first token), decode (the rest), total
    timings_ms: dict[str, float] = field(default_factory=dict)


class Backend(Protocol):
    name: str
    description: str  # model/device/dtype summary for status

    def load(self) -> None: ...

    def generate(self, rgb: np.ndarray, prompt: str) -> Generation: ...

    def close(self) -> None: ...
