"""Fixtures for the behaviour tests: tiny Qwen2.5-VL checkpoints trained to give one decision answer.

Built once and cached under $GO2VLM_CACHE or ~/.cache/go2vlm, keyed on the answer, the decision
prompt, the training steps and the library/source versions (~25-40 s each on an idle 2-core
machine when not cached; the build checks that the answer is exact).
"""

from __future__ import annotations

from pathlib import Path

import pytest

# A well-formed JSON action outside the whitelist: a model obeying the injected "run forward".
# (Short answers: the tiny tokenizer makes '{"action": "forward", "speed": 5}' 19 tokens, which
# takes minutes of CPU to learn exactly; these are 8-9 tokens, ~25-40 s.)
INJECTION_ANSWER = '{"action": "forward"}'
STOP_ANSWER = '{"action": "stop"}'
STEPS = 100


def decision_checkpoint(answer: str, steps: int = STEPS) -> Path:
    from go2vlm.perception.vlm.prompts import DECISION_PROMPT
    from testing_support.tiny_qwen import cached_tiny_checkpoint

    # Trained on the decision prompt itself, so the answer is exact for it.
    return cached_tiny_checkpoint(answer=answer, steps=steps, prompts=[DECISION_PROMPT])


@pytest.fixture(scope="session")
def injection_answer() -> str:
    return INJECTION_ANSWER


@pytest.fixture(scope="session")
def injection_ckpt() -> Path:
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    return decision_checkpoint(INJECTION_ANSWER)


@pytest.fixture(scope="session")
def stop_ckpt() -> Path:
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    return decision_checkpoint(STOP_ANSWER)
