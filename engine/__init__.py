"""Sketchmesh inference engine: numpy + onnxruntime + trimesh only.

Importing this package loads no model and imports neither torch, Qt nor ``training``.
Conventions (axes, cameras, pixels, normal encoding, framing) live in :mod:`engine.camera`.
"""

__version__ = "0.1.0"
