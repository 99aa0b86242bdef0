"""The mesh predictor's losses: paper Eq. 2-6 (Xiang et al., section 3.2).

Pure functions of tensors do the math; :class:`MeshLoss` only holds the template's
topology (built once, vectorised) and the weights. Image conventions (normal encoding
``(n + 1) / 2`` with background 0, silhouettes 1 on the shape) are those of
:mod:`engine.camera`.

Equations (``B`` batch, ``V`` vertices, ``E`` edges, ``P`` adjacent face pairs, ``H W``
pixels):

* Eq. 2, normal loss ``L_n = ||N_hat - N||_1`` -- :func:`normal_loss`.
* Eq. 3, silhouette IoU loss ``L_s = 1 - |S_hat * S|_1 / |S_hat + S - S_hat * S|_1`` --
  :func:`silhouette_iou_loss`.
* Eq. 4, edge (as-rigid-as-possible) loss ``L_e = 1/E sum_i | |e_hat_i| - |e_i| |`` --
  :func:`edge_loss`.
* Eq. 5, dihedral smoothness loss ``L_m = sum_(i,j) (1 + cos<f_i, f_j>)^2`` --
  :func:`dihedral_smoothness_loss`.
* Eq. 6, ``L = l_n L_n + l_s L_s + l_e L_e + l_m L_m`` -- :func:`total_loss`,
  :class:`MeshLoss`, weights in :class:`LossWeights`.

Every term is reduced per sample and then averaged over the batch, so the total does not
depend on the batch size.

Reduction of the normal term. The paper writes Eq. 2 as an L1 *norm* and weights it by
``l_n = 0.002`` against ``l_s = 0.9`` for a loss in [0, 1]: with a per-pixel mean the
normal term would be ~1e-4 and do nothing, with a sum over the 3 x 64 x 64 values of the
paper's 64 x 64 training images it is O(1) -- the same order as the silhouette term. So
:func:`normal_loss` sums over (C, H, W) by default. A plain sum grows with the image size,
so :class:`MeshLoss` rescales it to the paper's 64 x 64 pixel count
(:data:`NORMAL_REFERENCE_PIXELS`): ``lambda_n = 0.002`` means the same at 32, 64 or 128.

Numerical stability: norms use a clamped square root (finite value and gradient at zero
length); the dihedral term works in a per-sample scale-normalised frame (the scale is
detached), so it is scale invariant from 1e-6 to 1e6 and finite for coincident vertices
and zero-area faces; the IoU term is defined as 0 when both silhouettes are empty.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import nn

from engine.mesh import Mesh, adjacent_face_pairs, unique_edges

NORMAL_REFERENCE_PIXELS = 64 * 64
"""Pixel count the paper's ``lambda_n = 0.002`` was set for (64 x 64 normal images)."""

IOU_EPS = 1e-6
"""Added to intersection and union (in pixel units): IoU of two empty silhouettes is 1 (loss 0)."""

NORM_MIN_SQ = 1e-30
"""Squared lengths are clamped to at least this before a square root (gradient stays finite at 0)."""

DIHEDRAL_EPS = 1e-8
"""Added to squared lengths in the scale-normalised dihedral frame (mean edge length 1): a
degenerate face (opposite vertex on the shared edge line) gives cos = 0 instead of NaN, and the
gradient there is bounded by ~1 / sqrt(DIHEDRAL_EPS) = 1e4 (relative to the mesh scale)."""

NORMAL_REGIONS = ("image", "target")
"""Where the normal term is computed: the whole image (the paper) or inside the target silhouette."""

SCALE_MIN = 1e-30
"""Per-sample mesh scales below this (every vertex coincident) are replaced by 1."""


# --------------------------------------------------------------------------- checks


