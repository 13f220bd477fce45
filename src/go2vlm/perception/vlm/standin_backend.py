"""``standin`` backend: no model, the timing of one. It answers like a launch-bound eager decode does.

On a GPU, eager decode of Qwen2.5-VL is bound by kernel launches, not by the GPU: every new token
is a Python loop over the layers that launches a few hundred kernels, and the interpreter is held
for most of that time. Other threads of the same process (the bus's callbacks, the sim's physics and
rendering, ...) then compete with it for the interpreter, and every token takes longer. This
backend reproduces exactly that without a GPU: a prefill of ``prefill_ms`` and ``tokens`` tokens at
``tok_s``, each token a fixed amount of pure-Python work (calibrated in ``load()`` on this machine's
CPU time, so that it takes 1/``tok_s`` s when nothing else wants the interpreter).

The defaults are the real 3B's in bf16 on an H100 (docs/vlm.md's table, from issue 33's
measurement): 39.3 tokens/s, 32 new tokens, an 80 ms prefill, about 0.89 s a frame. ``model`` may
override them: ``model=tok_s=50.9,tokens=32,prefill_ms=76`` (the 7B). The answer is an empty
grounding (``[]``): no boxes, only time.
"""

from __future__ import annotations

import time

import numpy as np

from go2vlm.geometry.qwen import CoordSystem, smart_resize
from go2vlm.perception.vlm.backend import BackendError, BackendSettings, Generation

__all__ = ["StandinBackend", "StandinSpec", "parse_spec"]

DEFAULTS = {"tok_s": 39.3, "tokens": 32.0, "prefill_ms": 80.0}


class StandinSpec:
    def __init__(self, tok_s: float, tokens: int, prefill_ms: float) -> None:
        if tok_s <= 0 or tokens < 0 or prefill_ms < 0:
            raise BackendError(
                f"standin: tok_s > 0, tokens >= 0, prefill_ms >= 0 (got {tok_s}, {tokens}, {prefill_ms})"
            )
        self.tok_s, self.tokens, self.prefill_ms = tok_s, tokens, prefill_ms

    @property
    def frame_ms(self) -> float:
        return self.prefill_ms + self.tokens * 1e3 / self.tok_s


def parse_spec(model: str) -> StandinSpec:
    """`tok_s=..,tokens=..,prefill_ms=..` (any subset; anything without '=' is a free name)."""
    values = dict(DEFAULTS)
    for part in model.split(","):
        key, eq, value = part.strip().partition("=")
        if not eq:
            continue
        if key not in values:
            raise BackendError(f"standin model {model!r}: unknown key {key!r} (use {', '.join(DEFAULTS)})")
        try:
            values[key] = float(value)
        except ValueError as exc:
            raise BackendError(f"standin model {model!r}: {key}={value!r} is not a number") from exc
    return StandinSpec(values["tok_s"], int(values["tokens"]), values["prefill_ms"])


def _work(n: int) -> int:
    """n units of pure-Python work: the interpreter is held throughout (a decode step's launches)."""
    acc = 0
    for i in range(n):
        acc = (acc + i * i) % 1000003
    return acc


class StandinBackend:
    name = "standin"

    def __init__(self, settings: BackendSettings) -> None:
        self.settings = settings
        self.spec = parse_spec(settings.model)
        self.units_per_ms = 0.0
        self.description = (
            f"standin ({self.spec.tok_s:g} tok/s, {self.spec.tokens} tokens, prefill {self.spec.prefill_ms:g} ms)"
        )
        self.load_report: dict[str, float] = {}

    def load(self) -> None:
        """Calibrate: pure-Python work per millisecond of this thread's CPU time (the best of a few
        runs, so that another process's load on the machine does not shrink a token's work)."""
        n = 20000
        best = float("inf")
        for _ in range(7):
            t0 = time.thread_time()
            _work(n)
            best = min(best, time.thread_time() - t0)
        self.units_per_ms = n / max(best * 1e3, 1e-6)
        self.load_report = {"load_s": 0.0, "units_per_ms": round(self.units_per_ms, 1)}

    def generate(self, rgb: np.ndarray, prompt: str) -> Generation:
        if self.units_per_ms <= 0:
            raise BackendError("model not loaded")
        s, spec = self.settings, self.spec
        t0 = time.perf_counter()
        h, w = int(rgb.shape[0]), int(rgb.shape[1])
        rh, rw = smart_resize(h, w, min_pixels=s.min_pixels, max_pixels=s.max_pixels)
        t1 = time.perf_counter()
        _work(int(spec.prefill_ms * self.units_per_ms))
        t2 = time.perf_counter()
        per_token = int(1e3 / spec.tok_s * self.units_per_ms)
        for _ in range(spec.tokens):
            _work(per_token)
        t3 = time.perf_counter()
        return Generation(
            text="[]",
            original_hw=(h, w),
            resized_hw=(rh, rw),
            coords=CoordSystem.RESIZED_PIXELS,
            visual_tokens=rh * rw // 784,
            new_tokens=spec.tokens,
            timings_ms={
                "preprocess": (t1 - t0) * 1e3,
                "prefill": (t2 - t1) * 1e3,
                "decode": (t3 - t2) * 1e3,
                "total": (t3 - t0) * 1e3,
            },
        )

    def close(self) -> None:
        self.units_per_ms = 0.0
