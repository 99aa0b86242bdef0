"""Post-processing a modeller expects: smoothing, subdivision, and self-intersection checks.

All functions are pure (Mesh in, new Mesh or numbers out), vectorised over vertices / faces /
edges with sparse adjacency, and keep the input's vertices first in the output (subdivision
appends new vertices after the old ones).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from engine.mesh import Mesh, adjacent_face_pairs, unique_edges

TAUBIN_LAMBDA = 0.5
TAUBIN_MU = -0.53
"""Taubin's lambda|mu pair: pass-band ~0.1, shrinks far less than Laplacian smoothing."""

MAX_SMOOTH_ITERATIONS = 10_000
MAX_SUBDIVIDE_FACES = 5_000_000
"""Largest face count :func:`subdivide` will produce (each level multiplies faces by 4)."""

INTERSECT_EPS = 1e-9
"""Relative tolerance (times the mesh's bounding-box diagonal, cubed for volumes) below which
an orientation counts as zero: touching or coplanar contacts are not counted as intersections."""


def _check_mesh(mesh) -> None:
    if not isinstance(mesh, Mesh):
        raise TypeError(f"expected an engine.mesh.Mesh, got {type(mesh).__name__}")


def _adjacency(num_vertices: int, faces: np.ndarray) -> sp.csr_matrix:
    """(V, V) symmetric 0/1 vertex adjacency from the unique edges."""
    e = unique_edges(faces)
    data = np.ones(2 * len(e))
    rows = np.concatenate([e[:, 0], e[:, 1]])
    cols = np.concatenate([e[:, 1], e[:, 0]])
    return sp.csr_matrix((data, (rows, cols)), shape=(num_vertices, num_vertices))


def smooth(
    mesh: Mesh,
    method: str = "taubin",
    iterations: int = 10,
    *,
    lam: float = TAUBIN_LAMBDA,
    mu: float = TAUBIN_MU,
) -> Mesh:
    """Umbrella-operator smoothing: ``v <- v + w * (mean(neighbours) - v)``.

    ``"laplacian"`` applies weight ``lam`` every iteration (shrinks the shape); ``"taubin"``
    alternates ``lam`` and ``mu`` (< 0) per iteration pair, which removes high-frequency bumps
    with little shrinkage. Vertices without neighbours stay put.

    Args:
        mesh: input mesh (V vertices, F faces).
        method: ``"taubin"`` or ``"laplacian"``.
        iterations: number of smoothing steps (>= 0); for Taubin each step is one lambda and one mu pass.
        lam: positive step weight in (0, 1].
        mu: negative Taubin weight with ``-1 <= mu < -lam``.

    Returns:
        A new Mesh with the same faces and (V, 3) smoothed vertices.
    """
    _check_mesh(mesh)
    if method not in ("taubin", "laplacian"):
        raise ValueError(f"smooth method must be 'taubin' or 'laplacian', got {method!r}")
    if not isinstance(iterations, (int, np.integer)) or not 0 <= iterations <= MAX_SMOOTH_ITERATIONS:
        raise ValueError(f"iterations must be an int in [0, {MAX_SMOOTH_ITERATIONS}], got {iterations!r}")
    if not (np.isfinite(lam) and 0.0 < lam <= 1.0):
        raise ValueError(f"lam must be in (0, 1], got {lam}")
    if method == "taubin" and not (np.isfinite(mu) and -1.0 <= mu < -lam):
        raise ValueError(f"mu must be in [-1, -lam) = [-1, {-lam}), got {mu}")
    if iterations == 0 or mesh.num_faces == 0:
        return mesh
    A = _adjacency(mesh.num_vertices, mesh.faces)
    deg = np.asarray(A.sum(axis=1)).ravel()
    inv = np.where(deg > 0, 1.0 / np.maximum(deg, 1.0), 0.0)
    M = sp.diags(inv) @ A  # row-normalised: (M @ v)[i] = mean of i's neighbours
    has = (deg > 0)[:, None]
    v = mesh.vertices.astype(np.float64)
    weights = [lam] if method == "laplacian" else [lam, mu]
    for _ in range(int(iterations)):
        for w in weights:
            v = np.where(has, v + w * (M @ v - v), v)
    return mesh.with_vertices(v.astype(np.float32))


