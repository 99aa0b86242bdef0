"""The icosphere template the mesh predictor deforms.

Level k has ``10 * 4**k + 2`` vertices and ``20 * 4**k`` faces: level 2 -> 162 / 320,
level 3 -> 642 / 1280 (the paper's template), level 4 -> 2562 / 5120. Vertices lie on
a sphere of radius :data:`TEMPLATE_RADIUS`, faces wind counter-clockwise seen from
outside (outward normals), and the vertex order is deterministic: the 12 icosahedron
vertices first, then one new vertex per edge midpoint, level by level, in order of first
appearance over the faces.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from engine.mesh import Mesh

TEMPLATE_RADIUS = 0.5
"""Radius of the template sphere; a normalised shape fits in [-0.5, 0.5]^3."""

PAPER_LEVEL = 3


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    p = (1.0 + 5.0**0.5) / 2.0
    v = np.array(
        [[-1, p, 0], [1, p, 0], [-1, -p, 0], [1, -p, 0],
         [0, -1, p], [0, 1, p], [0, -1, -p], [0, 1, -p],
         [p, 0, -1], [p, 0, 1], [-p, 0, -1], [-p, 0, 1]],
        dtype=np.float64,
    )
    f = np.array(
        [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
         [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
         [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
         [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]],
        dtype=np.int64,
    )
    return v / np.linalg.norm(v, axis=1, keepdims=True), f


def _subdivide(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=0)  # (3F, 2) in face-major blocks
    F = len(f)
    # order edges by first appearance over faces (face 0's three edges, face 1's, ...)
    edges = edges.reshape(3, F, 2).transpose(1, 0, 2).reshape(-1, 2)
    key = np.sort(edges, axis=1)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    # renumber unique edges by first appearance
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    mid_id = len(v) + rank[inverse].reshape(F, 3)  # midpoint of edges (01, 12, 20) per face
    uniq_sorted = key[np.sort(first)]
    mids = v[uniq_sorted[:, 0]] + v[uniq_sorted[:, 1]]
    mids /= np.linalg.norm(mids, axis=1, keepdims=True)
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    ab, bc, ca = mid_id[:, 0], mid_id[:, 1], mid_id[:, 2]
    nf = np.stack(
        [np.stack([a, ab, ca], 1), np.stack([b, bc, ab], 1), np.stack([c, ca, bc], 1), np.stack([ab, bc, ca], 1)],
        axis=1,
    ).reshape(-1, 3)
    return np.concatenate([v, mids]), nf


@lru_cache(maxsize=8)
def _icosphere_arrays(level: int) -> tuple[np.ndarray, np.ndarray]:
    v, f = _icosahedron()
    for _ in range(level):
        v, f = _subdivide(v, f)
    return v, f


def icosphere(level: int = PAPER_LEVEL, radius: float = TEMPLATE_RADIUS) -> Mesh:
    """The template sphere at a subdivision level (0..6); level 3 is the paper's 642-vertex sphere."""
    if not isinstance(level, (int, np.integer)) or not 0 <= level <= 6:
        raise ValueError(f"icosphere level must be an integer in [0, 6], got {level!r}")
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"icosphere radius must be finite and > 0, got {radius}")
    v, f = _icosphere_arrays(int(level))
    return Mesh(v * radius, f)


TEMPLATE_SHAPES = ("sphere", "legs")
"""Template shapes of :func:`template_mesh` (``sketchmesh bench fit --template``; the predictors deform the sphere).

``"sphere"`` is the paper's icosphere. ``"legs"`` is the same icosphere (same vertices, faces and vertex
order) with four cones pulled down from its lower half, one under each corner of the view: the test of
whether a start that already has legs lets a deformed genus-0 surface fit a chair or a table, which the
sphere does not (direct fit: voxel IoU 0.28 on a chair and 0.18 on a table where other categories reach
0.80-0.96). It does not (``fit-legs-v19``, model card). Only the vertex positions differ, so the mirror
pairing, the faces and everything that reads the topology stay those of the sphere.
"""

LEG_AZIMUTHS_DEG = (45.0, 135.0, 225.0, 315.0)
"""Azimuths (degrees, from +x towards +z) of the legs' centres: symmetric under x -> -x and z -> -z."""
LEG_POLAR_DEG = 135.0
"""Angle of each leg's centre from +y (up): 45 degrees below the equator."""
LEG_PATCH_DEG = 22.0
"""Angular radius of the patch of sphere each leg is made of (about 20 vertices at level 3)."""
LEG_DROP = 0.7
"""How far (in template radii) the tip of a leg is pulled down, straight along -y."""
LEG_SQUEEZE = 0.8
"""How much a patch is narrowed towards its centre at the tip (0: not, 1: to a point); below 1 the map
``r -> r (1 - s (1 - r / R))`` is monotonic, so no triangle folds."""


