"""``openai`` backend: any OpenAI-compatible chat-completions server with image input.

vLLM, SGLang, Ollama, llama.cpp's server and ``transformers serve`` all take an image as a
base64 ``data:`` URL in a ``image_url`` content part. The client cannot see the server's
processor, yet Qwen2.5-VL answers boxes in pixels of the image *after* the server's smart
resize. So the client does the resize itself: it sends an image already at
``smart_resize(H, W, min_pixels, max_pixels)``; both sides a multiple of 28 and the area in
range, the server's own smart resize leaves it unchanged (as long as the server's
``max_pixels`` is not smaller than ours), and the coordinate frame is known exactly. It also
sends fewer bytes.

The API key comes from the ``api_key`` parameter or ``$GO2VLM_API_KEY`` / ``$OPENAI_API_KEY``
and is only ever handed to the HTTP client, never logged or reported.
"""

from __future__ import annotations

import base64
import io
import random
import time
from typing import Any

import numpy as np

from go2vlm.geometry.qwen import (
    DEFAULT_MAX_PIXELS,
    DEFAULT_MIN_PIXELS,
    CoordSystem,
    coord_system_for,
    smart_resize,
    visual_tokens,
)
from go2vlm.perception.vlm.backend import (
    BackendError,
    BackendSettings,
    Generation,
    checkpoint_pixel_limits,
    resolve_api_key,
)

__all__ = ["OpenAIBackend", "coords_from_model_name", "encode_jpeg_data_url"]


def coords_from_model_name(name: str) -> CoordSystem:
    """Guess the box convention from a served model's name (``coords`` param overrides)."""
    n = name.lower().replace("-", "_").replace(".", "_")
    if "qwen3" in n or "qwen2_vl" in n:
        return CoordSystem.NORM_1000
    return coord_system_for("qwen2_5_vl")


def encode_jpeg_data_url(rgb: np.ndarray, size_hw: tuple[int, int], quality: int = 90) -> str:
    """Resize (bicubic, as Qwen's processor) and JPEG-encode into a ``data:`` URL."""
    from PIL import Image

    image = Image.fromarray(np.ascontiguousarray(rgb))
    if (image.height, image.width) != size_hw:
        image = image.resize((size_hw[1], size_hw[0]), Image.Resampling.BICUBIC)
    buf = io.BytesIO()
    image.save(buf, format="JPEG", quality=quality)
    return "data:image/jpeg;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