def _check_image_pair(pred: torch.Tensor, target: torch.Tensor, ndim: int, what: str, layout: str) -> None:
    if not isinstance(pred, torch.Tensor) or not isinstance(target, torch.Tensor):
        raise TypeError(f"{what} expects tensors, got {type(pred).__name__} and {type(target).__name__}")
    if pred.ndim != ndim or pred.shape != target.shape:
        raise ValueError(f"{what} expects pred and target of the same shape {layout}, got {tuple(pred.shape)} and {tuple(target.shape)}")
    if not pred.is_floating_point():
        raise ValueError(f"{what} expects floating-point images, got {pred.dtype}")


def _check_vertices(vertices: torch.Tensor, what: str) -> None:
    if not isinstance(vertices, torch.Tensor) or vertices.ndim != 3 or vertices.shape[-1] != 3:
        shape = tuple(vertices.shape) if isinstance(vertices, torch.Tensor) else type(vertices).__name__
        raise ValueError(f"{what} expects vertices (B, V, 3), got {shape}")
    if not vertices.is_floating_point():
        raise ValueError(f"{what} expects floating-point vertices, got {vertices.dtype}")


def _check_index(index: torch.Tensor, width: int, num_vertices: int, what: str, name: str) -> None:
    if not isinstance(index, torch.Tensor) or index.ndim != 2 or index.shape[1] != width:
        shape = tuple(index.shape) if isinstance(index, torch.Tensor) else type(index).__name__
        raise ValueError(f"{what} expects {name} (N, {width}) int64, got {shape}")
    if index.dtype != torch.int64:
        raise ValueError(f"{what} expects {name} of dtype int64, got {index.dtype}")
    if index.numel() and (int(index.min()) < 0 or int(index.max()) >= num_vertices):
        raise ValueError(f"{what}: {name} indices must be in [0, {num_vertices}), got [{int(index.min())}, {int(index.max())}]")


def safe_norm(x: torch.Tensor, dim: int = -1) -> torch.Tensor:
    """Euclidean norm along ``dim`` with a finite gradient at zero length (the gradient there is 0)."""
    return torch.sqrt(torch.clamp((x * x).sum(dim), min=NORM_MIN_SQ))


# --------------------------------------------------------------------------- Eq. 2


def normal_loss(pred: torch.Tensor, target: torch.Tensor, reduction: str = "sum",
                mask: torch.Tensor | None = None) -> torch.Tensor:
    """Eq. 2: L1 distance between normal images, per sample, averaged over the batch.

    Args:
        pred: (B, 3, H, W) rendered normal image, encoded ``(n + 1) / 2``, background 0.
        target: (B, 3, H, W) ground-truth normal image, same encoding.
        reduction: ``"sum"`` (default, the paper's L1 norm: sum over C, H, W) or ``"mean"``
            (mean over C, H, W). See the module docstring for why the sum is the default.
        mask: optional (B, H, W) weights (e.g. the target silhouette); pixels where it is 0 count 0.

    Returns:
        () scalar tensor, ``mean_b reduce_chw |pred - target|``.
    """
    _check_image_pair(pred, target, 4, "normal_loss", "(B, 3, H, W)")
    if pred.shape[1] != 3:
        raise ValueError(f"normal_loss expects 3 channels (B, 3, H, W), got {tuple(pred.shape)}")
    diff = (pred - target).abs()
    if mask is not None:
        if mask.shape != (pred.shape[0], *pred.shape[2:]):
            raise ValueError(f"normal_loss mask must be (B, H, W) = {(pred.shape[0], *pred.shape[2:])}, got {tuple(mask.shape)}")
        diff = diff * mask[:, None].to(diff.dtype)
    diff = diff.flatten(1)
    if reduction == "sum":
        per_sample = diff.sum(1)
    elif reduction == "mean":
        per_sample = diff.mean(1)
    else:
        raise ValueError(f"normal_loss reduction must be 'sum' or 'mean', got {reduction!r}")
    return per_sample.mean()


# --------------------------------------------------------------------------- Eq. 3


