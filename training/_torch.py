"""Lazy torch import with a clear message when the ``train`` extra is missing."""

from __future__ import annotations

from engine.errors import MissingExtraError


def require_torch():
    """Return the torch module, or raise MissingExtraError naming the extra to install."""
    try:
        import torch
    except ImportError:
        raise MissingExtraError(
            "this command needs PyTorch, which comes with the training extra: pip install 'sketchmesh[train]'"
        ) from None
    return torch
