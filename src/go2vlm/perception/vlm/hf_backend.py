"""``transformers`` backend: Qwen2.5-VL (and Qwen2-VL / Qwen3-VL) in this process.

Loads a local directory or hub id with ``AutoProcessor`` and
``Qwen2_5_VLForConditionalGeneration`` (``AutoModelForImageTextToText`` for the other
Qwen-VL families), picks dtype/device, optionally quantizes with bitsandbytes (nf4
with double quantization as in the VLM article, or int8), and reports where the
time went: preprocess, prefill (to the first token), decode.

Compiled decode (``compile``): eager decode is bound by kernel launches, not by the GPU (the 7B, 28
layers, decodes faster than the 3B, 36 layers; docs/vlm.md). With ``compile=on`` generation uses a
static KV cache and transformers' compiled forward for the decode steps; prefill stays eager. The
cache has one fixed length for every frame (the most visual tokens ``max_pixels`` allows, a text
budget and ``max_new_tokens``), so every frame's decode has the same shapes and nothing recompiles
after the warm-up, which ``load()`` runs on a frame of the largest size (its time is in
``load_report``). ``auto`` compiles on CUDA in bf16/fp16 without bitsandbytes (on nf4 the compiled
path measured slower than eager) and never on the CPU.
"""

from __future__ import annotations

import importlib.util
import os
import re
import time
from typing import Any

import numpy as np

from go2vlm.errors import ConfigError
from go2vlm.geometry.qwen import DEFAULT_MAX_PIXELS, DEFAULT_MIN_PIXELS, CoordSystem, coord_system_for
from go2vlm.perception.vlm.backend import BackendError, BackendSettings, Generation, VlmOutOfMemory, pixel_limits_of

__all__ = [
    "TransformersBackend",
    "check_model_ref",
    "configure_cuda_allocator",
    "resolve_compile",
    "resolve_device",
    "resolve_dtype",
]

_DTYPES = {"fp16": "float16", "float16": "float16", "bf16": "bfloat16", "bfloat16": "bfloat16", "fp32": "float32"}


def configure_cuda_allocator() -> None:
    """Expandable segments before the first CUDA allocation: less fragmentation, fewer OOMs
    when image sizes (and so activation shapes) change from frame to frame. Respects a user's
    own setting (either spelling)."""
    if "PYTORCH_CUDA_ALLOC_CONF" not in os.environ and "PYTORCH_ALLOC_CONF" not in os.environ:
        os.environ["PYTORCH_CUDA_ALLOC_CONF"] = "expandable_segments:True"


def resolve_device(device: str) -> str:
    import torch

    if device in ("", "auto"):
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise BackendError(f"device={device!r} but torch sees no CUDA GPU (torch {torch.__version__})")
    return device


def resolve_dtype(dtype: str, device: str) -> Any:
    """auto: bf16 on GPUs that have it, else fp16 on GPU; fp32 on CPU (fp16 matmuls are slow there)."""
    import torch

    if dtype in ("", "auto"):
        if device.startswith("cuda"):
            return torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float16
        return torch.float32
    name = _DTYPES.get(dtype)
    if name is None:
        raise BackendError(f"dtype={dtype!r}: use auto, fp16, bf16 or fp32")
    return getattr(torch, name)


def resolve_compile(mode: str, device: str, dtype: str, quantization: str) -> bool:
    """Whether to decode with the static cache and the compiled forward. `dtype` is the resolved one
    ("float16", "bfloat16", "float32"). auto: CUDA in bf16/fp16 without bitsandbytes."""
    if mode == "off":
        return False
    if mode == "on":
        return True
    if mode not in ("", "auto"):
        raise BackendError(f"compile={mode!r}: use auto, on or off")
    quantized = quantization not in ("", "none")
    return device.startswith("cuda") and dtype in ("float16", "bfloat16") and not quantized


# Text tokens the static cache keeps room for beside the image: the chat template and the longest
# prompt (the detect prompt with a query is ~150 tokens). A longer prompt still works: transformers
# then sizes a larger cache, which costs one recompile.
TEXT_BUDGET_TOKENS = 512
CACHE_ROUND = 256  # cache lengths in steps of this: a setting change rarely changes the shapes