def silhouette_iou_loss(pred: torch.Tensor, target: torch.Tensor, eps: float = IOU_EPS,
                        weight: torch.Tensor | None = None) -> torch.Tensor:
    """Eq. 3: one minus the soft intersection-over-union of silhouettes, averaged over the batch.

    Per sample, with ``I = sum(S_hat * S)`` and ``U = sum(S_hat + S - S_hat * S)`` over pixels::

        L_s = 1 - (I + eps) / (U + eps)

    For silhouettes in [0, 1], ``U >= I >= 0`` so ``L_s`` is in [0, 1]. The ``eps`` in the
    numerator as well as the denominator defines the both-empty case: two empty silhouettes
    match perfectly, loss 0, with finite gradients (the denominator is at least ``eps``). When
    the union is a handful of pixels or more, ``eps`` (1e-6 pixel) changes the value by < 1e-6.

    With ``weight`` (``w >= 0`` per pixel) both sums are weighted, ``I = sum(w S_hat S)`` and
    ``U = sum(w (S_hat + S - S_hat S))``: a pixel of weight 4 counts as four, so a small region
    (legs and the gaps between them, :func:`support_band_weights`) moves the loss as a larger
    one would. Still in [0, 1]; weights of 1 give Eq. 3 exactly.

    Args:
        pred: (B, H, W) rendered silhouette in [0, 1].
        target: (B, H, W) ground-truth silhouette in [0, 1].
        eps: > 0, in pixel units.
        weight: None, or (B, H, W) finite per-pixel weights >= 0 (not differentiated).

    Returns:
        () scalar tensor.
    """
    _check_image_pair(pred, target, 3, "silhouette_iou_loss", "(B, H, W)")
    if not (math.isfinite(eps) and eps > 0):
        raise ValueError(f"silhouette_iou_loss eps must be finite and > 0, got {eps}")
    p, t = pred.flatten(1), target.flatten(1)
    overlap = p * t
    cover = p + t - overlap
    if weight is not None:
        if not isinstance(weight, torch.Tensor) or tuple(weight.shape) != tuple(pred.shape):
            raise ValueError(f"silhouette_iou_loss weight must be a tensor of the silhouettes' shape {tuple(pred.shape)}, "
                             f"got {getattr(weight, 'shape', type(weight).__name__)}")
        w = weight.detach().flatten(1).to(p.dtype)
        overlap, cover = overlap * w, cover * w
    inter = overlap.sum(1)
    union = cover.sum(1)
    return (1.0 - (inter + eps) / (union + eps)).mean()


SUPPORT_BAND = 0.25
"""Share of a target silhouette's height, from its lowest row, that :func:`support_band_weights` weights: where a
standing shape's supports are (the band :func:`training.evaluation.metrics.image_support_count` counts them in)."""


def support_band_weights(target: torch.Tensor, gain: float, band: float = SUPPORT_BAND) -> torch.Tensor:
    """Per-pixel weights of the silhouette term that make a standing shape's supports count.

    A chair's legs and the gaps between them are a few percent of its silhouette's pixels, so a mesh that stands on a
    skirt loses little IoU. These weights are ``1 + gain`` on every pixel (shape or background, the full width) of the
    rows in the lowest ``band`` of the rows each target silhouette covers, and 1 elsewhere: legs left out and gaps
    filled in cost ``1 + gain`` times as much. An empty target gets weights of 1.

    Args:
        target: (B, H, W) target silhouettes in [0, 1] (a pixel above 0.5 is covered).
        gain: finite, >= 0 (0: all weights 1).
        band: the share of the covered rows' span weighted, in (0, 1]; at least one row.

    Returns:
        (B, H, W) weights, the target's dtype and device, no gradient.
    """
    if isinstance(gain, bool) or not isinstance(gain, (int, float)) or not (math.isfinite(gain) and gain >= 0):
        raise ValueError(f"support_band_weights gain must be a finite number >= 0, got {gain!r}")
    if isinstance(band, bool) or not isinstance(band, (int, float)) or not (math.isfinite(band) and 0 < band <= 1):
        raise ValueError(f"support_band_weights band must be a number in (0, 1], got {band!r}")
    if target.ndim != 3:
        raise ValueError(f"support_band_weights expects (B, H, W) silhouettes, got {tuple(target.shape)}")
    with torch.no_grad():
        h = target.shape[1]
        rows_covered = (target > 0.5).any(dim=2)  # (B, H)
        index = torch.arange(h, device=target.device)
        lowest = torch.where(rows_covered, index, -1).amax(dim=1)  # -1 when empty
        highest = torch.where(rows_covered, index, h).amin(dim=1)
        span = (lowest - highest + 1).clamp(min=0).to(torch.float64)
        count = torch.ceil(span * band - 1e-9).clamp(min=1).to(torch.long)
        in_band = (index[None] > (lowest - count)[:, None]) & (index[None] <= lowest[:, None])  # (B, H)
        in_band &= (lowest >= 0)[:, None]
        w = 1.0 + float(gain) * in_band.to(target.dtype)
        return w[:, :, None].expand(target.shape).contiguous()


