"""Compiled decode (hf_backend `compile`): when it is on, that its static cache has one length for
every frame, and that it gives eager decode's greedy tokens, token for token, without a recompile
after the warm-up in load()."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from go2vlm.geometry.qwen import smart_resize
from go2vlm.perception.vlm.backend import BackendError, BackendSettings
from go2vlm.perception.vlm.hf_backend import TEXT_BUDGET_TOKENS, resolve_compile, static_cache_len


@pytest.mark.parametrize(
    ("mode", "device", "dtype", "quant", "want"),
    [
        ("auto", "cuda", "bfloat16", "none", True),
        ("auto", "cuda:1", "float16", "none", True),
        ("auto", "cuda", "float32", "none", False),
        ("auto", "cuda", "bfloat16", "nf4", False),  # measured slower than eager on nf4
        ("auto", "cuda", "float16", "int8", False),
        ("auto", "cpu", "float32", "none", False),
        ("on", "cpu", "float32", "none", True),  # forced: the CPU test below
        ("off", "cuda", "bfloat16", "none", False),
    ],
)
def test_auto_compiles_cuda_half_precision_without_bitsandbytes(
    mode: str, device: str, dtype: str, quant: str, want: bool
) -> None:
    assert resolve_compile(mode, device, dtype, quant) is want


def test_unknown_compile_mode_is_an_error() -> None:
    with pytest.raises(BackendError, match="compile"):
        resolve_compile("maybe", "cuda", "bfloat16", "none")


@given(
    h=st.integers(56, 4000),
    w=st.integers(56, 4000),
    max_pixels=st.integers(3136, 2_000_000),
    new=st.integers(1, 1024),
)
def test_one_cache_length_holds_any_frame(h: int, w: int, max_pixels: int, new: int) -> None:
    """Whatever the camera's size, its visual tokens, a prompt within the text budget and the
    generation budget fit the one cache length: no frame changes the decode's shapes. (Frames under
    56 px a side are upscaled to min_pixels and may exceed max_pixels; no camera sends them, and one
    would cost a recompile, not an error.)"""
    min_pixels = 3136
    try:
        rh, rw = smart_resize(h, w, min_pixels=min_pixels, max_pixels=max_pixels)
    except ValueError:
        return  # an aspect ratio Qwen refuses: never reaches generate
    visual = rh * rw // 784
    n = static_cache_len(max_pixels, 14, 2, new)
    assert visual + 2 + TEXT_BUDGET_TOKENS + new <= n
    assert n % 256 == 0


@pytest.mark.slow  # torch.compile's inductor builds C++ kernels on the CPU: 1-2 minutes
def test_compiled_decode_gives_eager_tokens_without_recompiling() -> None:
    pytest.importorskip("transformers")
    import torch._dynamo
    from torch._dynamo.utils import counters

    from go2vlm.perception.vlm.hf_backend import TransformersBackend
    from go2vlm.perception.vlm.prompts import detect_prompt
    from testing_support.tiny_qwen import TINY_MAX_PIXELS, TINY_MIN_PIXELS, cached_tiny_checkpoint

    # Random weights: an answer that depends on the image and the prompt (a trained tiny model
    # always says the same), so matching tokens mean matching logits.
    ckpt: Path = cached_tiny_checkpoint(answer=None, steps=0)
    torch._dynamo.reset()

    def backend(compile: str) -> TransformersBackend:
        s = BackendSettings(
            model=str(ckpt),
            device="cpu",
            compile=compile,
            max_pixels=TINY_MAX_PIXELS,
            min_pixels=TINY_MIN_PIXELS,
            max_new_tokens=16,
            min_new_tokens=16,
        )
        b = TransformersBackend(s)
        b.load()
        return b

    eager, compiled = backend("off"), backend("on")
    assert not eager.compiled and "compile_warmup_s" not in eager.load_report
    assert compiled.compiled and compiled.load_report["compile_warmup_s"] > 0
    graphs_after_warmup = counters["stats"]["unique_graphs"]
    assert graphs_after_warmup > 0

    rng = np.random.default_rng(3)
    cases = [((112, 112), "red ball"), ((60, 140), "blue cylinder"), ((97, 83), "the green box on the left")]
    for (h, w), label in cases:
        frame = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        want = eager.generate(frame, detect_prompt([label]))
        got = compiled.generate(frame, detect_prompt([label]))
        assert got.new_tokens == want.new_tokens == 16
        assert got.text == want.text, (h, w, label)
    # Other image sizes and prompts: the same compiled graphs (fixed shapes), no recompile per frame.
    assert counters["stats"]["unique_graphs"] == graphs_after_warmup
    eager.close()
    compiled.close()