def _edge_table(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique edges (E, 2) and, per face, the edge index of its (01, 12, 20) edges: (F, 3)."""
    f = np.asarray(faces, dtype=np.int64)
    F = len(f)
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = np.sort(directed, axis=1)
    edges, inverse = np.unique(key, axis=0, return_inverse=True)
    return edges, inverse.reshape(3, F).T


def _midpoint_step(v: np.ndarray, f: np.ndarray, loop: bool) -> tuple[np.ndarray, np.ndarray]:
    V = len(v)
    edges, face_edges = _edge_table(f)
    E = len(edges)
    if loop:
        # opposite vertex of each (face, edge) slot; interior edges have two
        opp = np.stack([f[:, 2], f[:, 0], f[:, 1]], axis=1)  # opposite of edge 01 is 2, of 12 is 0, of 20 is 1
        opp_sum = np.zeros((E, 3))
        count = np.zeros(E)
        np.add.at(opp_sum, face_edges.ravel(), v[opp.ravel()])
        np.add.at(count, face_edges.ravel(), 1.0)
        ends = v[edges[:, 0]] + v[edges[:, 1]]
        interior = (count == 2)[:, None]
        new_edge = np.where(interior, 0.375 * ends + 0.125 * opp_sum, 0.5 * ends)
        # old vertices: Loop's beta on interior vertices, 3/4 + 1/8 + 1/8 on boundary vertices
        boundary_edges = edges[count != 2]
        A = _adjacency(V, f)
        k = np.asarray(A.sum(axis=1)).ravel()
        nsum = A @ v
        with np.errstate(divide="ignore", invalid="ignore"):
            beta = np.where(k > 0, (40.0 - (2.0 * np.cos(2.0 * np.pi / np.maximum(k, 1)) + 3.0) ** 2) / (64.0 * np.maximum(k, 1)), 0.0)
        new_old = (1.0 - k * beta)[:, None] * v + beta[:, None] * nsum
        if len(boundary_edges):
            bsum = np.zeros_like(v)
            bcount = np.zeros(V)
            np.add.at(bsum, boundary_edges[:, 0], v[boundary_edges[:, 1]])
            np.add.at(bsum, boundary_edges[:, 1], v[boundary_edges[:, 0]])
            np.add.at(bcount, boundary_edges.ravel(), 1.0)
            on_b = bcount == 2
            new_old[on_b] = 0.75 * v[on_b] + 0.125 * bsum[on_b]
            corner = (bcount > 0) & ~on_b  # non-manifold boundary corners stay put
            new_old[corner] = v[corner]
        v_old = new_old
    else:
        new_edge = 0.5 * (v[edges[:, 0]] + v[edges[:, 1]])
        v_old = v
    mid = V + face_edges  # (F, 3): vertex ids of midpoints of edges 01, 12, 20
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    ab, bc, ca = mid[:, 0], mid[:, 1], mid[:, 2]
    nf = np.stack(
        [np.stack([a, ab, ca], 1), np.stack([b, bc, ab], 1), np.stack([c, ca, bc], 1), np.stack([ab, bc, ca], 1)], axis=1
    ).reshape(-1, 3)
    return np.concatenate([v_old, new_edge]), nf


def subdivide(mesh: Mesh, levels: int = 1, method: str = "loop") -> Mesh:
    """Split every triangle into four, ``levels`` times.

    ``"midpoint"`` inserts edge midpoints (shape unchanged); ``"loop"`` is Loop subdivision
    (Loop's original beta, the 3/8-1/8 edge rule, 3/4-1/8 on boundaries), which converges to a
    smooth surface and shrinks convex shapes slightly. The V old vertices come first, then one
    vertex per unique edge; faces keep the input's winding.

    Args:
        mesh: input mesh (V, F).
        levels: number of subdivisions (>= 0); F grows as F * 4**levels.
        method: ``"loop"`` or ``"midpoint"``.

    Returns:
        A new Mesh with F * 4**levels faces.
    """
    _check_mesh(mesh)
    if method not in ("loop", "midpoint"):
        raise ValueError(f"subdivide method must be 'loop' or 'midpoint', got {method!r}")
    if not isinstance(levels, (int, np.integer)) or levels < 0:
        raise ValueError(f"levels must be an int >= 0, got {levels!r}")
    if mesh.num_faces * 4**levels > MAX_SUBDIVIDE_FACES:
        raise ValueError(
            f"{levels} subdivision levels would make {mesh.num_faces * 4**levels} faces, over the limit of {MAX_SUBDIVIDE_FACES}"
        )
    v = mesh.vertices.astype(np.float64)
    f = mesh.faces
    for _ in range(int(levels)):
        if len(f) == 0:
            break
        v, f = _midpoint_step(v, f, method == "loop")
    return Mesh(v.astype(np.float32), f)


def _cross(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row-wise cross product of (N, 3) arrays as its three (N,) components (np.cross's axis handling
    cost as much as the arithmetic at the sizes of a self-intersection check)."""
    u0, u1, u2 = u.T
    v0, v1, v2 = v.T
    return u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0


def _dot(n: tuple[np.ndarray, np.ndarray, np.ndarray], w: np.ndarray) -> np.ndarray:
    """(N,) row-wise dot product of :func:`_cross`'s components with (N, 3) ``w``."""
    w0, w1, w2 = w.T
    return n[0] * w0 + n[1] * w1 + n[2] * w2


def _orient(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(N,) signed volume det[b - a, c - a, d - a] (6 x tetrahedron volume)."""
    return _dot(_cross(b - a, c - a), d - a)


def _segment_crosses_triangle(p, q, a, b, c, eps) -> np.ndarray:
    """(N,) bool: segment pq properly crosses triangle abc (strictly, up to ``eps``): the definition
    :func:`triangles_intersect` evaluates in bulk, kept as its reference (tests check they agree).

    The endpoints lie strictly on opposite sides of the triangle's plane and the line pq passes
    strictly inside the triangle (the three edge orientations share a sign).
    """
    sp_ = _orient(a, b, c, p)
    sq = _orient(a, b, c, q)
    straddle = ((sp_ > eps) & (sq < -eps)) | ((sp_ < -eps) & (sq > eps))
    o1 = _orient(p, q, a, b)
    o2 = _orient(p, q, b, c)
    o3 = _orient(p, q, c, a)
    inside = ((o1 > eps) & (o2 > eps) & (o3 > eps)) | ((o1 < -eps) & (o2 < -eps) & (o3 < -eps))
    return straddle & inside


def triangles_intersect(t1: np.ndarray, t2: np.ndarray, eps: float = 0.0) -> np.ndarray:
    """Vectorised narrow phase: do triangle pairs cross (non-coplanar, transversal intersection)?

    Two non-coplanar triangles intersect iff an edge of one crosses the other. Contacts within
    ``eps`` (touching at a vertex or edge, coplanar overlap) are not counted.

    Args:
        t1, t2: (N, 3, 3) float64 triangle corners.
        eps: orientation tolerance (a volume; see :data:`INTERSECT_EPS`).

    Returns:
        (N,) bool.
    """
    t1 = np.asarray(t1, dtype=np.float64)
    t2 = np.asarray(t2, dtype=np.float64)
    if t1.shape != t2.shape or t1.ndim != 3 or t1.shape[1:] != (3, 3):
        raise ValueError(f"triangles must both be (N, 3, 3), got {t1.shape} and {t2.shape}")
    # each corner's side of the other triangle's plane, its normal computed once: the same predicate as
    # _segment_crosses_triangle's straddle test. Early out: a triangle whose three corners lie strictly on one side
    # of the other's plane cannot cross it (most broad-phase pairs are neighbours of neighbours, rejected here)
    sides = []
    for s, t in ((t1, t2), (t2, t1)):
        normal = _cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        sides.append(np.stack([_dot(normal, s[:, k] - t[:, 0]) for k in range(3)], axis=1))
    live = np.ones(len(t1), dtype=bool)
    for side in sides:
        live &= ~(np.all(side > eps, axis=1) | np.all(side < -eps, axis=1))
    hit = np.zeros(len(t1), dtype=bool)
    idx = np.flatnonzero(live)
    if len(idx) == 0:
        return hit
    found = np.zeros(len(idx), dtype=bool)
    for s, t, side in ((t1[idx], t2[idx], sides[0][idx]), (t2[idx], t1[idx], sides[1][idx])):
        for i, j in ((0, 1), (1, 2), (2, 0)):
            # edge ij crosses t: its ends strictly on opposite sides of t's plane, then (only for those) the line
            # strictly inside t (_segment_crosses_triangle's definition, evaluated where it can still hold)
            sp_, sq = side[:, i], side[:, j]
            k = np.flatnonzero(((sp_ > eps) & (sq < -eps)) | ((sp_ < -eps) & (sq > eps)))
            if len(k) == 0:
                continue
            p, q, a, b, c = s[k, i], s[k, j], t[k, 0], t[k, 1], t[k, 2]
            o1, o2, o3 = _orient(p, q, a, b), _orient(p, q, b, c), _orient(p, q, c, a)
            found[k] |= ((o1 > eps) & (o2 > eps) & (o3 > eps)) | ((o1 < -eps) & (o2 < -eps) & (o3 < -eps))
    hit[idx] = found
    return hit


MAX_GRID_ENTRIES_PER_FACE = 64
"""Broad-phase budget: the grid cell grows until the (face, cell) entries stay below this times F."""


def _pairs_within_groups(group_start: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """All index pairs (p, q), p < q, inside consecutive groups of a length-n sorted array.

    Args:
        group_start: (n,) index of the first element of each element's group.
    """
    group_end = np.empty(n, np.int64)  # one past the last element of each element's group
    starts = np.flatnonzero(np.r_[True, group_start[1:] != group_start[:-1]])
    ends = np.r_[starts[1:], n]
    group_end[:] = np.repeat(ends, ends - starts)
    count = group_end - np.arange(n) - 1
    first = np.repeat(np.arange(n), count)
    offs = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    return first, first + 1 + offs


def candidate_pairs(mesh: Mesh) -> np.ndarray:
    """Broad phase: face pairs (i < j) whose bounding boxes overlap and that share no vertex.

    A uniform grid (cell ~ the median face size): each face is entered in every cell its box
    touches, pairs are formed only inside cells (vectorised with sort + repeat) and box-tested.
    Two overlapping boxes share every cell of their intersection; a pair is kept only in the one
    cell holding the larger of the two boxes' low corners (inside both boxes' cell ranges when
    they overlap), so no deduplication pass is needed. The work scales with F times the local
    face density, not F^2.

    Returns:
        (P, 2) int64 face index pairs, i < j, unique, sorted.
    """
    _check_mesh(mesh)
    if mesh.num_faces < 2:
        return np.zeros((0, 2), np.int64)
    tri = mesh.vertices.astype(np.float64)[mesh.faces]
    return _grid_pairs(tri.min(axis=1), tri.max(axis=1), mesh.faces)


def _grid_pairs(lo: np.ndarray, hi: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """:func:`candidate_pairs` of the faces (F, 3) with boxes ``lo``, ``hi`` (F, 3): index pairs into these rows."""
    F = len(faces)
    if F < 2:
        return np.zeros((0, 2), np.int64)
    origin = lo.min(axis=0)
    span = float(np.max(hi.max(axis=0) - origin))
    cell = max(float(np.median(np.max(hi - lo, axis=1))), span * 1e-6, 1e-300)
    while True:
        c0 = np.floor((lo - origin) / cell).astype(np.int64)
        c1 = np.floor((hi - origin) / cell).astype(np.int64)
        n = c1 - c0 + 1  # (F, 3) cells per axis
        per_face = n.prod(axis=1)
        if per_face.sum() <= MAX_GRID_ENTRIES_PER_FACE * F:
            break
        cell *= 2.0
    face = np.repeat(np.arange(F), per_face)
    k = np.arange(per_face.sum()) - np.repeat(np.cumsum(per_face) - per_face, per_face)
    nf = n[face]
    ix = c0[face, 0] + k % nf[:, 0]
    iy = c0[face, 1] + (k // nf[:, 0]) % nf[:, 1]
    iz = c0[face, 2] + k // (nf[:, 0] * nf[:, 1])
    dims = c1.max(axis=0) + 1
    cell_id = (ix * dims[1] + iy) * dims[2] + iz
    order = np.argsort(cell_id, kind="stable")
    cell_sorted, face_sorted = cell_id[order], face[order]
    start_of = np.flatnonzero(np.r_[True, cell_sorted[1:] != cell_sorted[:-1]])
    group_start = np.repeat(start_of, np.diff(np.r_[start_of, len(cell_sorted)]))
    p, q = _pairs_within_groups(group_start, len(cell_sorted))
    # the reference cell (the max of the two low corners' cells, per axis) is the pair's cell when, on every axis, the
    # cell is one of the two faces' low corner cell: a 3-bit flag per entry, so the duplicates go before any box test
    low = ((ix == c0[face, 0]) * 1 | (iy == c0[face, 1]) * 2 | (iz == c0[face, 2]) * 4)[order]
    keep = np.flatnonzero((low[p] | low[q]) == 7)
    i, j = face_sorted[p[keep]], face_sorted[q[keep]]
    ok = np.ones(len(i), bool)
    for a in range(3):  # per axis: (N,)-vector ops, no (N, 3) reductions
        lo_a, hi_a = lo[:, a], hi[:, a]
        ok &= (lo_a[i] <= hi_a[j]) & (lo_a[j] <= hi_a[i])
    i, j = i[ok], j[ok]
    fi, fj = faces[i], faces[j]
    share = np.zeros(len(i), bool)
    for a in range(3):  # nine (N,) comparisons: far faster than one (N, 3, 3) comparison reduced over two axes
        for b in range(3):
            share |= fi[:, a] == fj[:, b]
    i, j = i[~share], j[~share]
    key = np.sort(np.minimum(i, j) * F + np.maximum(i, j))  # 1-D keys sort far faster than rows
    return np.stack([key // F, key % F], axis=1).astype(np.int64)


def candidate_pairs_bruteforce(mesh: Mesh) -> np.ndarray:
    """Slow O(F^2) reference of :func:`candidate_pairs` (for tests): same output, all pairs box-tested."""
    tri = mesh.vertices.astype(np.float64)[mesh.faces]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    i, j = np.triu_indices(mesh.num_faces, 1)
    ok = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
    i, j = i[ok], j[ok]
    share = np.any(mesh.faces[i][:, :, None] == mesh.faces[j][:, None, :], axis=(1, 2))
    return np.stack([i[~share], j[~share]], axis=1).astype(np.int64)


def _candidate_pairs_of(mesh: Mesh, faces: np.ndarray) -> np.ndarray:
    """:func:`candidate_pairs` restricted to the pairs with at least one face among ``faces`` (int indices): the grid
    of :func:`candidate_pairs` over only the faces whose boxes overlap the box around those faces (no other face can
    meet one of them), so a check after a local change costs what the change's neighbourhood holds.

    Returns:
        (P, 2) int64 face index pairs, i < j, unique, sorted.
    """
    faces = np.unique(np.asarray(faces, np.int64))
    if mesh.num_faces < 2 or len(faces) == 0:
        return np.zeros((0, 2), np.int64)
    tri = mesh.vertices.astype(np.float64)[mesh.faces]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    box_lo, box_hi = lo[faces].min(axis=0), hi[faces].max(axis=0)
    near = np.flatnonzero(np.all((lo <= box_hi) & (hi >= box_lo), axis=1))  # the listed faces among them
    pairs = near[_grid_pairs(lo[near], hi[near], mesh.faces[near])]  # near is sorted: pairs stay i < j, sorted
    listed = np.zeros(mesh.num_faces, bool)
    listed[faces] = True
    return pairs[listed[pairs].any(axis=1)]


def intersecting_pairs(mesh: Mesh, faces: np.ndarray | None = None) -> np.ndarray:
    """(P, 2) int64 pairs of faces (sharing no vertex) that cross each other; see :func:`self_intersections`.

    ``faces`` (int indices) limits the check to the pairs with at least one of those faces (the ones that moved:
    two faces that did not move cross or not as before)."""
    _check_mesh(mesh)
    pairs = candidate_pairs(mesh) if faces is None else _candidate_pairs_of(mesh, faces)
    if len(pairs) == 0:
        return pairs
    v = mesh.vertices.astype(np.float64)
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))) if len(v) else 0.0
    eps = INTERSECT_EPS * max(diag, 1e-300) ** 3
    tri = v[mesh.faces]
    hit = triangles_intersect(tri[pairs[:, 0]], tri[pairs[:, 1]], eps)
    return pairs[hit]


def self_intersections(mesh: Mesh) -> int:
    """Number of pairs of non-adjacent faces (sharing no vertex) that intersect.

    Broad phase: axis-aligned bounding boxes on a uniform grid. Narrow phase: edge-triangle
    crossings with orientation predicates in float64 and a scale-relative tolerance, so
    touching contacts and coplanar overlaps are not counted (a predicted mesh from a sphere
    template has no coplanar non-adjacent faces in practice).
    """
    return int(len(intersecting_pairs(mesh)))


REPAIR_ROUNDS = 30
"""Most check-and-smooth rounds :func:`repair_self_intersections` runs before it gives up."""
REPAIR_STEPS = 1
"""Umbrella steps per round on the crossing region: one, so each round moves only what still crosses."""
REPAIR_WEIGHT = 0.5
"""Umbrella step weight: each step moves a region vertex half way to its neighbours' mean."""


@dataclass(frozen=True)
class RepairResult:
    """What :func:`repair_self_intersections` did.

    Attributes:
        mesh: the repaired mesh (the input object itself when it had no self-intersection).
        before: crossing face pairs in the input.
        after: crossing face pairs in ``mesh`` (0 unless the rounds ran out).
        rounds: smoothing rounds run (0 for a mesh without crossings).
        moved: vertices that moved.
    """

    mesh: Mesh
    before: int
    after: int
    rounds: int
    moved: int


def repair_folds(mesh: Mesh, crossings: int | None = None) -> RepairResult:
    """The fold repair the engine runs on the mesh it returns (:func:`repair_self_intersections` with its defaults),
    skipped when ``crossings`` is a count of ``mesh``'s crossing face pairs just made and is 0 (the refinement counts
    them on the mesh it returns, :attr:`engine.refine.RefineResult.crossings`): the same result, one check fewer."""
    if crossings == 0:
        _check_mesh(mesh)
        return RepairResult(mesh, 0, 0, 0, 0)
    return repair_self_intersections(mesh)


def repair_self_intersections(mesh: Mesh, rounds: int = REPAIR_ROUNDS, steps: int = REPAIR_STEPS,
                              weight: float = REPAIR_WEIGHT) -> RepairResult:
    """Remove self-intersections by smoothing only where the surface crosses itself.

    A predicted mesh folds where a thin part (a lamp's stem, a rifle's barrel) is squeezed until
    its rings of faces pass through each other; the fix is to untwist the fold, not to smooth the
    whole shape (global Taubin smoothing barely touches a fold at all). Each round takes the
    vertices of every face that still crosses another plus one ring of neighbours, moves them
    ``steps`` times part way (``weight``) towards their neighbours' mean, and checks the whole mesh
    again (:func:`intersecting_pairs`). Only what still crosses moves: a region kept from round to
    round, or several steps a round, untangles in fewer checks but shrinks thin parts several times
    as much (measured on the tenth pair's test predictions: README, "Repairing folds").

    Work follows what is wrong: a mesh without crossings costs one check and comes back as the
    same object. If ``rounds`` run out with crossings left, the state with the fewest is returned
    (``after`` says how many). Umbrella steps are affine-invariant, so the result scales with the
    mesh (the check's tolerance is relative to its size); vertices without neighbours stay put.

    Args:
        mesh: input mesh.
        rounds: most rounds (>= 0; 0 only counts).
        steps: umbrella steps per round (>= 1).
        weight: step weight in (0, 1].

    Returns:
        A :class:`RepairResult`.
    """
    _check_mesh(mesh)
    if not isinstance(rounds, (int, np.integer)) or isinstance(rounds, bool) or rounds < 0:
        raise ValueError(f"rounds must be an int >= 0, got {rounds!r}")
    if not isinstance(steps, (int, np.integer)) or isinstance(steps, bool) or steps < 1:
        raise ValueError(f"steps must be an int >= 1, got {steps!r}")
    if not (isinstance(weight, (int, float, np.floating)) and 0.0 < float(weight) <= 1.0):
        raise ValueError(f"weight must be in (0, 1], got {weight!r}")
    pairs = intersecting_pairs(mesh)
    before = len(pairs)
    if before == 0 or rounds == 0:
        return RepairResult(mesh, before, before, 0, 0)
    f = mesh.faces
    v = mesh.vertices.astype(np.float64)
    adj = _adjacency(len(v), f)
    deg = np.asarray(adj.sum(axis=1)).ravel()
    out_dtype = mesh.vertices.dtype if np.issubdtype(mesh.vertices.dtype, np.floating) else np.float64
    best = (before, mesh)
    done = 0
    while done < rounds:
        done += 1
        region = np.zeros(len(v), bool)
        region[f[pairs.ravel()]] = True
        region |= (adj @ region.astype(np.float64)) > 0
        idx = np.flatnonzero(region & (deg > 0))
        sub = adj[idx]
        for _ in range(steps):
            v[idx] += float(weight) * ((sub @ v) / deg[idx, None] - v[idx])
        trial = mesh.with_vertices(v.astype(out_dtype))
        # every crossing face lies in the region, so a pair of faces outside it did not cross and still does not:
        # only pairs with a face that moved need checking again (work follows the fold, not the mesh)
        moved = region & (deg > 0)
        pairs = intersecting_pairs(trial, np.flatnonzero(moved[f].any(axis=1)))
        if len(pairs) < best[0]:
            best = (len(pairs), trial)
        if len(pairs) == 0:
            break
    out = best[1]
    moved = int(np.count_nonzero(np.any(out.vertices != mesh.vertices, axis=1)))
    return RepairResult(out, before, best[0], done, moved)


def mesh_stats(mesh: Mesh) -> dict:
    """Modeller-facing numbers: counts, watertightness, consistent winding, area, volume, intersections.

    ``watertight``: every edge is shared by exactly two faces; ``winding_consistent``: each shared
    edge is traversed in opposite directions by its two faces.
    """
    _check_mesh(mesh)
    f = mesh.faces
    _, face_edges = _edge_table(f) if len(f) else (None, np.zeros((0, 3), np.int64))
    counts = np.bincount(face_edges.ravel()) if len(f) else np.zeros(0, np.int64)
    watertight = bool(len(f) > 0 and np.all(counts == 2))
    pairs, edges = adjacent_face_pairs(f) if len(f) else (np.zeros((0, 2), np.int64), np.zeros((0, 2), np.int64))
    consistent = True
    if len(pairs):
        # the second face must contain the edge as (b, a)
        g = f[pairs[:, 1]]
        a, b = edges[:, 0], edges[:, 1]
        nxt = np.roll(g, -1, axis=1)
        rev = np.any((g == b[:, None]) & (nxt == a[:, None]), axis=1)
        consistent = bool(np.all(rev))
    v = mesh.vertices.astype(np.float64)
    tri = v[f]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = float(0.5 * np.linalg.norm(cross, axis=1).sum())
    volume = float(np.einsum("ij,ij->i", tri[:, 0], cross).sum() / 6.0)
    return {
        "vertices": mesh.num_vertices,
        "faces": mesh.num_faces,
        "watertight": watertight,
        "winding_consistent": consistent,
        "area": area,
        "volume": volume if watertight else None,
        "self_intersections": self_intersections(mesh),
    }
