"""The backend a node asks for by name. A model that computes in the interpreter (transformers,
standin) runs in a process of its own unless `process=off` (:mod:`.process_backend`); the others,
and every backend inside that process, are built in the process that asks (:mod:`.inprocess`)."""

from __future__ import annotations

from go2vlm.perception.vlm.backend import Backend, BackendSettings
from go2vlm.perception.vlm.inprocess import BACKENDS, make_in_process

__all__ = ["BACKENDS", "make_backend"]


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
    return make_in_process(settings)
