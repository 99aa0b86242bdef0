"""SoftRas-style soft silhouette: an outside reference for the Eq. 1 edge gradient.

Soft Rasterizer (Liu et al. 2019) replaces the hard coverage test by a probability that a
pixel ``p`` lies in face ``j``::

    D_j(p) = sigmoid(delta_j(p) * d_j(p)^2 / sigma),   A(p) = 1 - prod_j (1 - D_j(p))

with ``d_j`` the distance from ``p`` to the face's outline in NDC units (the image spans
[-1, 1]), ``delta_j = +1`` inside the face and ``-1`` outside, and ``A`` the silhouette. Every
face within reach of a pixel contributes, occluded or not, so the gradient is exact (of this
smoothed image) and reaches vertices from pixels a little away from the outline; the price is
a blurred silhouette and work per (face, nearby pixel) pair rather than per boundary pixel.

The method (the paper's Eq. 1) does not use it: :class:`training.loop.config.TrainConfig`'s
``silhouette="soft"`` swaps it in for the mesh loss's silhouette so the two can be compared at
equal time (``sketchmesh bench variants``).

Work scales with what is drawn: each face only meets the pixels of its screen box widened by
the reach of the sigmoid (:func:`reach_px`: where ``D`` falls below :data:`SOFT_EPS`), not the
whole image. ``log(1 - D) = -softplus(delta d^2 / sigma)`` keeps the product finite when ``D``
rounds to 1 inside a face; faces with a vertex behind the near plane, a non-finite projection
or zero screen area are dropped (finite values, zero gradient).
"""

from __future__ import annotations

import math
from dataclasses import replace

import torch
import torch.nn.functional as F_
from torch import Tensor

from training.render.rasterize import _check_inputs, project_vertices, rasterize

SOFT_EPS = 1e-4
"""Face probabilities below this are dropped (they change A by less than 1e-4 per face)."""

DEFAULT_SIGMA = 1e-4
"""SoftRas's sharpness for silhouettes, in NDC units squared."""

MAX_PAIRS = 1 << 23
"""Most (face, pixel) pairs one call may form (a clear error above, never an out-of-memory)."""

__all__ = ["soft_silhouette", "reach_px", "DEFAULT_SIGMA"]


def reach_px(sigma: float, image_size: int) -> float:
    """Distance in pixels beyond a face's outline at which its probability falls to SOFT_EPS."""
    sigma_px = sigma * (image_size / 2.0) ** 2
    return math.sqrt(sigma_px * math.log(1.0 / SOFT_EPS - 1.0))


def _segment_dist_sq(px: Tensor, py: Tensor, ax: Tensor, ay: Tensor, bx: Tensor, by: Tensor) -> Tensor:
    """Squared distance from points to segments a-b (all tensors broadcast); degenerate segments are points."""
    ex, ey = bx - ax, by - ay
    len_sq = ex * ex + ey * ey
    t = ((px - ax) * ex + (py - ay) * ey) / len_sq.clamp(min=1e-12)
    t = t.clamp(0.0, 1.0)
    dx, dy = px - (ax + t * ex), py - (ay + t * ey)
    return dx * dx + dy * dy