def template_mesh(level: int = PAPER_LEVEL, radius: float = TEMPLATE_RADIUS, shape: str = "sphere") -> Mesh:
    """The template of ``shape`` (:data:`TEMPLATE_SHAPES`) at an icosphere level: the icosphere's faces and
    vertex order, its vertex positions moved for ``"legs"`` (each leg: the patch within
    :data:`LEG_PATCH_DEG` of its centre, weight ``w = 1 - angle / patch``, narrowed by ``1 - LEG_SQUEEZE w``
    towards the centre and pulled down by ``LEG_DROP w`` radii)."""
    if shape not in TEMPLATE_SHAPES:
        raise ValueError(f"template shape must be one of {TEMPLATE_SHAPES}, got {shape!r}")
    sphere = icosphere(level, radius)
    if shape == "sphere":
        return sphere
    return Mesh(_legged_vertices(int(level), float(radius)), sphere.faces)


@lru_cache(maxsize=8)
def _legged_vertices(level: int, radius: float) -> np.ndarray:
    u, _ = _icosphere_arrays(level)  # unit sphere
    v = u * radius
    polar = np.radians(LEG_POLAR_DEG)
    for az in np.radians(LEG_AZIMUTHS_DEG):
        d = np.array([np.sin(polar) * np.cos(az), np.cos(polar), np.sin(polar) * np.sin(az)])
        angle = np.arccos(np.clip(u @ d, -1.0, 1.0))
        w = np.clip(1.0 - angle / np.radians(LEG_PATCH_DEG), 0.0, 1.0)[:, None]
        centre = radius * d
        moved = centre + (v - centre) * (1.0 - LEG_SQUEEZE * w) - w * np.array([0.0, LEG_DROP * radius, 0.0])
        v = np.where(w > 0, moved, v)
    v = v.astype(np.float32)
    v.setflags(write=False)
    return v


@lru_cache(maxsize=8)
def mirror_permutation(level: int = PAPER_LEVEL) -> np.ndarray:
    """(V,) int64: ``perm[i]`` is the vertex at vertex i's mirror image in the plane x = 0.

    The icosahedron and its edge midpoints are symmetric under x -> -x, so every template vertex
    has a partner (itself on the plane); ``perm`` is an involution. Read-only.
    """
    if not isinstance(level, (int, np.integer)) or not 0 <= level <= 6:
        raise ValueError(f"icosphere level must be an integer in [0, 6], got {level!r}")
    v, _ = _icosphere_arrays(int(level))
    keys = {tuple(k): i for i, k in enumerate(np.round(v, 9).tolist())}
    mirrored = np.round(v * np.array([-1.0, 1.0, 1.0]), 9) + 0.0  # + 0.0: no -0.0 keys
    try:
        perm = np.array([keys[tuple(k)] for k in mirrored.tolist()], dtype=np.int64)
    except KeyError as e:  # pragma: no cover - the construction is symmetric
        raise AssertionError(f"icosphere level {level} is not mirror-symmetric") from e
    perm.setflags(write=False)
    return perm


def mirror_average(plain: np.ndarray, flipped: np.ndarray) -> np.ndarray:
    """Average a view-frame prediction with the one made from the left-right mirrored drawing.

    Args:
        plain: (..., V, 3) template vertices as predicted from the drawing.
        flipped: (..., V, 3) as predicted from the drawing flipped left to right: a prediction of
            the shape's mirror image, whose vertex j sits near template vertex j.

    Returns:
        (..., V, 3): ``(plain + M flipped[perm]) / 2`` with ``M = diag(-1, 1, 1)`` (the flip of the
        image is x -> -x in the view frame, :mod:`engine.camera`) and ``perm`` the template's
        :func:`mirror_permutation`, so each vertex is averaged with its mirror partner's estimate.
    """
    plain = np.asarray(plain)
    flipped = np.asarray(flipped)
    if plain.shape != flipped.shape or plain.ndim < 2 or plain.shape[-1] != 3:
        raise ValueError(f"mirror_average needs two (..., V, 3) arrays of one shape, got {plain.shape} and {flipped.shape}")
    level = level_for_vertex_count(plain.shape[-2])
    back = flipped[..., mirror_permutation(level), :] * np.array([-1.0, 1.0, 1.0], dtype=flipped.dtype)
    return (plain + back) / 2


def level_for_vertex_count(num_vertices: int) -> int:
    """Inverse of the vertex count formula; raises ValueError for counts that are not an icosphere's."""
    for level in range(7):
        if 10 * 4**level + 2 == num_vertices:
            return level
    raise ValueError(f"{num_vertices} vertices is not an icosphere vertex count (162, 642, 2562, ...)")
