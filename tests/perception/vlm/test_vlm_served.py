"""The openai backend against a server that answers as vLLM serving Qwen2.5-VL does (vllm_standin.py):
boxes in absolute pixels of the image after the server's own resize. The backend sends the frame
already resized, so they map back onto the camera's pixels exactly; a server resizing further (a
smaller max_pixels than the node's) is caught by the token count where the server reports usage."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from vllm_standin import VllmStandin

from go2vlm.geometry.qwen import CoordSystem, smart_resize
from go2vlm.perception.vlm.backend import BackendSettings, visual_token_mismatch
from go2vlm.perception.vlm.factory import make_backend
from go2vlm.vocabulary.answers import finalize_boxes, parse_grounding

pytest.importorskip("openai")

MODEL = "Qwen/Qwen2.5-VL-3B-Instruct"
RED = (400, 300, 560, 420)  # x1, y1, x2, y2 in the camera's pixels


def frame(h: int = 720, w: int = 1280) -> np.ndarray:
    img = np.full((h, w, 3), 30, np.uint8)
    x1, y1, x2, y2 = RED
    img[y1:y2, x1:x2] = (230, 20, 20)
    return img


def ask(url: str, max_pixels: int) -> tuple[list[tuple[float, ...]], str | None, tuple[int, int]]:
    b = make_backend(BackendSettings(model=MODEL, backend="openai", base_url=url, max_pixels=max_pixels, retries=0))
    b.load()
    try:
        gen = b.generate(frame(), "Locate the red ball; answer Qwen grounding JSON.")
    finally:
        b.close()
    assert gen.coords is CoordSystem.RESIZED_PIXELS  # Qwen2.5-VL: absolute pixels of the resized image
    boxes = finalize_boxes(
        parse_grounding(gen.text).boxes,
        coords=gen.coords,
        resized_hw=gen.resized_hw,
        original_hw=gen.original_hw,
        counters=Counter(),
    )
    return [tuple(b.box) for b in boxes], visual_token_mismatch(gen), gen.resized_hw


@pytest.mark.parametrize("node_max_pixels", [401408, 200704, 1003520])
def test_boxes_map_back_to_camera_pixels_through_vllm(node_max_pixels: int) -> None:
    server = VllmStandin(MODEL)  # vLLM's default: the checkpoint's max_pixels (12845056), larger than ours
    with server.serving() as url:
        boxes, mismatch, sent = ask(url, node_max_pixels)
    assert sent == smart_resize(720, 1280, max_pixels=node_max_pixels)
    assert server.seen_sizes == [sent]  # the server's resize left our already resized frame alone
    assert mismatch is None
    (box,) = boxes
    scale = 1280 / sent[1]
    assert box == pytest.approx(RED, abs=2 * scale + 1)  # a resized pixel or two: bicubic edges, JPEG


def test_a_server_with_a_smaller_max_pixels_is_caught_by_its_token_count() -> None:
    # vllm serve ... --mm-processor-kwargs '{"max_pixels": 200704}' --enable-force-include-usage
    server = VllmStandin(MODEL, max_pixels=200704, force_usage=True)
    with server.serving() as url:
        boxes, mismatch, sent = ask(url, 401408)  # the node sends 840x476; the server shrinks it again
        assert server.seen_sizes[-1] != sent
        assert mismatch is not None and "max_pixels" in mismatch
        (box,) = boxes
        assert box != pytest.approx(RED, abs=10)  # mapped from the wrong size: why the check exists
        boxes, mismatch, _ = ask(url, 200704)  # the node's max_pixels set to the server's: right again
    assert mismatch is None
    assert boxes[0] == pytest.approx(RED, abs=2 * 1280 / 588 + 1)