def soft_silhouette(vertices: Tensor, faces: Tensor, cameras: Tensor, image_size: int, *, sigma: float = DEFAULT_SIGMA) -> Tensor:
    """(B, S, S) soft silhouette ``A`` of meshes, differentiable by ordinary autograd.

    Args:
        vertices: (B, V, 3) float32/float64; faces: (F, 3) int64; cameras: (B, 16) or (16,) in
            :meth:`engine.camera.Camera.to_array` layout; image_size: S.
        sigma: sharpness in NDC units squared (finite, > 0; SoftRas: 1e-4). Smaller is closer
            to the hard silhouette and reaches fewer pixels.

    Raises:
        ValueError: the rasterizer's input checks, a bad sigma, or more than :data:`MAX_PAIRS`
            (face, pixel) pairs (a huge mesh on screen or a huge sigma).
    """
    vertices, faces, cams = _check_inputs(vertices, faces, cameras, image_size, 1.0, "flat")
    sigma = float(sigma)
    if not (sigma > 0 and math.isfinite(sigma)):
        raise ValueError(f"sigma must be finite and > 0, got {sigma}")
    S = int(image_size)
    B, F = vertices.shape[0], faces.shape[0]
    _, screen, _, vvalid = project_vertices(vertices, cams, S)
    tri = screen[:, faces]  # (B, F, 3, 2) pixel coordinates, differentiable
    with torch.no_grad():
        t = tri.detach()
        area2 = (t[:, :, 1, 0] - t[:, :, 0, 0]) * (t[:, :, 2, 1] - t[:, :, 0, 1]) - (
            t[:, :, 1, 1] - t[:, :, 0, 1]
        ) * (t[:, :, 2, 0] - t[:, :, 0, 0])
        ok = vvalid[:, faces].all(-1) & (area2.abs() > 1e-12)
        reach = reach_px(sigma, S)
        lo = t.amin(2) - reach  # (B, F, 2)
        hi = t.amax(2) + reach
        big = float(4 * S + 4)
        x0 = torch.ceil(lo[..., 0].clamp(-big, big) - 0.5).clamp(0, S).long()
        x1 = torch.floor(hi[..., 0].clamp(-big, big) - 0.5).clamp(-1, S - 1).long()
        y0 = torch.ceil(lo[..., 1].clamp(-big, big) - 0.5).clamp(0, S).long()
        y1 = torch.floor(hi[..., 1].clamp(-big, big) - 0.5).clamp(-1, S - 1).long()
        nx, ny = (x1 - x0 + 1).clamp(min=0), (y1 - y0 + 1).clamp(min=0)
        count = torch.where(ok, nx * ny, torch.zeros_like(nx)).reshape(-1)  # (B * F,)
        total = int(count.sum())
        if total > MAX_PAIRS:
            raise ValueError(
                f"soft silhouette needs {total:,} (face, pixel) pairs, over {MAX_PAIRS:,}: "
                f"lower sigma ({sigma:g}), the image size or the batch"
            )
        bf = torch.repeat_interleave(torch.arange(B * F, device=count.device), count)
        first = torch.cumsum(count, 0) - count
        k = torch.arange(total, device=count.device) - first.repeat_interleave(count)
        nxf = nx.reshape(-1).index_select(0, bf)
        pix_x = x0.reshape(-1).index_select(0, bf) + k % nxf.clamp(min=1)
        pix_y = y0.reshape(-1).index_select(0, bf) + k // nxf.clamp(min=1)
        b_idx = bf // F
        flat_pix = (b_idx * S + pix_y) * S + pix_x
        sgn = torch.sign(area2).reshape(-1).index_select(0, bf)
    if total == 0:
        return vertices.new_zeros(B, S, S) + 0.0 * tri.sum()
    tv = tri.reshape(B * F, 3, 2).index_select(0, bf)  # (N, 3, 2) differentiable
    px, py = pix_x.to(tv.dtype) + 0.5, pix_y.to(tv.dtype) + 0.5
    d2 = None
    inside = torch.ones_like(px, dtype=torch.bool)
    for e in range(3):
        a, b = tv[:, (e + 1) % 3], tv[:, (e + 2) % 3]
        de = _segment_dist_sq(px, py, a[:, 0], a[:, 1], b[:, 0], b[:, 1])
        d2 = de if d2 is None else torch.minimum(d2, de)
        with torch.no_grad():  # inside: on the interior side of every edge (either orientation)
            cross = (b[:, 0] - a[:, 0]) * (py - a[:, 1]) - (b[:, 1] - a[:, 1]) * (px - a[:, 0])
            inside &= sgn * cross > 0
    sigma_px = sigma * (S / 2.0) ** 2
    x = torch.where(inside, d2, -d2) / sigma_px
    log_out = -F_.softplus(x)  # log(1 - sigmoid(x)), finite for any x
    acc = vertices.new_zeros(B * S * S).index_add(0, flat_pix, log_out)
    return (1.0 - torch.exp(acc)).view(B, S, S)


SILHOUETTES = ("eq1", "soft")


def rasterize_for_loss(vertices, faces, cameras, image_size, *, delta=1.0, shading="flat", edge_range=1,
                       silhouette="eq1", soft_sigma=DEFAULT_SIGMA, normal_edges=True):
    """:func:`training.render.rasterize` with the training variants of the silhouette gradient.

    ``silhouette="eq1"`` (the method) returns the rasterizer's output with the Eq. 1 gradient
    (``edge_range`` pixels of reach); ``"soft"`` replaces its silhouette by
    :func:`soft_silhouette` (SoftRas, the outside reference), the normal image keeping Eq. 1.
    ``normal_edges=False``: the normal image without the Eq. 1 edge gradient (see :func:`rasterize`).
    """
    if silhouette not in SILHOUETTES:
        raise ValueError(f"silhouette must be one of {SILHOUETTES}, got {silhouette!r}")
    out = rasterize(vertices, faces, cameras, image_size, delta=delta, shading=shading, edge_range=edge_range,
                    normal_edges=normal_edges)
    if silhouette == "soft":
        out = replace(out, silhouette=soft_silhouette(vertices, faces, cameras, image_size, sigma=soft_sigma))
    return out