# --------------------------------------------------------------------------- Eq. 4


def edge_lengths(vertices: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
    """(B, E) lengths of ``edges`` (E, 2) int64 on ``vertices`` (B, V, 3) (finite gradient at length 0)."""
    _check_vertices(vertices, "edge_lengths")
    _check_index(edges, 2, vertices.shape[1], "edge_lengths", "edges")
    return safe_norm(vertices[:, edges[:, 1]] - vertices[:, edges[:, 0]])


def edge_loss(vertices: torch.Tensor, edges: torch.Tensor, template_lengths: torch.Tensor) -> torch.Tensor:
    """Eq. 4: mean absolute change of edge length against the template, averaged over the batch.

    ``L_e = 1/E sum_i | |e_hat_i| - |e_i| |``: ``e_hat_i`` the current edge, ``e_i`` the same
    edge on the template. Coincident vertices give a finite value and gradient (the norm's
    square root is clamped, so the gradient of a zero-length edge is 0, not NaN).

    Args:
        vertices: (B, V, 3) current vertex positions.
        edges: (E, 2) int64 vertex indices (e.g. :func:`engine.mesh.unique_edges`).
        template_lengths: (E,) template edge lengths, same dtype family as ``vertices``.

    Returns:
        () scalar tensor.
    """
    _check_vertices(vertices, "edge_loss")
    _check_index(edges, 2, vertices.shape[1], "edge_loss", "edges")
    if not isinstance(template_lengths, torch.Tensor) or template_lengths.shape != (edges.shape[0],):
        got = tuple(template_lengths.shape) if isinstance(template_lengths, torch.Tensor) else type(template_lengths).__name__
        raise ValueError(f"edge_loss expects template_lengths ({edges.shape[0]},), got {got}")
    return _edge_loss(vertices, edges, template_lengths)


def _edge_loss(vertices: torch.Tensor, edges: torch.Tensor, template_lengths: torch.Tensor) -> torch.Tensor:
    """:func:`edge_loss` without the input checks (for callers holding validated topology)."""
    if edges.shape[0] == 0:
        return vertices.sum() * 0.0
    lengths = safe_norm(vertices[:, edges[:, 1]] - vertices[:, edges[:, 0]])  # (B, E)
    return (lengths - template_lengths.to(lengths.dtype)).abs().mean(1).mean()


# --------------------------------------------------------------------------- 3D diagnostic


def sample_mesh_points(vertices: torch.Tensor, faces: torch.Tensor, n: int, generator: torch.Generator | None = None
                   ) -> torch.Tensor:
    """(B, n, 3) points on each mesh's surface, uniform by area, differentiable in ``vertices``.

    Faces are drawn with probability proportional to their (detached) area, then a point inside
    the face with uniform barycentric weights ``(1 - sqrt(r1), sqrt(r1) (1 - r2), sqrt(r1) r2)``;
    the point is that weighted sum of the face's vertices, so its gradient reaches them. A mesh
    whose faces all have zero area samples faces uniformly (no NaN from a 0/0 probability).

    Args:
        vertices: (B, V, 3). faces: (F, 3) int64. n: points per mesh (>= 1).
        generator: CPU generator for the draws (reproducible steps).
    """
    _check_vertices(vertices, "sample_mesh_points")
    _check_index(faces, 3, vertices.shape[1], "sample_mesh_points", "faces")
    if n < 1:
        raise ValueError(f"sample_mesh_points needs n >= 1, got {n}")
    b = vertices.shape[0]
    tri = vertices[:, faces]  # (B, F, 3, 3)
    with torch.no_grad():
        area = safe_norm(torch.linalg.cross(tri[:, :, 1] - tri[:, :, 0], tri[:, :, 2] - tri[:, :, 0])).float().cpu()
        area = torch.where(area.sum(1, keepdim=True) > 0, area, torch.ones_like(area))
        idx = torch.multinomial(area, n, replacement=True, generator=generator).to(vertices.device)  # (B, n)
        r = torch.rand(b, n, 2, generator=generator).to(vertices.device, vertices.dtype)
    s1 = r[..., 0].sqrt()
    w = torch.stack([1.0 - s1, s1 * (1.0 - r[..., 1]), s1 * r[..., 1]], dim=-1)  # (B, n, 3)
    picked = torch.gather(tri, 1, idx[:, :, None, None].expand(b, n, 3, 3))  # (B, n, 3 corners, 3)
    return (w[..., None] * picked).sum(2)


def chamfer_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Symmetric Chamfer-L1 distance between point sets, averaged over the batch.

    ``0.5 * (mean_p min_t |p - t| + mean_t min_p |p - t|)`` per sample (Euclidean distances, the
    ``chamfer_l1`` of :mod:`training.evaluation.metrics`); finite gradient where points coincide.

    Args:
        pred: (B, N, 3). target: (B, M, 3).
    """
    if pred.ndim != 3 or target.ndim != 3 or pred.shape[0] != target.shape[0] or pred.shape[2] != 3 \
            or target.shape[2] != 3:
        raise ValueError(f"chamfer_loss expects (B, N, 3) and (B, M, 3), got {tuple(pred.shape)} and {tuple(target.shape)}")
    # Nearest neighbours without autograd (the gradient of a min reaches only its argmin), by
    # |p|^2 + |t|^2 - 2 p.t in one batched matmul: no (B, N, M, 3) difference tensor (400 MB a step
    # at 32 x 1024 x 1024) and no backward through the (B, N, M) matrix. Then exact distances of
    # the nearest pairs only, with autograd.
    with torch.no_grad():
        d2 = (pred.pow(2).sum(-1)[:, :, None] + target.pow(2).sum(-1)[:, None, :]
              - 2.0 * torch.bmm(pred, target.transpose(1, 2)))  # (B, N, M)
        near_t, near_p = d2.argmin(2), d2.argmin(1)  # (B, N) into target, (B, M) into pred
    to_target = safe_norm(pred - torch.gather(target, 1, near_t[..., None].expand(-1, -1, 3))).mean(1)
    to_pred = safe_norm(target - torch.gather(pred, 1, near_p[..., None].expand(-1, -1, 3))).mean(1)
    return (0.5 * (to_target + to_pred)).mean()


# --------------------------------------------------------------------------- Eq. 5


def dihedral_indices(faces: np.ndarray) -> np.ndarray:
    """(P, 4) int64 ``(a, b, c0, c1)`` per adjacent face pair, built once from the template's faces.

    Concretely, row p says faces f0 = (a, b, c0) and f1 (containing a, b, c1) share the edge
    (a, b), in f0's winding; ``c0`` and ``c1`` are the vertices opposite that edge. Built from
    :func:`engine.mesh.adjacent_face_pairs`, vectorised.

    Args:
        faces: (F, 3) int64 faces.
    """
    f = np.asarray(faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must be (F, 3), got {f.shape}")
    pairs, edges = adjacent_face_pairs(f)
    if len(pairs) == 0:
        return np.zeros((0, 4), dtype=np.int64)
    f0, f1 = f[pairs[:, 0]], f[pairs[:, 1]]  # (P, 3) each

    def opposite(tri: np.ndarray) -> np.ndarray:
        other = (tri != edges[:, :1]) & (tri != edges[:, 1:])  # (P, 3)
        if not np.all(other.sum(1) >= 1):
            raise ValueError("faces contain a triangle with a repeated vertex index on a shared edge")
        return tri[np.arange(len(tri)), np.argmax(other, axis=1)]

    return np.stack([edges[:, 0], edges[:, 1], opposite(f0), opposite(f1)], axis=1)


def dihedral_cosines(vertices: torch.Tensor, quads: torch.Tensor, eps: float = DIHEDRAL_EPS) -> torch.Tensor:
    """(B, P) cosine of the dihedral angle of each adjacent face pair.

    For a pair sharing edge ``e = b - a`` with opposite vertices ``c0`` and ``c1``, take the
    components of ``c0 - a`` and ``c1 - a`` perpendicular to the edge, ``n0`` and ``n1``: they
    point from the edge into each face's half-plane, so their angle is the dihedral angle
    measured through the surface (as in the Neural Mesh Renderer / Soft Rasterizer
    smoothness loss). A flat surface gives 180 degrees (cos = -1); a fold to 90 degrees
    gives cos = 0; a face folded back onto its neighbour gives cos = 1.

    Stability: lengths are divided by a per-sample, detached scale (root mean square shared
    edge length), then ``eps`` is added to every squared length. Degenerate pairs (opposite
    vertex on the edge line, or a zero-length edge) give a finite cosine in [-1, 1].

    Args:
        vertices: (B, V, 3).
        quads: (P, 4) int64 from :func:`dihedral_indices`.
        eps: > 0, in the normalised frame (squared-length units, mean edge length 1).
    """
    _check_vertices(vertices, "dihedral_cosines")
    _check_index(quads, 4, vertices.shape[1], "dihedral_cosines", "quads")
    if not (math.isfinite(eps) and eps >= 0):
        raise ValueError(f"dihedral eps must be finite and >= 0, got {eps}")
    return _dihedral_cosines(vertices, quads, eps)


def _dihedral_cosines(vertices: torch.Tensor, quads: torch.Tensor, eps: float) -> torch.Tensor:
    """:func:`dihedral_cosines` without the input checks."""
    a = vertices[:, quads[:, 0]]  # (B, P, 3)
    e = vertices[:, quads[:, 1]] - a
    u0 = vertices[:, quads[:, 2]] - a
    u1 = vertices[:, quads[:, 3]] - a
    with torch.no_grad():
        scale = torch.sqrt((e * e).sum(-1).mean(1) if quads.shape[0] else e.new_ones(vertices.shape[0]))  # (B,)
        scale = torch.where(torch.isfinite(scale) & (scale > SCALE_MIN), scale, torch.ones_like(scale))
    inv = (1.0 / scale)[:, None, None]
    e, u0, u1 = e * inv, u0 * inv, u1 * inv
    ee = (e * e).sum(-1, keepdim=True) + eps
    n0 = u0 - ((u0 * e).sum(-1, keepdim=True) / ee) * e
    n1 = u1 - ((u1 * e).sum(-1, keepdim=True) / ee) * e
    n0 = n0 / torch.sqrt((n0 * n0).sum(-1, keepdim=True) + eps)
    n1 = n1 / torch.sqrt((n1 * n1).sum(-1, keepdim=True) + eps)
    return (n0 * n1).sum(-1).clamp(-1.0, 1.0)


def dihedral_smoothness_loss(vertices: torch.Tensor, quads: torch.Tensor, eps: float = DIHEDRAL_EPS) -> torch.Tensor:
    """Eq. 5: ``sum over adjacent face pairs of (1 + cos<f_i, f_j>)^2``, averaged over the batch.

    0 for a flat surface, 1 per pair folded to 90 degrees, 4 per pair folded flat back onto
    itself. Scale invariant (see :func:`dihedral_cosines`). A sum, as in the paper (and NMR /
    SoftRas); the paper's ``lambda_m = 0.01`` is set for that.

    Args:
        vertices: (B, V, 3).
        quads: (P, 4) int64 from :func:`dihedral_indices`.
        eps: see :func:`dihedral_cosines`.

    Returns:
        () scalar tensor.
    """
    cos = dihedral_cosines(vertices, quads, eps)
    return ((1.0 + cos) ** 2).sum(1).mean()


def _dihedral_smoothness_loss(vertices: torch.Tensor, quads: torch.Tensor, eps: float = DIHEDRAL_EPS) -> torch.Tensor:
    """:func:`dihedral_smoothness_loss` without the input checks."""
    return ((1.0 + _dihedral_cosines(vertices, quads, eps)) ** 2).sum(1).mean()


# --------------------------------------------------------------------------- Eq. 6


@dataclass(frozen=True)
class LossWeights:
    """Weights of Eq. 6; the defaults are the paper's (section 4.1).

    Attributes:
        normal: lambda_n, on the normal L1 sum rescaled to 64 x 64 pixels.
        silhouette: lambda_s, on 1 - IoU.
        edge: lambda_e, on the mean absolute edge-length change.
        smoothness: lambda_m, on the dihedral sum.
    """

    normal: float = 0.002
    silhouette: float = 0.9
    edge: float = 0.9
    smoothness: float = 0.01

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value) or value < 0:
                raise ValueError(f"loss weight {name} must be a finite number >= 0, got {value!r}")
            object.__setattr__(self, name, float(value))


def total_loss(terms: dict[str, torch.Tensor], weights: LossWeights) -> tuple[torch.Tensor, dict[str, float]]:
    """Eq. 6: weighted sum of the terms present in ``terms``.

    Args:
        terms: any of ``"normal"``, ``"silhouette"``, ``"edge"``, ``"smoothness"`` -> () tensors.
        weights: the lambdas.

    Returns:
        total: () tensor, ``sum_k weights.k * terms[k]`` (a weight of 0 drops the term's graph).
        log: the unweighted terms and ``"total"`` as detached Python floats.
    """
    w = asdict(weights)
    unknown = set(terms) - set(w)
    if unknown:
        raise ValueError(f"unknown loss terms {sorted(unknown)}; expected some of {sorted(w)}")
    if not terms:
        raise ValueError("total_loss needs at least one term")
    parts = [w[k] * v for k, v in terms.items() if w[k] != 0.0]
    total = torch.stack(parts).sum() if parts else next(iter(terms.values())) * 0.0
    log = {k: float(v.detach()) for k, v in terms.items()}
    log["total"] = float(total.detach())
    return total, log


class MeshLoss(nn.Module):
    """Eq. 6 for meshes with a fixed template topology; holds only the precomputed topology.

    Buffers (built once in ``__init__``, moved with ``.to()``):
        edges: (E, 2) int64 unique edges of the template.
        template_lengths: (E,) float32 edge lengths on the template.
        quads: (P, 4) int64 dihedral index (see :func:`dihedral_indices`).

    Args:
        template: the template mesh (e.g. :func:`engine.icosphere.icosphere`).
        weights: the lambdas (default: the paper's).
        normal_reference_pixels: the normal L1 sum is multiplied by
            ``normal_reference_pixels / (H * W)``; ``None`` keeps the plain sum.
        normal_region: ``"image"`` (the paper's Eq. 2 over the whole image) or ``"target"`` (only
            pixels inside the ground-truth silhouette). With background 0, a pixel the prediction
            covers outside the target costs about 1.5 (the encoded normal's channel sum), as much
            as a target pixel left uncovered, while a covered target pixel with a wrong normal
            costs up to 3: at the paper's weights this whole-image sum pulls 10x harder than the
            IoU term, and from the template sphere its steepest descent is to shrink the render
            towards empty. Inside the target only, uncovered pixels still cost and wrong normals
            still cost, but nothing rewards rendering less; over-coverage is left to the IoU term.
        support_band_weight: the silhouette term's pixels in the lowest quarter of each target's rows weigh
            ``1 + support_band_weight`` (:func:`support_band_weights`; 0, the default: Eq. 3 as written).
    """

    def __init__(self, template: Mesh, weights: LossWeights | None = None,
                 normal_reference_pixels: int | None = NORMAL_REFERENCE_PIXELS,
                 normal_region: str = "image", support_band_weight: float = 0.0) -> None:
        super().__init__()
        if (isinstance(support_band_weight, bool) or not isinstance(support_band_weight, (int, float))
                or not (math.isfinite(support_band_weight) and support_band_weight >= 0)):
            raise ValueError(f"support_band_weight must be a finite number >= 0, got {support_band_weight!r}")
        self.support_band_weight = float(support_band_weight)
        if normal_region not in NORMAL_REGIONS:
            raise ValueError(f"normal_region must be one of {NORMAL_REGIONS}, got {normal_region!r}")
        self.normal_region = normal_region
        if not isinstance(template, Mesh):
            raise TypeError(f"MeshLoss template must be an engine.mesh.Mesh, got {type(template).__name__}")
        self.weights = weights if weights is not None else LossWeights()
        self.normal_reference_pixels = normal_reference_pixels
        edges = unique_edges(template.faces)
        v = template.vertices.astype(np.float64)
        lengths = np.linalg.norm(v[edges[:, 1]] - v[edges[:, 0]], axis=1)
        self.register_buffer("edges", torch.from_numpy(edges))
        self.register_buffer("template_lengths", torch.from_numpy(lengths.astype(np.float32)))
        self.register_buffer("quads", torch.from_numpy(dihedral_indices(template.faces)))
        self.num_vertices = template.num_vertices

    def forward(
        self,
        vertices: torch.Tensor,
        pred_normals: torch.Tensor | None = None,
        target_normals: torch.Tensor | None = None,
        pred_silhouette: torch.Tensor | None = None,
        target_silhouette: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, dict[str, float]]:
        """Compute Eq. 6.

        Args:
            vertices: (B, V, 3) predicted vertices (V = the template's).
            pred_normals, target_normals: (B, 3, H, W) or both None (term skipped).
            pred_silhouette, target_silhouette: (B, H, W) or both None (term skipped).

        Returns:
            total: () tensor; log: detached floats per term and ``"total"``.
        """
        _check_vertices(vertices, "MeshLoss")
        if vertices.shape[1] != self.num_vertices:
            raise ValueError(f"MeshLoss expects {self.num_vertices} vertices (the template's), got {tuple(vertices.shape)}")
        terms: dict[str, torch.Tensor] = {}
        if (pred_normals is None) != (target_normals is None):
            raise ValueError("MeshLoss needs both pred_normals and target_normals, or neither")
        if pred_normals is not None:
            mask = None
            if self.normal_region == "target":
                if target_silhouette is None:
                    raise ValueError("MeshLoss normal_region='target' needs the target silhouette")
                mask = target_silhouette > 0.5
            ln = normal_loss(pred_normals, target_normals, reduction="sum", mask=mask)
            if self.normal_reference_pixels is not None:
                ln = ln * (float(self.normal_reference_pixels) / (pred_normals.shape[-1] * pred_normals.shape[-2]))
            terms["normal"] = ln
        if (pred_silhouette is None) != (target_silhouette is None):
            raise ValueError("MeshLoss needs both pred_silhouette and target_silhouette, or neither")
        if pred_silhouette is not None:
            weight = (support_band_weights(target_silhouette, self.support_band_weight)
                      if self.support_band_weight else None)
            terms["silhouette"] = silhouette_iou_loss(pred_silhouette, target_silhouette, weight=weight)
        # topology buffers were validated at construction: skip the per-call range checks (no device sync)
        terms["edge"] = _edge_loss(vertices, self.edges, self.template_lengths)
        terms["smoothness"] = _dihedral_smoothness_loss(vertices, self.quads)
        return total_loss(terms, self.weights)
