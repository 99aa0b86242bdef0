"""The mesh value type that crosses every layer, and functions deriving from it.

Conventions (frames, normalisation) are in :mod:`engine.camera`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Mesh:
    """An immutable triangle mesh.

    Attributes:
        vertices: (V, 3) float32, finite.
        faces: (F, 3) int64, each index in [0, V), counter-clockwise seen from outside.

    Construction validates shapes, dtypes (converting where lossless), finiteness and
    index range, and raises ``ValueError`` naming what it received. The arrays are made
    read-only so a Mesh can be shared between threads. Derived values (normals, bounds)
    are computed by functions, never stored.
    """

    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices)
        f = np.asarray(self.faces)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"Mesh vertices must be (V, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"Mesh faces must be (F, 3), got {f.shape}")
        if not np.issubdtype(v.dtype, np.floating) and not np.issubdtype(v.dtype, np.integer):
            raise ValueError(f"Mesh vertices must be numeric, got {v.dtype}")
        if f.size and not np.issubdtype(f.dtype, np.integer):
            if not np.all(np.mod(f, 1) == 0):
                raise ValueError(f"Mesh faces must be integer indices, got {f.dtype}")
        v = np.array(v, dtype=np.float32)
        f = np.array(f, dtype=np.int64).reshape(-1, 3)
        if not np.all(np.isfinite(v)):
            raise ValueError("Mesh vertices contain NaN or inf")
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise ValueError(f"Mesh face indices must be in [0, {len(v)}), got range [{f.min()}, {f.max()}]")
        v.setflags(write=False)
        f.setflags(write=False)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)

    @property
    def num_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def num_faces(self) -> int:
        return int(self.faces.shape[0])

    def with_vertices(self, vertices: np.ndarray) -> Mesh:
        """A new Mesh with the same faces and new (V, 3) vertices."""
        v = np.asarray(vertices)
        if v.shape != self.vertices.shape:
            raise ValueError(f"new vertices must be {self.vertices.shape}, got {v.shape}")
        return Mesh(v, self.faces)


def face_normals(vertices: np.ndarray, faces: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    """(F, 3) unit face normals (right-hand rule over the face's vertex order).

    Zero-area faces get a zero normal instead of NaN.
    """
    v = np.asarray(vertices, dtype=np.float64)
    tri = v[np.asarray(faces)]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(length > eps, n / np.maximum(length, eps), 0.0)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    """(V, 3) unit vertex normals: area-weighted sum of incident face normals.

    Vertices with no incident (non-degenerate) face get a zero normal.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length = 2 * area
    acc = np.zeros_like(v)
    for k in range(3):
        np.add.at(acc, f[:, k], n)
    length = np.linalg.norm(acc, axis=1, keepdims=True)
    return np.where(length > eps, acc / np.maximum(length, eps), 0.0)


def bounds(vertices: np.ndarray) -> np.ndarray:
    """(2, 3) axis-aligned bounding box: [min, max]."""
    v = np.asarray(vertices)
    return np.stack([v.min(axis=0), v.max(axis=0)])


def unique_edges(faces: np.ndarray) -> np.ndarray:
    """(E, 2) int64 undirected edges, each once, sorted (i < j), in a deterministic order."""
    f = np.asarray(faces, dtype=np.int64)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    e = np.sort(e, axis=1)
    return np.unique(e, axis=0)


def is_closed(faces: np.ndarray) -> bool:
    """Whether triangles (F, 3) form a closed, consistently oriented surface: every directed edge appears once and
    its reverse once (each edge in exactly two faces, which run along it in opposite directions)."""
    f = np.asarray(faces, np.int64)
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        return False
    a = f.ravel()
    b = np.roll(f, -1, axis=1).ravel()
    if np.any(a == b):
        return False
    n = int(f.max()) + 1
    fwd = np.sort(a * n + b)
    if np.any(fwd[1:] == fwd[:-1]):  # a directed edge twice: not manifold or not consistently oriented
        return False
    return bool(np.array_equal(fwd, np.sort(b * n + a)))


def adjacent_face_pairs(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of faces sharing an edge, for the dihedral smoothness loss.

    Returns:
        pairs: (P, 2) int64 face indices (f0, f1).
        edges: (P, 2) int64 the shared edge's vertex indices (a, b), ordered as in f0's winding.
    Concretely, ``pairs[p] = (f0, f1)`` means faces f0 and f1 share edge ``edges[p]``.
    Edges shared by more than two faces (non-manifold) contribute every pair.
    """
    f = np.asarray(faces, dtype=np.int64)
    F = len(f)
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    face_id = np.tile(np.arange(F), 3)
    key = np.sort(directed, axis=1)
    order = np.lexsort((face_id, key[:, 1], key[:, 0]))
    key, directed, face_id = key[order], directed[order], face_id[order]
    same = np.all(key[1:] == key[:-1], axis=1)
    idx = np.nonzero(same)[0]
    pairs = np.stack([face_id[idx], face_id[idx + 1]], axis=1)
    edges = directed[idx]
    return pairs, edges
