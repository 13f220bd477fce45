"""The backend a node asks for by name; each imports its heavy dependencies (torch, openai) only
when it is chosen. A model that computes in the interpreter (transformers, standin) runs in a process
of its own unless `process=off` (process_backend.py)."""

from __future__ import annotations

from go2vlm.perception.vlm.backend import Backend, BackendSettings

__all__ = ["BACKENDS", "make_backend"]

BACKENDS = ("transformers", "openai", "standin")


def make_backend(settings: BackendSettings) -> Backend:
    """The backend named by ``settings.backend`` (imports its heavy dependencies lazily)."""
    if settings.backend not in BACKENDS:
        raise ValueError(f"unknown backend {settings.backend!r}; use {', '.join(BACKENDS)}")
    from go2vlm.perception.vlm.process_backend import InferenceProcess, wants_process

    if wants_process(settings):
        if settings.backend == "transformers":  # a model that can never load fails here, not in the child
            from go2vlm.perception.vlm.hf_backend import check_model_ref

            check_model_ref(settings.model)
        return InferenceProcess(settings)
    if settings.backend == "transformers":
        from go2vlm.perception.vlm.hf_backend import TransformersBackend

        return TransformersBackend(settings)
    if settings.backend == "standin":
        from go2vlm.perception.vlm.standin_backend import StandinBackend

        return StandinBackend(settings)
    from go2vlm.perception.vlm.openai_backend import OpenAIBackend

    return OpenAIBackend(settings)