class OpenAIBackend:
    name = "openai"

    def __init__(self, settings: BackendSettings) -> None:
        self.settings = settings
        self.client: Any = None
        self.coords = (
            CoordSystem(settings.coords)
            if settings.coords not in ("", "auto")
            else coords_from_model_name(settings.model)
        )
        self.description = f"openai:{settings.model} @ {settings.base_url}"
        self.retries_used = 0
        self._text_tokens: dict[str, int] = {}  # prompt -> the server's count without the image (0: unknown)

    def load(self) -> None:
        import openai

        s = self.settings
        if not s.model:
            raise BackendError("parameter model is empty: give the model name the server serves")
        if s.max_pixels == 0:  # the checkpoint's own limits, where the served model's name is a local dir
            s.min_pixels, s.max_pixels = checkpoint_pixel_limits(s.model) or (DEFAULT_MIN_PIXELS, DEFAULT_MAX_PIXELS)
        key = resolve_api_key(s.api_key)
        # Our own retry loop (below) so that retries are counted and backoff is bounded by us.
        self.client = openai.OpenAI(
            base_url=s.base_url,
            api_key=key.reveal() or "EMPTY",  # local servers want no key, the SDK wants a string
            timeout=s.timeout_s,
            max_retries=0,
        )

    def _text_only_tokens(self, prompt: str) -> int:
        """The server's prompt-token count for `prompt` without an image (one 1-token request per distinct
        prompt, cached); 0 when the server does not say or the request fails (the check is then off)."""
        if prompt not in self._text_tokens:
            try:
                r = self.client.chat.completions.create(
                    model=self.settings.model,
                    messages=[{"role": "user", "content": [{"type": "text", "text": prompt}]}],
                    max_tokens=1,
                    temperature=0.0,
                )
                self._text_tokens[prompt] = int(getattr(r.usage, "prompt_tokens", 0) or 0)
            except Exception:  # noqa: BLE001 - a calibration, never a reason to lose the answer
                self._text_tokens[prompt] = 0
        return self._text_tokens[prompt]

    def _request(self, data_url: str, prompt: str) -> tuple[str, float | None, int, int]:
        """One streamed request: (text, time of first content token, prompt tokens, completion tokens)."""
        s = self.settings
        stream = self.client.chat.completions.create(
            model=s.model,
            messages=[
                {
                    "role": "user",
                    "content": [
                        {"type": "image_url", "image_url": {"url": data_url}},
                        {"type": "text", "text": prompt},
                    ],
                }
            ],
            max_tokens=s.max_new_tokens,
            temperature=0.0,
            stream=True,
        )
        parts: list[str] = []
        first: float | None = None
        prompt_tokens = completion_tokens = 0
        for chunk in stream:
            usage = getattr(chunk, "usage", None)
            if usage is not None:
                prompt_tokens = int(getattr(usage, "prompt_tokens", 0) or 0)
                completion_tokens = int(getattr(usage, "completion_tokens", 0) or 0)
            for choice in getattr(chunk, "choices", None) or []:
                delta = getattr(choice, "delta", None)
                content = getattr(delta, "content", None) if delta is not None else None
                if isinstance(content, str) and content:
                    if first is None:
                        first = time.perf_counter()
                    parts.append(content)
        return "".join(parts), first, prompt_tokens, completion_tokens

    def generate(self, rgb: np.ndarray, prompt: str) -> Generation:
        import openai

        if self.client is None:
            raise BackendError("client not created (load() not called)")
        s = self.settings
        t0 = time.perf_counter()  # wall time here and below: request latencies and network retries
        oh, ow = int(rgb.shape[0]), int(rgb.shape[1])
        resized = smart_resize(oh, ow, min_pixels=s.min_pixels, max_pixels=s.max_pixels)
        data_url = encode_jpeg_data_url(rgb, resized, s.jpeg_quality)
        t1 = time.perf_counter()
        attempt = 0
        while True:
            t_req = time.perf_counter()
            try:
                text, first, prompt_tokens, completion_tokens = self._request(data_url, prompt)
                break
            except (openai.APIConnectionError, openai.APITimeoutError, openai.RateLimitError) as exc:
                err: Exception = exc
                retryable = True
            except openai.APIStatusError as exc:
                err = exc
                retryable = exc.status_code >= 500
            if not retryable or attempt >= s.retries:
                # str(exc) of the SDK's errors carries status and server message, never our key
                raise BackendError(f"{type(err).__name__} from {s.base_url}: {err}") from err
            attempt += 1
            self.retries_used += 1
            # Exponential backoff with jitter, capped so a camera-rate loop is not stalled long.
            time.sleep(min(2.0, 0.25 * 2 ** (attempt - 1)) * (0.5 + random.random()))
        t2 = time.perf_counter()
        first_t = first if first is not None else t2
        n_visual = visual_tokens(resized)
        base = self._text_only_tokens(prompt) if prompt_tokens else 0
        expected = base + n_visual + 2 if base else 0  # + <|vision_start|> and <|vision_end|>
        return Generation(
            text=text,
            original_hw=(oh, ow),
            resized_hw=resized,
            coords=self.coords,
            visual_tokens=n_visual,
            prompt_tokens=prompt_tokens,
            expected_prompt_tokens=expected,
            new_tokens=completion_tokens,
            timings_ms={
                "preprocess": (t1 - t0) * 1e3,
                # Through HTTP: time to the first streamed token ~ server preprocess + prefill + network.
                "prefill": (first_t - t_req) * 1e3,
                "decode": (t2 - first_t) * 1e3,
                "total": (t2 - t0) * 1e3,
                "retries": float(attempt),
            },
        )

    def close(self) -> None:
        client, self.client = self.client, None
        if client is not None:
            try:
                client.close()
            except Exception:  # noqa: BLE001 - closing is best effort
                pass
