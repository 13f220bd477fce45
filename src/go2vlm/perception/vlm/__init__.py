"""VLM perception: Qwen2.5-VL looks at camera frames; answers and grounded boxes go on the bus.

Light to import: torch/transformers/openai load only when a backend is created.

* :mod:`.vlm_node` -- the ``vlm`` node (``go2vlm run vlm --param model=DIR``)
* :mod:`.backend`, :mod:`.factory`, :mod:`.hf_backend`, :mod:`.openai_backend` -- in-process or
  OpenAI-compatible server; :mod:`.process_backend` -- the model in a process of its own;
  :mod:`.standin_backend` -- no model, a launch-bound decode's timing
* ``go2vlm.vocabulary.answers`` -- untrusted model output -> boxes, with counters (one path for every reader)
* ``go2vlm.geometry.qwen`` -- Qwen smart resize, coordinate conventions
"""

from go2vlm.geometry.qwen import CoordSystem, smart_resize, visual_tokens
from go2vlm.perception.vlm.prompts import DEFAULT_PROMPT, build_prompt, detect_prompt
from go2vlm.vocabulary.answers import Box, ParseResult, finalize_boxes, parse_grounding

__all__ = [
    "DEFAULT_PROMPT",
    "Box",
    "CoordSystem",
    "ParseResult",
    "build_prompt",
    "detect_prompt",
    "finalize_boxes",
    "parse_grounding",
    "smart_resize",
    "visual_tokens",
]
