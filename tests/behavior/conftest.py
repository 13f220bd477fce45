"""Fixtures for the behaviour tests: tiny Qwen2.5-VL checkpoints trained to give one decision answer.

Built once and cached under $GO2VLM_CACHE or ~/.cache/go2vlm, keyed on the answer, the decision
prompt, the training steps and the library/source versions (~25-40 s each on an idle 2-core
machine when not cached; the build checks that the answer is exact).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import pytest

# A well-formed JSON action outside the whitelist: a model obeying the injected "run forward".
# (Short answers: the tiny tokenizer makes '{"action": "forward", "speed": 5}' 19 tokens, which
# takes minutes of CPU to learn exactly; these are 8-9 tokens, ~25-40 s.)
INJECTION_ANSWER = '{"action": "forward"}'
STOP_ANSWER = '{"action": "stop"}'
STEPS = 100


def decision_checkpoint(answer: str, steps: int = STEPS) -> Path:
    import tokenizers
    import torch
    import transformers

    from go2vlm.behavior.decisions import DECISION_PROMPT
    from go2vlm.perception.vlm import tiny

    root = Path(os.environ.get("GO2VLM_CACHE") or Path.home() / ".cache" / "go2vlm")
    key = hashlib.sha256(
        json.dumps(
            {
                "answer": answer,
                "prompt": DECISION_PROMPT,
                "steps": steps,
                "versions": [transformers.__version__, tokenizers.__version__, torch.__version__],
                "tiny": hashlib.sha256(Path(tiny.__file__).read_bytes()).hexdigest(),
            },
            sort_keys=True,
        ).encode()
    ).hexdigest()[:16]
    final = root / f"decision-{key}"
    if (final / "go2vlm_tiny.json").is_file():
        return final
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f"decision-{key}.", dir=root))
    try:
        tiny.save_untrained_checkpoint(tmp, seed=0)
        # Trained on the decision prompt itself, so the answer is exact for it.
        tiny.train_fixed_output(tmp, answer, steps, seed=0, prompts=[DECISION_PROMPT])
        (tmp / "go2vlm_tiny.json").write_text(json.dumps({"answer": answer, "steps": steps}))
        try:
            tmp.rename(final)
        except OSError:
            if not (final / "go2vlm_tiny.json").is_file():
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return final


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
