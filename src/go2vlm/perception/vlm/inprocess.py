"""The backend a name stands for, built in this process; each imports its heavy dependencies
(torch, openai) only when it is chosen. The node gets its backend from :mod:`.factory`, which may put
it in a process of its own; that process builds it here."""

from __future__ import annotations

from go2vlm.perception.vlm.backend import Backend, BackendSettings

__all__ = ["BACKENDS", "make_in_process"]

BACKENDS = ("transformers", "openai", "standin")


def make_in_process(settings: BackendSettings) -> Backend:
    """The backend named by ``settings.backend``, in this process."""
    if settings.backend == "transformers":
        from go2vlm.perception.vlm.hf_backend import TransformersBackend

        return TransformersBackend(settings)
    if settings.backend == "standin":
        from go2vlm.perception.vlm.standin_backend import StandinBackend

        return StandinBackend(settings)
    if settings.backend == "openai":
        from go2vlm.perception.vlm.openai_backend import OpenAIBackend

        return OpenAIBackend(settings)
    raise ValueError(f"unknown backend {settings.backend!r}; use {', '.join(BACKENDS)}")
