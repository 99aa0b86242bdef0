"""Differentiable rasterizer (torch): the public op and its no-grad numpy convenience.

See :mod:`training.render.rasterize` for the design and the approximate gradient (Eq. 1),
:mod:`training.render.reference` for the slow loop reference used by the tests, and
:mod:`training.render.dense` for the every-face-against-every-pixel baseline used only by
``sketchmesh bench renderer``.
"""

from training.render.rasterize import RenderOutput, cameras_to_tensor, rasterize, render_normals_numpy

__all__ = ["RenderOutput", "cameras_to_tensor", "rasterize", "render_normals_numpy"]