def static_cache_len(max_pixels: int, patch: int, merge: int, max_new_tokens: int) -> int:
    """One KV-cache length for every frame: the most visual tokens `max_pixels` allows, the text
    budget and the generation budget, rounded up."""
    unit = patch * merge  # the resize works in units of 28 px: a side is never under one
    # A thin frame whose short side the resize would floor to 0 units keeps one unit, and its long
    # side (at most 200x the short, Qwen's limit) may then take it past max_pixels: at most 200 tokens.
    visual = max(max_pixels // (unit * unit), 200) + 2  # + vision start/end
    need = visual + TEXT_BUDGET_TOKENS + max_new_tokens
    return -(-need // CACHE_ROUND) * CACHE_ROUND


def _quantization_config(quantization: str, device: str, dtype: Any) -> Any:
    import torch

    if quantization in ("", "none"):
        return None
    if quantization not in ("nf4", "int8"):
        raise BackendError(f"quantization={quantization!r}: use none, nf4 or int8")
    if not device.startswith("cuda"):
        raise BackendError(f"quantization={quantization} needs a CUDA GPU (bitsandbytes); device is {device!r}")
    if importlib.util.find_spec("bitsandbytes") is None:
        raise BackendError(f"quantization={quantization} needs bitsandbytes: pip install bitsandbytes")
    from transformers import BitsAndBytesConfig

    if quantization == "int8":
        return BitsAndBytesConfig(load_in_8bit=True)
    # The VLM article's settings: 4-bit NF4 weights, double quantization of the scales, fp16 compute
    # (bf16 where the dtype says so; fp32 compute would throw away the speed).
    compute = dtype if dtype in (torch.float16, torch.bfloat16) else torch.float16
    return BitsAndBytesConfig(
        load_in_4bit=True,
        bnb_4bit_quant_type="nf4",
        bnb_4bit_use_double_quant=True,
        bnb_4bit_compute_dtype=compute,
    )


def _is_oom(exc: BaseException) -> bool:
    import torch

    oom_type = getattr(torch, "OutOfMemoryError", None) or getattr(torch.cuda, "OutOfMemoryError", None)
    if oom_type is not None and isinstance(exc, oom_type):
        return True
    return isinstance(exc, RuntimeError) and "out of memory" in str(exc).lower()


def oom_error(settings: BackendSettings, exc: BaseException, where: str) -> VlmOutOfMemory:
    hints = []
    if settings.quantization in ("", "none"):
        hints.append("load 4-bit with quantization=nf4 (about 1/3 of the fp16 weight memory)")
    hints.append(f"lower max_pixels (now {settings.max_pixels}; visual tokens = max_pixels/784)")
    hints.append("lower max_new_tokens, or free the GPU (a simulator renderer shares it)")
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return VlmOutOfMemory(f"CUDA out of memory during {where}: {first}. Try: " + "; ".join(hints))


class _FirstTokenClock:
    """A logits processor that only notes when it is first called: that is the end of prefill."""

    def __init__(self, sync: Any) -> None:
        self.sync = sync
        self.first: float | None = None

    def __call__(self, input_ids: Any, scores: Any) -> Any:
        if self.first is None:
            self.sync()
            self.first = time.perf_counter()  # wall time: time to the first token
        return scores


# A Hugging Face hub id: `name` or `org/name` of letters, digits, '-', '_' and '.' (no '--' or '..').
_HUB_ID = re.compile(r"^(?!.*(--|\.\.))[A-Za-z0-9][\w.-]*(/[A-Za-z0-9][\w.-]*)?$")


def check_model_ref(model: str) -> None:
    """A `model` that can never load is a configuration error now, not a node without a model:
    it must be an existing checkpoint directory or have the form of a hub id."""
    if not model:
        raise ConfigError("parameter model is empty: give a local checkpoint directory or a hub id")
    path = os.path.expanduser(model)
    if os.path.isdir(path):
        return
    if os.path.exists(path):
        raise ConfigError(f"model {model!r} is a file; give the checkpoint directory")
    if model.startswith(("/", ".", "~")) or not _HUB_ID.match(model):
        raise ConfigError(f"model {model!r}: no such directory, and not a hub id")


class TransformersBackend:
    name = "transformers"

    def __init__(self, settings: BackendSettings) -> None:
        check_model_ref(settings.model)
        self.settings = settings
        self.model: Any = None
        self.processor: Any = None
        self.device = ""
        self.dtype: Any = None
        self.model_type = ""
        self.coords = CoordSystem.RESIZED_PIXELS
        self.description = f"transformers:{settings.model}"
        self.compiled = False
        self.cache_len = 0  # the static KV cache's length (compiled decode)
        self.load_report: dict[str, float] = {}  # load_s, compile_warmup_s

    def load(self) -> None:
        t_load = time.perf_counter()
        self._load()
        self.load_report = {"load_s": round(time.perf_counter() - t_load, 2)}
        if self.compiled:
            t_warm = time.perf_counter()
            self._warm_up()
            self.load_report["compile_warmup_s"] = round(time.perf_counter() - t_warm, 2)

    def _load(self) -> None:
        configure_cuda_allocator()
        import torch
        from transformers import AutoConfig, AutoProcessor

        s = self.settings
        if not s.model:
            raise BackendError("parameter model is empty: give a local checkpoint directory or a hub id")
        self.device = resolve_device(s.device)
        self.dtype = resolve_dtype(s.dtype, self.device)
        quant = _quantization_config(s.quantization, self.device, self.dtype)
        try:
            config = AutoConfig.from_pretrained(s.model)
        except (OSError, ValueError) as exc:
            raise BackendError(f"cannot read a model config from {s.model!r}: {exc}") from exc
        self.model_type = str(getattr(config, "model_type", ""))
        self.coords = CoordSystem(s.coords) if s.coords not in ("", "auto") else coord_system_for(self.model_type)
        model_cls: type[Any]
        if self.model_type == "qwen2_5_vl":
            from transformers import Qwen2_5_VLForConditionalGeneration as model_cls
        else:
            from transformers import AutoModelForImageTextToText as model_cls
        kwargs: dict[str, Any] = {"dtype": self.dtype}
        if quant is not None:
            kwargs["quantization_config"] = quant
        if self.device.startswith("cuda"):
            kwargs["device_map"] = {"": self.device}
        try:
            self.processor = AutoProcessor.from_pretrained(s.model)
            if s.max_pixels == 0:  # the checkpoint's own limits (a hub id's too: its processor is loaded)
                limits = pixel_limits_of(self.processor.image_processor)
                s.min_pixels, s.max_pixels = limits or (DEFAULT_MIN_PIXELS, DEFAULT_MAX_PIXELS)
            self.model = model_cls.from_pretrained(s.model, **kwargs)
        except Exception as exc:
            if _is_oom(exc):
                self._free()
                raise oom_error(s, exc, "model loading") from exc
            raise
        if not self.device.startswith("cuda"):
            self.model.to(self.device)
        self.model.eval()
        dtype_name = str(self.dtype).replace("torch.", "")
        self.compiled = resolve_compile(s.compile, self.device, dtype_name, s.quantization)
        if self.compiled:
            patch, merge = self._patch_merge()
            self.cache_len = static_cache_len(s.max_pixels, patch, merge, s.max_new_tokens)
        q = "" if s.quantization in ("", "none") else f", {s.quantization}"
        c = f", compiled decode, cache {self.cache_len}" if self.compiled else ""
        self.description = f"transformers:{s.model} ({self.model_type}, {self.device}, {dtype_name}{q}{c})"
        if self.device.startswith("cuda"):
            torch.cuda.reset_peak_memory_stats()

    def _patch_merge(self) -> tuple[int, int]:
        # patch 14 (Qwen2/2.5-VL) or 16 (Qwen3-VL): read it, do not assume it
        ip = self.processor.image_processor
        return int(getattr(ip, "patch_size", 14)), int(getattr(ip, "merge_size", 2))

    def _compile_kwargs(self) -> dict[str, object]:
        """generate()'s arguments for the compiled decode: a static cache of one length for every frame."""
        if not self.compiled:
            return {}
        from transformers import CompileConfig, GenerationConfig

        if self.device.startswith("cuda"):
            config = CompileConfig()  # transformers' default: inductor, reduce-overhead (CUDA graphs)
        else:
            config = CompileConfig(mode="default")  # no CUDA graphs on the CPU
            # transformers compiles only on accelerators unless told (a private flag, typed None there)
            config._compile_all_devices = True  # type: ignore[assignment]
        kwargs: dict[str, object] = {"cache_implementation": "static", "compile_config": config}
        # Newer transformers take the cache's length (max_cache_len); older ones grow the static cache (the
        # largest of the calls so far), so the warm-up's largest frame fixes the length all the same.
        if hasattr(GenerationConfig(), "max_cache_len"):
            kwargs["max_cache_len"] = self.cache_len
        return kwargs

    def _warm_up(self) -> None:
        """Compile before the first frame: two generations on a frame of the largest size (the second
        one runs the compiled graphs once more, as every later frame will)."""
        from go2vlm.geometry.qwen import smart_resize
        from go2vlm.perception.vlm.prompts import detect_prompt

        s = self.settings
        side = int(s.max_pixels**0.5)
        patch, merge = self._patch_merge()
        h, w = smart_resize(side, side, factor=patch * merge, min_pixels=s.min_pixels, max_pixels=s.max_pixels)
        frame = np.full((h, w, 3), 128, np.uint8)
        for _ in range(2):
            self.generate(frame, detect_prompt(()), new_tokens=min(8, s.max_new_tokens))

    def _free(self) -> None:
        import gc

        import torch

        gc.collect()
        if torch.cuda.is_available():
            torch.cuda.empty_cache()

    def _sync(self) -> None:
        if self.device.startswith("cuda"):
            import torch

            torch.cuda.synchronize()

    def generate(self, rgb: np.ndarray, prompt: str, new_tokens: int = 0) -> Generation:
        """One answer; `new_tokens` > 0 generates exactly that many (the warm-up)."""
        if self.model is None:
            raise BackendError("model not loaded")
        import torch
        from PIL import Image
        from transformers import LogitsProcessorList

        s = self.settings
        t0 = time.perf_counter()  # wall time here and below: compute latencies, not node time
        image = Image.fromarray(np.ascontiguousarray(rgb))
        messages = [{"role": "user", "content": [{"type": "image"}, {"type": "text", "text": prompt}]}]
        text = self.processor.apply_chat_template(messages, tokenize=False, add_generation_prompt=True)
        inputs = self.processor(
            text=[text],
            images=[image],
            return_tensors="pt",
            size={"shortest_edge": s.min_pixels, "longest_edge": s.max_pixels},
        )
        grid = inputs["image_grid_thw"][0].tolist()  # (t, H'/patch, W'/patch)
        patch, merge = self._patch_merge()
        resized_hw = (int(grid[1]) * patch, int(grid[2]) * patch)
        n_visual = int(grid[0]) * int(grid[1]) * int(grid[2]) // (merge * merge)
        inputs = inputs.to(self.model.device)
        prompt_len = int(inputs["input_ids"].shape[1])
        self._sync()
        t1 = time.perf_counter()
        clock = _FirstTokenClock(self._sync)
        try:
            with torch.inference_mode():
                out = self.model.generate(
                    **inputs,
                    max_new_tokens=new_tokens or s.max_new_tokens,
                    min_new_tokens=new_tokens or min(s.min_new_tokens, s.max_new_tokens) or None,
                    do_sample=False,
                    logits_processor=LogitsProcessorList([clock]),
                    **self._compile_kwargs(),
                )
            self._sync()
        except Exception as exc:
            if _is_oom(exc):
                del inputs
                self._free()
                raise oom_error(s, exc, "generation") from exc
            raise
        t2 = time.perf_counter()
        new_ids = out[0, prompt_len:]
        answer = self.processor.tokenizer.decode(new_ids, skip_special_tokens=True)
        t3 = time.perf_counter()
        first = clock.first if clock.first is not None else t2
        return Generation(
            text=answer,
            original_hw=(int(rgb.shape[0]), int(rgb.shape[1])),
            resized_hw=resized_hw,
            coords=self.coords,
            visual_tokens=n_visual,
            prompt_tokens=prompt_len,
            new_tokens=int(new_ids.shape[0]),
            timings_ms={
                "preprocess": (t1 - t0) * 1e3,
                "prefill": (first - t1) * 1e3,
                "decode": (t2 - first) * 1e3,
                "detokenize": (t3 - t2) * 1e3,
                "total": (t3 - t0) * 1e3,
            },
        )

    def close(self) -> None:
        self.model = None
        self.processor = None
        self._free()
