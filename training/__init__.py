"""Sketchmesh training: torch. Differentiable rasterizer, losses, networks, data, trainer.

May import :mod:`engine` (shared geometry, cameras, export), never :mod:`app`.
"""
