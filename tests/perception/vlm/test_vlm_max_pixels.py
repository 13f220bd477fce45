"""`max_pixels=0`: the checkpoint's own processor limits (the tiny grounder's 3136..37632, 48 visual
tokens for a 640x480 frame) in both backends; an explicit value overrides; nonsense is a clear error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from testing.conftest import grounder_ckpt, grounder_server  # noqa: F401

from go2vlm.perception.vlm.backend import BackendSettings, checkpoint_pixel_limits, pixel_limits_of
from go2vlm.perception.vlm.vlm_node import VlmConfig

GROUNDER = Path(__file__).resolve().parents[2] / "data" / "tiny_grounder"


def test_limits_come_from_the_checkpoints_processor_config(tmp_path: Path) -> None:
    assert checkpoint_pixel_limits(str(GROUNDER)) == (3136, 37632)
    assert checkpoint_pixel_limits(str(tmp_path)) is None  # no config: the caller's default applies
    assert checkpoint_pixel_limits("Qwen/Qwen2.5-VL-3B-Instruct") is None  # not a local dir
    assert pixel_limits_of({"min_pixels": 3136, "max_pixels": 12845056}) == (3136, 12845056)
    assert pixel_limits_of({"size": {"shortest_edge": 10, "longest_edge": 5}}) is None


def test_the_node_accepts_zero_and_rejects_a_tiny_budget() -> None:
    VlmConfig(model="m", max_pixels=0).validate()
    VlmConfig(model="m", max_pixels=0, min_pixels=10**7).validate()  # the checkpoint's min applies then
    with pytest.raises(ValueError, match="max_pixels"):
        VlmConfig(model="m", max_pixels=100).validate()


def test_openai_backend_takes_a_local_checkpoints_limits() -> None:
    pytest.importorskip("openai")
    from go2vlm.perception.vlm.openai_backend import OpenAIBackend

    b = OpenAIBackend(BackendSettings(model=str(GROUNDER), backend="openai", max_pixels=0))
    b.load()  # creates the client only: no request
    try:
        assert (b.settings.min_pixels, b.settings.max_pixels) == (3136, 37632)
    finally:
        b.close()
    explicit = OpenAIBackend(BackendSettings(model=str(GROUNDER), backend="openai", max_pixels=100352))
    explicit.load()
    assert explicit.settings.max_pixels == 100352  # an explicit value overrides
    explicit.close()


@pytest.mark.slow
def test_transformers_backend_sees_the_grounders_48_tokens() -> None:
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    from go2vlm.perception.vlm.hf_backend import TransformersBackend

    b = TransformersBackend(BackendSettings(model=str(GROUNDER), device="cpu", max_pixels=0, max_new_tokens=8))
    b.load()
    try:
        gen = b.generate(np.zeros((480, 640, 3), np.uint8), "Locate the red ball.")
    finally:
        b.close()
    assert gen.resized_hw == (168, 224) and gen.visual_tokens == 48


@pytest.mark.slow
def test_openai_backend_notices_a_server_that_resized_the_image(grounder_server: str) -> None:  # noqa: F811
    """Through a real `transformers serve` of the grounder (its processor caps images at 37632 pixels):
    with max_pixels=0 the client sends what the server keeps, and the token counts agree; with the node's
    default (401408) the server shrinks the image again, its prompt has ~350 fewer tokens, and that is
    reported instead of boxes silently mapped from the wrong size."""
    pytest.importorskip("openai")
    from go2vlm.perception.vlm.backend import visual_token_mismatch
    from go2vlm.perception.vlm.openai_backend import OpenAIBackend

    frame = np.zeros((480, 640, 3), np.uint8)
    for max_pixels, agrees in ((0, True), (401408, False)):
        b = OpenAIBackend(BackendSettings(model=str(GROUNDER), backend="openai", base_url=grounder_server,
                                          max_pixels=max_pixels, max_new_tokens=8))  # fmt: skip
        b.load()
        try:
            gen = b.generate(frame, "Locate the blue cylinder.")
        finally:
            b.close()
        assert gen.prompt_tokens > 0 and gen.expected_prompt_tokens > 0, gen
        why = visual_token_mismatch(gen)
        assert (why is None) == agrees, (max_pixels, gen.prompt_tokens, gen.expected_prompt_tokens, why)
    assert why is not None and "max_pixels" in why
