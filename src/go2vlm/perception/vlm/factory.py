"""The backend a node asks for by name; each imports its heavy dependencies (torch, openai) only
when it is chosen."""

from __future__ import annotations

from go2vlm.perception.vlm.backend import Backend, BackendSettings

__all__ = ["make_backend"]


def make_backend(settings: BackendSettings) -> Backend:
    """The backend named by ``settings.backend`` (imports its heavy dependencies lazily)."""
    if settings.backend == "transformers":
        from go2vlm.perception.vlm.hf_backend import TransformersBackend

        return TransformersBackend(settings)
    if settings.backend == "openai":
        from go2vlm.perception.vlm.openai_backend import OpenAIBackend

        return OpenAIBackend(settings)
    raise ValueError(f"unknown backend {settings.backend!r}; use 'transformers' or 'openai'")
