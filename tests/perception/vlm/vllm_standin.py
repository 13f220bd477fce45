"""A stand-in for `vllm serve Qwen/Qwen2.5-VL-3B-Instruct` on loopback: it answers the OpenAI chat
completions API exactly as vLLM does for Qwen2.5-VL, where it matters to go2vlm:

- the image goes through Qwen2.5-VL's processor: smart resize (factor 28, min_pixels 3136, and
  max_pixels from `--mm-processor-kwargs '{"max_pixels": N}'`, default the checkpoint's 12845056);
- the model answers boxes in **absolute pixels of that resized image** (Qwen2.5-VL's convention);
  here the "model" is a red-pixel finder on the resized image, so the right answer is known;
- streaming as vLLM streams: a first chunk with the role, content deltas, a chunk with the finish
  reason, `data: [DONE]`; usage in the stream only with `stream_options.include_usage` or when
  the server was started with `--enable-force-include-usage`;
- prompt tokens = the text's tokens + the image's visual tokens + 2 (vision start/end).
"""

from __future__ import annotations

import base64
import io
import json
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import numpy as np

from go2vlm.geometry.qwen import smart_resize

CHECKPOINT_MAX_PIXELS = 12845056  # Qwen2.5-VL's preprocessor_config.json
MIN_PIXELS = 3136


def text_tokens(messages: list[dict[str, Any]]) -> int:
    """A deterministic stand-in for the tokenizer's count of the chat template and the text."""
    n = 20  # the system turn and the template's markers
    for m in messages:
        content = m.get("content")
        parts = [content] if isinstance(content, str) else [p.get("text", "") for p in content or []]
        n += sum(len(p.encode()) // 4 + 1 for p in parts if p)
    return n


def red_box(rgb: np.ndarray) -> list[int] | None:
    """The red object's box [x1, y1, x2, y2] in this image's pixels (the stand-in model's answer)."""
    r, g, b = (rgb[..., i].astype(int) for i in range(3))
    ys, xs = np.nonzero((r > 150) & (g < 100) & (b < 100))
    if len(xs) == 0:
        return None
    return [int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1]


class VllmStandin:
    def __init__(self, model: str, max_pixels: int = CHECKPOINT_MAX_PIXELS, force_usage: bool = False) -> None:
        self.model, self.max_pixels, self.force_usage = model, max_pixels, force_usage
        self.seen_sizes: list[tuple[int, int]] = []  # (H, W) of every image as the model saw it

    def answer(self, body: dict[str, Any]) -> tuple[str, int]:
        from PIL import Image

        messages = body["messages"]
        prompt_tokens = text_tokens(messages)
        text = "I see no image."
        for m in messages:
            for part in m.get("content") if isinstance(m.get("content"), list) else []:
                if part.get("type") != "image_url":
                    continue
                url = part["image_url"]["url"]
                image = Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).convert("RGB")
                h, w = smart_resize(image.height, image.width, min_pixels=MIN_PIXELS, max_pixels=self.max_pixels)
                if (h, w) != (image.height, image.width):
                    image = image.resize((w, h), Image.Resampling.BICUBIC)
                self.seen_sizes.append((h, w))
                prompt_tokens += h * w // 784 + 2
                box = red_box(np.asarray(image))
                found = [] if box is None else [{"bbox_2d": box, "label": "red ball"}]
                text = "```json\n" + json.dumps(found) + "\n```"
        return text, prompt_tokens

    @contextmanager
    def serving(self) -> Iterator[str]:
        """Serve on 127.0.0.1:<free port>; yields the /v1 base URL."""
        server = ThreadingHTTPServer(("127.0.0.1", 0), _handler(self))
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        try:
            yield f"http://127.0.0.1:{server.server_address[1]}/v1"
        finally:
            server.shutdown()
            server.server_close()


def _handler(standin: VllmStandin) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args: Any) -> None:
            pass

        def _json(self, code: int, obj: dict[str, Any]) -> None:
            data = json.dumps(obj).encode()
            self.send_response(code)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)

        def do_GET(self) -> None:
            if self.path.rstrip("/") == "/v1/models":
                self._json(200, {"object": "list", "data": [{"id": standin.model, "object": "model"}]})
            else:
                self._json(404, {"error": {"message": "not found"}})

        def do_POST(self) -> None:
            body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
            if body.get("model") != standin.model:  # vLLM: 404 NotFoundError for another model name
                self._json(404, {"error": {"message": f"The model `{body.get('model')}` does not exist."}})
                return
            text, prompt_tokens = standin.answer(body)
            max_tokens = int(body.get("max_tokens") or 1 << 30)
            tokens = text.split(" ")[:max_tokens]  # "tokens": words, enough for counting
            text = " ".join(tokens)
            usage = {"prompt_tokens": prompt_tokens, "completion_tokens": len(tokens)}
            usage["total_tokens"] = usage["prompt_tokens"] + usage["completion_tokens"]
            base = {"id": "chatcmpl-standin", "created": int(time.time()), "model": standin.model}
            if not body.get("stream"):
                choice = {"index": 0, "message": {"role": "assistant", "content": text}, "finish_reason": "stop"}
                self._json(200, {**base, "object": "chat.completion", "choices": [choice], "usage": usage})
                return
            self.send_response(200)
            self.send_header("Content-Type", "text/event-stream")
            self.end_headers()
            include_usage = standin.force_usage or bool((body.get("stream_options") or {}).get("include_usage"))

            def send(choices: list[dict[str, Any]], extra: dict[str, Any] | None = None) -> None:
                chunk = {**base, "object": "chat.completion.chunk", "choices": choices, **(extra or {})}
                self.wfile.write(f"data: {json.dumps(chunk)}\n\n".encode())

            send([{"index": 0, "delta": {"role": "assistant", "content": ""}, "finish_reason": None}])
            for i, tok in enumerate(tokens):
                send([{"index": 0, "delta": {"content": tok if i == 0 else " " + tok}, "finish_reason": None}])
            send([{"index": 0, "delta": {}, "finish_reason": "stop"}])
            if include_usage:
                send([], {"usage": usage})
            self.wfile.write(b"data: [DONE]\n\n")

    return Handler
