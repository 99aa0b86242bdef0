"""Line drawings of a mesh, as an artist would draw them: contours, creases, suggestive contours.

Three kinds of lines (kind codes in :data:`LINE_KINDS`):

* **Occluding contours**: mesh edges between a front-facing and a back-facing face (and
  open boundary edges). Front-facing uses the perspective view vector from the face
  centroid to the camera centre.
* **Creases**: edges whose two face normals differ by more than ``crease_angle_deg``
  (convex and concave), when at least one of the faces is front-facing.
* **Suggestive contours** (DeCarlo et al., "Suggestive Contours for Conveying Shape", 2003):
  on front-facing faces, the zero set of the radial curvature
  ``kappa_r = w^T II w / |w|^2`` (``w`` = the view vector projected onto the tangent plane,
  ``II`` the per-vertex second fundamental form) where its directional derivative along
  ``w`` is positive, filtered as in the paper by ``D_w kappa_r / |w| > t_d`` and
  ``angle(n, v) > theta_c``. The per-vertex curvature tensor follows Rusinkiewicz
  ("Estimating curvatures and their derivatives on triangle meshes", 2004): a least-squares
  fit per face of the change of vertex normals along the edges, lifted to a 3x3 tensor,
  area-averaged at the vertices and projected onto each vertex's tangent plane. Faces that
  touch a crease are excluded (their averaged normals are not a smooth surface's).

Hidden-line removal uses the rasterizer's depth buffer: each candidate segment is split into
pieces about ``sample_spacing_px`` long and a piece is kept if its midpoint is not behind the
z-buffer: ``depth <= max(depth over the 3x3 pixel neighbourhood) + depth_tolerance`` (or the
neighbourhood touches the background). Work scales with what is visible, not with hidden
geometry: faces are bucketed once per mesh into a coarse grid of cells, and a view first culls
every cell whose bounding box lies entirely behind the z-buffer (a max-pooling pyramid of the
depth buffer, conservative); contours are searched only among the faces of the remaining
cells, and creases, boundaries and suggestive contours only on the faces seen in
``face_index`` (dilated by one vertex ring so sub-pixel faces next to seen ones count).

Coordinates: polylines are (N, 2) float64 **continuous pixel coordinates (x = col, y = row)**
as :func:`engine.camera.ndc_to_pixel` gives them (pixel centres at k + 0.5). Rasters follow
:mod:`engine.camera`: (H, W) float32 in [0, 1], **1 = ink**.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.camera import Camera, ndc_to_pixel, project
from engine.contract import SKETCH_STROKE_WIDTH_PX
from engine.mesh import Mesh, face_normals, vertex_normals

KIND_CONTOUR, KIND_CREASE, KIND_SUGGESTIVE, KIND_BOUNDARY = 0, 1, 2, 3
LINE_KINDS = {KIND_CONTOUR: "contour", KIND_CREASE: "crease", KIND_SUGGESTIVE: "suggestive", KIND_BOUNDARY: "boundary"}

WELD_TOLERANCE = 1e-6
"""Vertices closer than this (normalised units) are welded for topology (ShapeNet meshes are split at UV seams)."""
FRONT_EPS = 1e-12
"""A face is front-facing when n . (camera - centroid) > FRONT_EPS (degenerate faces count as back-facing)."""
W_EPS = 1e-8
"""|w|^2 below this (view nearly along the normal) leaves kappa_r undefined; such vertices draw no suggestive contour."""
PRECULL_SAMPLES = 5
"""Points per contour edge in the cheap hidden-contour pre-cull (ends, quarters, middle)."""
CELL_GRID = 8
"""Faces are bucketed into CELL_GRID^3 cells; a view skips cells entirely behind its z-buffer."""
WIDTH_DECIMALS = 2
"""Per-stroke widths and inks are rounded to this many decimals to batch strokes into few draw calls."""


@dataclass(frozen=True)
class LineSettings:
    """What to draw and the thresholds (angles in degrees, lengths in pixels of the output image).

    Attributes:
        crease_angle_deg: an edge is a crease when its face normals differ by more than this.
        suggestive: draw suggestive contours.
        sc_theta_c_deg: DeCarlo's theta_c: no suggestive contour where angle(n, v) < theta_c.
        sc_threshold: DeCarlo's t_d on ``D_w kappa_r / |w|`` (normalised shape units, 1/length^2).
        sc_min_curvature: optional extra filter (0 = off): a face holds a suggestive contour only if
            kappa_r < -sc_min_curvature at one of its vertices (1/length). Off by default: it breaks
            the zero set into pieces, and flat parts are already quiet because faces touching a
            crease do not contribute to the curvature estimate.
        sc_min_length_px: suggestive-contour polylines shorter than this (pixels at 256, scaled with the
            image size) are dropped: short ones are curvature-estimation noise.
        sc_smoothing: one-ring smoothing passes of kappa_r before its zero set is taken.
        depth_tolerance: hidden-line depth slack in camera units (the shape spans 1).
        sample_spacing_px: length of the pieces tested against the z-buffer.
        min_length_px: polylines shorter than this are dropped (specks).
    """

    crease_angle_deg: float = 40.0
    suggestive: bool = True
    sc_theta_c_deg: float = 20.0
    sc_threshold: float = 1.0
    sc_min_curvature: float = 0.0
    sc_min_length_px: float = 6.0
    sc_smoothing: int = 2
    depth_tolerance: float = 0.01
    sample_spacing_px: float = 1.0
    min_length_px: float = 2.0

    def __post_init__(self) -> None:
        if not 0.0 < self.crease_angle_deg < 180.0:
            raise ValueError(f"crease_angle_deg must be in (0, 180), got {self.crease_angle_deg}")
        if not (self.sample_spacing_px > 0 and np.isfinite(self.sample_spacing_px)):
            raise ValueError(f"sample_spacing_px must be > 0, got {self.sample_spacing_px}")
        if not (self.depth_tolerance >= 0 and np.isfinite(self.depth_tolerance)):
            raise ValueError(f"depth_tolerance must be >= 0, got {self.depth_tolerance}")


@dataclass(frozen=True, eq=False)
class MeshLineData:
    """View-independent data for line drawing, computed once per mesh by :func:`prepare_mesh`.

    Attributes:
        vertices: (V, 3) float64 welded vertices.
        faces: (F, 3) int64 faces over the welded vertices (same order as the input faces).
        edges: (E, 2) int64 unique edges (i < j).
        edge_faces: (E, 2) int64 the (up to) two faces of each edge; -1 for a boundary edge.
            Concretely, ``edge_faces[e] = (f0, f1)`` means edge e lies on faces f0 and f1.
        face_edges: (F, 3) int64 edge ids of each face's edges (01, 12, 20).
        face_normals: (F, 3) float64 unit normals (zero for degenerate faces).
        face_centroids: (F, 3) float64.
        vertex_normals: (V, 3) float64 unit area-weighted vertex normals.
        crease: (E,) bool, normals differ by more than the crease angle.
        smooth_face: (F,) bool, the face touches no crease or boundary vertex.
        curvature: (V, 3, 3) float64 second fundamental form lifted to 3D (tangent-plane projected).
        vf_ptr, vf_idx: CSR vertex -> incident faces (faces of vertex i are vf_idx[vf_ptr[i]:vf_ptr[i+1]]).
        cell_ptr, cell_faces: CSR of a CELL_GRID^3 grid over face centroids (non-empty cells only):
            the faces of cell c are cell_faces[cell_ptr[c]:cell_ptr[c+1]].
        cell_boxes: (K, 2, 3) float64 bounding box (min, max) of each cell's faces' vertices.
    """

    vertices: np.ndarray
    faces: np.ndarray
    edges: np.ndarray
    edge_faces: np.ndarray
    face_edges: np.ndarray
    face_normals: np.ndarray
    face_centroids: np.ndarray
    vertex_normals: np.ndarray
    crease: np.ndarray
    smooth_face: np.ndarray
    curvature: np.ndarray
    vf_ptr: np.ndarray
    vf_idx: np.ndarray
    cell_ptr: np.ndarray
    cell_faces: np.ndarray
    cell_boxes: np.ndarray


def _weld(vertices: np.ndarray, faces: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    key = np.round(vertices / tol).astype(np.int64)
    order = np.lexsort(key.T[::-1])
    ks = key[order]
    new_group = np.concatenate([[True], np.any(ks[1:] != ks[:-1], axis=1)])
    group = np.cumsum(new_group) - 1
    inverse = np.empty(len(vertices), np.int64)
    inverse[order] = group
    return vertices[order[new_group]], inverse[faces]


def _edge_topology(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    F = len(faces)
    V = int(faces.max()) + 1 if F else 1
    he = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])  # (3F, 2), block k = edge k of each face
    lo, hi = np.minimum(he[:, 0], he[:, 1]), np.maximum(he[:, 0], he[:, 1])
    keys, inverse = np.unique(lo * V + hi, return_inverse=True)  # 1-D keys: much faster than unique rows
    inverse = inverse.reshape(-1)
    edges = np.stack([keys // V, keys % V], axis=1)
    face_id = np.tile(np.arange(F), 3)
    order = np.argsort(inverse, kind="stable")  # stable: faces of an edge stay in increasing order
    inv_s, face_s = inverse[order], face_id[order]
    start = np.searchsorted(inv_s, np.arange(len(edges)))
    count = np.bincount(inv_s, minlength=len(edges))
    edge_faces = np.full((len(edges), 2), -1, dtype=np.int64)
    edge_faces[:, 0] = face_s[start]
    two = count >= 2
    edge_faces[two, 1] = face_s[start[two] + 1]
    face_edges = inverse.reshape(3, F).T.copy()
    return edges, edge_faces, face_edges


def _scatter_add(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """out[i] = sum of values[index == i] for a flat (N,) index and (N, ...) values (bincount per component)."""
    flat = values.reshape(len(values), -1)
    out = np.stack([np.bincount(index, weights=flat[:, c], minlength=n) for c in range(flat.shape[1])], axis=1)
    return out.reshape((n,) + values.shape[1:])


def curvature_tensors(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray,
                      use_face: np.ndarray | None = None) -> np.ndarray:
    """Per-vertex second fundamental form as a (V, 3, 3) tangent-plane tensor.

    For a unit tangent direction t at vertex i the normal curvature is ``t @ T[i] @ t``;
    a sphere of radius r with outward normals gives ``T = (I - n n^T) / r`` (positive).

    Args:
        vertices: (V, 3) float64.
        faces: (F, 3) int64.
        normals: (V, 3) unit vertex normals.
        use_face: optional (F,) bool; only these faces contribute (faces touching a crease have
            averaged-across-the-crease vertex normals that are no smooth surface's). Vertices
            with no contributing face get a zero tensor.
    """
    v = np.asarray(vertices, np.float64)
    tri = v[faces]  # (F, 3, 3)
    nrm = normals[faces]  # (F, 3, 3)
    e = np.stack([tri[:, 2] - tri[:, 1], tri[:, 0] - tri[:, 2], tri[:, 1] - tri[:, 0]], axis=1)  # (F, 3, 3)
    dn = np.stack([nrm[:, 2] - nrm[:, 1], nrm[:, 0] - nrm[:, 2], nrm[:, 1] - nrm[:, 0]], axis=1)
    fn = np.cross(e[:, 2], -e[:, 1])  # (v1 - v0) x (v2 - v0)
    area2 = np.linalg.norm(fn, axis=1)
    good = area2 > 1e-20
    fn = fn / np.maximum(area2, 1e-300)[:, None]
    elen = np.linalg.norm(e[:, 0], axis=1)
    u = e[:, 0] / np.maximum(elen, 1e-300)[:, None]
    w = np.cross(fn, u)
    eu, ew = np.einsum("fkc,fc->fk", e, u), np.einsum("fkc,fc->fk", e, w)  # (F, 3)
    du, dw = np.einsum("fkc,fc->fk", dn, u), np.einsum("fkc,fc->fk", dn, w)
    # least squares for [a, b, c] in II = [[a, b], [b, c]]:  II @ (eu, ew) = (du, dw)
    A = np.zeros((len(faces), 6, 3))
    A[:, 0:3, 0], A[:, 0:3, 1] = eu, ew
    A[:, 3:6, 1], A[:, 3:6, 2] = eu, ew
    rhs = np.concatenate([du, dw], axis=1)
    AtA = np.einsum("fki,fkj->fij", A, A) + 1e-12 * np.eye(3)
    Atb = np.einsum("fki,fk->fi", A, rhs)
    sol = np.linalg.solve(AtA, Atb[..., None])[..., 0]
    sol[~good] = 0.0
    a, b, c = sol[:, 0], sol[:, 1], sol[:, 2]
    B = np.stack([u, w], axis=2)  # (F, 3, 2)
    II = np.stack([np.stack([a, b], 1), np.stack([b, c], 1)], 1)  # (F, 2, 2)
    T_f = B @ II @ B.transpose(0, 2, 1)  # (F, 3, 3)
    if use_face is not None:
        area2 = np.where(use_face, area2, 0.0)
    wgt = (0.5 * area2)[:, None, None]
    idx = faces.T.ravel()  # (3F,) vertex of each (corner, face)
    acc = _scatter_add(idx, np.tile(T_f * wgt, (3, 1, 1)), len(v))
    wsum = np.bincount(idx, weights=np.tile(0.5 * area2, 3), minlength=len(v))
    T = acc / np.maximum(wsum, 1e-300)[:, None, None]
    P = np.eye(3)[None] - normals[:, :, None] * normals[:, None, :]
    T = P @ T @ P
    return 0.5 * (T + T.transpose(0, 2, 1))


def prepare_mesh(mesh: Mesh, settings: LineSettings = LineSettings()) -> MeshLineData:
    """Compute the view-independent topology and curvature for :func:`extract_lines` (once per shape)."""
    if not isinstance(mesh, Mesh):
        raise TypeError(f"prepare_mesh needs an engine.mesh.Mesh, got {type(mesh).__name__}")
    if mesh.num_faces == 0:
        raise ValueError("cannot draw lines of a mesh with no faces")
    v, f = _weld(np.asarray(mesh.vertices, np.float64), mesh.faces, WELD_TOLERANCE)
    edges, edge_faces, face_edges = _edge_topology(f)
    fn = face_normals(v, f)
    vn = vertex_normals(v, f)
    both = edge_faces[:, 1] >= 0
    cosang = np.einsum("ec,ec->e", fn[edge_faces[:, 0]], fn[np.maximum(edge_faces[:, 1], 0)])
    crease = both & (cosang < np.cos(np.radians(settings.crease_angle_deg)))
    rough_v = np.zeros(len(v), bool)
    rough_v[edges[crease | ~both].ravel()] = True
    smooth_face = ~rough_v[f].any(axis=1)
    curv = curvature_tensors(v, f, vn, smooth_face) if settings.suggestive else np.zeros((len(v), 3, 3))
    order = np.argsort(f.ravel(), kind="stable")
    vf_idx = (order // 3).astype(np.int64)
    vf_ptr = np.concatenate([[0], np.cumsum(np.bincount(f.ravel(), minlength=len(v)))]).astype(np.int64)
    centroids = v[f].mean(axis=1)
    cell_ptr, cell_faces, cell_boxes = _face_cells(v, f, centroids)
    return MeshLineData(v, f, edges, edge_faces, face_edges, fn, centroids, vn, crease, smooth_face, curv, vf_ptr, vf_idx,
                        cell_ptr, cell_faces, cell_boxes)


def _face_cells(v: np.ndarray, f: np.ndarray, centroids: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bucket faces into a CELL_GRID^3 grid by centroid: CSR (ptr, faces) and per-cell vertex bounding boxes."""
    lo, hi = centroids.min(axis=0), centroids.max(axis=0)
    scale = CELL_GRID / np.maximum(hi - lo, 1e-12)
    g = np.clip(((centroids - lo) * scale).astype(np.int64), 0, CELL_GRID - 1)
    cell = (g[:, 0] * CELL_GRID + g[:, 1]) * CELL_GRID + g[:, 2]
    order = np.argsort(cell, kind="stable")
    cs = cell[order]
    starts = np.flatnonzero(np.concatenate([[True], cs[1:] != cs[:-1]]))
    ptr = np.concatenate([starts, [len(cs)]]).astype(np.int64)
    tri = v[f[order]]  # (F, 3, 3) in cell order
    boxes = np.stack([np.minimum.reduceat(tri.min(axis=1), starts), np.maximum.reduceat(tri.max(axis=1), starts)], axis=1)
    return ptr, order.astype(np.int64), boxes


def _zmax_windows(depth: np.ndarray) -> list[np.ndarray]:
    """Sliding-window maxima of the z-buffer: level L holds, at (i, j), the max over rows
    i..i+2^L-1 and columns j..j+2^L-1 (clipped to the image; +inf background stays +inf)."""
    levels = [depth]
    size = depth.shape[0]
    step = 1
    while 2 * step <= size:
        d = levels[-1]
        pad = np.full((size + step, size + step), -np.inf)
        pad[:size, :size] = d
        levels.append(np.maximum(np.maximum(pad[:size, :size], pad[step:, :size]),
                                 np.maximum(pad[:size, step:], pad[step:, step:])))
        step *= 2
    return levels


def _cells_maybe_visible(prep: MeshLineData, camera: Camera, size: int, depth: np.ndarray, tol: float) -> np.ndarray:
    """(K,) bool: cells whose bounding box is not entirely behind the z-buffer (hierarchical z culling).

    A cell is culled when the nearest depth of its box's 8 corners is farther than the largest
    z-buffer depth over the pixel rectangle covering the box's projection (exact range maximum
    from :func:`_zmax_windows` with four windows; the box itself is conservative).
    """
    K = len(prep.cell_boxes)
    b = prep.cell_boxes
    corners = np.stack([np.stack([b[:, i, 0], b[:, j, 1], b[:, k, 2]], axis=1)
                        for i in (0, 1) for j in (0, 1) for k in (0, 1)], axis=1)  # (K, 8, 3)
    uv, d = project(corners.reshape(-1, 3), camera)
    px = ndc_to_pixel(uv, size).reshape(K, 8, 2)
    d = d.reshape(K, 8)
    keep = np.ones(K, bool)
    ok = np.all(np.isfinite(px.reshape(K, -1)), axis=1) & np.all(d > 0, axis=1)
    if not np.any(ok):
        return keep
    lo = np.floor(px[ok].min(axis=1)).astype(np.int64)  # (k, 2) (col, row)
    hi = np.floor(px[ok].max(axis=1)).astype(np.int64)
    lo = np.clip(lo, 0, size - 1)
    hi = np.clip(hi, 0, size - 1)
    extent = np.max(hi - lo, axis=1) + 1  # pixels covered along the longer side
    levels = _zmax_windows(np.asarray(depth, np.float64))
    lvl = np.clip(np.floor(np.log2(extent)).astype(np.int64), 0, len(levels) - 1)
    zmax = np.full(len(lo), -np.inf)
    for L in np.unique(lvl):
        sel = np.flatnonzero(lvl == L)
        w = 1 << int(L)  # 2 windows of side w per axis cover [lo, hi] exactly (w >= extent / 2)
        img = levels[L]
        r0, c0 = lo[sel, 1], lo[sel, 0]
        r1, c1 = np.maximum(hi[sel, 1] - w + 1, r0), np.maximum(hi[sel, 0] - w + 1, c0)
        zmax[sel] = np.maximum(np.maximum(img[r0, c0], img[r1, c0]), np.maximum(img[r0, c1], img[r1, c1]))
    keep[np.flatnonzero(ok)] = d[ok].min(axis=1) <= zmax + tol
    return keep


@dataclass(frozen=True, eq=False)
class LineDrawing:
    """The visible lines of one view.

    Attributes:
        polylines: list of (N_i, 2) float64 pixel coordinates (x = col, y = row), N_i >= 2.
        kinds: (P,) int64 kind code per polyline (see :data:`LINE_KINDS`).
        size: the image size the coordinates refer to.
        stats: counts (candidates, pieces tested, ...) for benchmarks.
    """

    polylines: list
    kinds: np.ndarray
    size: int
    stats: dict


def _unique_ids(ids: np.ndarray, n: int) -> np.ndarray:
    """Sorted unique values of ``ids`` (all in [0, n)) via a boolean mask: O(len(ids)) + one O(n) memset."""
    mask = np.zeros(n, bool)
    mask[ids] = True
    return np.flatnonzero(mask)


def _visible_faces(face_index: np.ndarray, prep: MeshLineData) -> np.ndarray:
    """Faces seen in face_index plus their one-vertex-ring neighbours (sorted unique ids)."""
    F, V = len(prep.faces), len(prep.vertices)
    seen = _unique_ids(face_index[face_index >= 0], F)
    if len(seen) == 0:
        return seen
    verts = _unique_ids(prep.faces[seen].ravel(), V)
    starts, ends = prep.vf_ptr[verts], prep.vf_ptr[verts + 1]
    counts = ends - starts
    idx = np.repeat(starts - np.cumsum(np.concatenate([[0], counts[:-1]])), counts) + np.arange(counts.sum())
    return _unique_ids(np.concatenate([seen, prep.vf_idx[idx]]), F)


def _suggestive_segments(prep: MeshLineData, faces_vis: np.ndarray, front: np.ndarray, cam_pos: np.ndarray,
                         settings: LineSettings) -> tuple[np.ndarray, np.ndarray]:
    """Suggestive-contour segments on visible front-facing smooth faces: (S, 2, 3) endpoints and (S,) face ids."""
    fc = faces_vis[front & prep.smooth_face[faces_vis]]
    if len(fc) == 0:
        return np.zeros((0, 2, 3)), np.zeros(0, np.int64)
    tri_idx = prep.faces[fc]  # (Fc, 3)
    verts = _unique_ids(tri_idx.ravel(), len(prep.vertices))
    vmap = np.zeros(len(prep.vertices), np.int64)
    vmap[verts] = np.arange(len(verts))
    inv = vmap[tri_idx]  # (Fc, 3) positions in verts
    p = prep.vertices[verts]
    n = prep.vertex_normals[verts]
    view = cam_pos - p
    view /= np.maximum(np.linalg.norm(view, axis=1, keepdims=True), 1e-300)
    w = view - np.einsum("vc,vc->v", view, n)[:, None] * n
    ww = np.einsum("vc,vc->v", w, w)
    kr = np.einsum("vi,vij,vj->v", w, prep.curvature[verts], w) / np.maximum(ww, W_EPS)
    kr_ok = ww > W_EPS
    # light smoothing over the one-ring (within the visible front faces): the per-vertex curvature
    # estimate is noisy at the scale of single triangles, which breaks the zero set into specks
    for _ in range(settings.sc_smoothing):
        face_mean = kr[inv].mean(axis=1)
        cnt = np.bincount(inv.ravel(), minlength=len(verts))
        ring = np.bincount(inv.ravel(), weights=np.repeat(face_mean, 3), minlength=len(verts)) / np.maximum(cnt, 1)
        kr = 0.5 * kr + 0.5 * ring
    k = kr[inv]  # (Fc, 3)
    ok = kr_ok[inv].all(axis=1)
    pos = k >= 0
    # optionally, a zero crossing needs a clearly negative (concave) end
    cross = ok & pos.any(axis=1) & (k.min(axis=1) < -settings.sc_min_curvature)
    if not np.any(cross):
        return np.zeros((0, 2, 3)), np.zeros(0, np.int64)
    fc, k, tri_idx = fc[cross], k[cross], tri_idx[cross]
    tri = prep.vertices[tri_idx]  # (S, 3, 3)
    fn = prep.face_normals[fc]
    centroid = tri.mean(axis=1)
    vf = cam_pos - centroid
    vf /= np.maximum(np.linalg.norm(vf, axis=1, keepdims=True), 1e-300)
    ndotv = np.einsum("fc,fc->f", fn, vf)
    wf = vf - ndotv[:, None] * fn
    wn = np.linalg.norm(wf, axis=1)
    # gradient of the linear interpolant of kappa_r over the triangle: sum_i k_i (n x e_i) / (2A)
    e = np.stack([tri[:, 2] - tri[:, 1], tri[:, 0] - tri[:, 2], tri[:, 1] - tri[:, 0]], axis=1)
    area2 = np.linalg.norm(np.cross(e[:, 2], -e[:, 1]), axis=1)
    grad = np.einsum("fk,fkc->fc", k, np.cross(fn[:, None, :], e)) / np.maximum(area2, 1e-300)[:, None]
    dwkr = np.einsum("fc,fc->f", grad, wf) / np.maximum(wn, 1e-300)
    keep = (dwkr > settings.sc_threshold) & (ndotv < np.cos(np.radians(settings.sc_theta_c_deg))) & (area2 > 1e-20)
    fc, k, tri_idx, pos = fc[keep], k[keep], tri_idx[keep], (k[keep] >= 0)
    if len(fc) == 0:
        return np.zeros((0, 2, 3)), np.zeros(0, np.int64)
    # zero crossings on the two edges whose ends differ in sign; interpolate in sorted vertex order so the
    # point on an edge is bit-identical from both of its faces (lets chaining join them)
    pts = []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        ia, ib = tri_idx[:, a], tri_idx[:, b]
        ka, kb = k[:, a], k[:, b]
        swap = ia > ib
        lo_i, hi_i = np.where(swap, ib, ia), np.where(swap, ia, ib)
        lo_k, hi_k = np.where(swap, kb, ka), np.where(swap, ka, kb)
        t = lo_k / np.where(lo_k - hi_k == 0, 1.0, lo_k - hi_k)
        t = np.clip(t, 0.0, 1.0)[:, None]
        pt = prep.vertices[lo_i] * (1.0 - t) + prep.vertices[hi_i] * t
        pts.append((pt, pos[:, a] != pos[:, b]))
    P = np.stack([p for p, _ in pts], axis=1)  # (S, 3, 3)
    M = np.stack([m for _, m in pts], axis=1)  # (S, 3) exactly two True per row
    order = np.argsort(~M, axis=1, kind="stable")[:, :2]
    seg = np.take_along_axis(P, order[:, :, None], axis=1)
    return seg, fc


def extract_lines(prep: MeshLineData, camera: Camera, size: int, depth: np.ndarray, face_index: np.ndarray,
                  settings: LineSettings = LineSettings()) -> LineDrawing:
    """Visible contours, creases and suggestive contours of one view as polylines.

    Args:
        prep: :func:`prepare_mesh` of the mesh that was rasterised (same face order).
        camera: the (framed) camera of the view.
        size: image size H = W of the buffers.
        depth: (H, W) float32 z-buffer ``-z_cam``, +inf on background (the rasterizer's ``depth``).
        face_index: (H, W) int64 visible face per pixel, -1 on background (the rasterizer's ``face_index``).
        settings: thresholds.

    Returns:
        A :class:`LineDrawing` with pixel-coordinate polylines.
    """
    depth = np.asarray(depth)
    face_index = np.asarray(face_index)
    if depth.shape != (size, size) or face_index.shape != (size, size):
        raise ValueError(f"depth and face_index must be ({size}, {size}), got {depth.shape} and {face_index.shape}")
    if face_index.size and face_index.max() >= len(prep.faces):
        raise ValueError(f"face_index refers to face {face_index.max()} but the mesh has {len(prep.faces)} faces")
    stats = {"visible_faces": 0, "candidate_edges": 0, "segments": 0, "pieces": 0}
    faces_vis = _visible_faces(face_index, prep)
    stats["visible_faces"] = int(len(faces_vis))
    if len(faces_vis) == 0:
        return LineDrawing([], np.zeros(0, np.int64), size, stats)
    cam_pos = camera.position
    zmax = _max3x3(np.asarray(depth, np.float64))
    # hierarchical z culling: only faces in cells not entirely behind the z-buffer are looked at,
    # so hidden geometry (interiors, occluded parts) costs O(cells), not O(faces)
    keep_cells = _cells_maybe_visible(prep, camera, size, depth, settings.depth_tolerance)
    kc = np.flatnonzero(keep_cells)
    counts = prep.cell_ptr[kc + 1] - prep.cell_ptr[kc]
    idx = np.repeat(prep.cell_ptr[kc] - np.cumsum(np.concatenate([[0], counts[:-1]])), counts) + np.arange(counts.sum())
    faces_live = prep.cell_faces[idx]
    stats["cells_kept"] = int(len(kc))
    stats["cells"] = int(len(prep.cell_boxes))
    stats["faces_tested"] = int(len(faces_live))

    # front-facing flags, computed once per face on first use (two O(F) memsets, no O(F) arithmetic)
    fr_cache = np.zeros(len(prep.faces), bool)
    done = np.zeros(len(prep.faces), bool)

    def front(fids: np.ndarray) -> np.ndarray:
        todo = fids[~done[fids]]
        if len(todo):
            todo = _unique_ids(todo, len(prep.faces))
            fr_cache[todo] = np.einsum("fc,fc->f", prep.face_normals[todo], cam_pos - prep.face_centroids[todo]) > FRONT_EPS
            done[todo] = True
        return fr_cache[fids]

    front(faces_live)

    ef_all = prep.edge_faces
    has2_all = ef_all[:, 1] >= 0
    # occluding contours among the live faces' edges (their front face may be a sub-pixel sliver that
    # face_index misses), culled at once when their ends, quarters and middle lie behind the z-buffer
    live_e = _unique_ids(prep.face_edges[faces_live].ravel(), len(prep.edges))
    lef = ef_all[live_e]
    l2 = lef[:, 1] >= 0
    lfr0, lfr1 = front(lef[:, 0]), front(np.maximum(lef[:, 1], 0))
    contour_all = live_e[l2 & (lfr0 != lfr1)]
    contour_e = contour_all[_maybe_visible(prep.vertices[prep.edges[contour_all]], camera, size, zmax, settings)]
    # creases and open boundaries only next to faces seen in face_index
    near_e = _unique_ids(prep.face_edges[faces_vis].ravel(), len(prep.edges))
    ef = ef_all[near_e]
    has2 = has2_all[near_e]
    fr0, fr1 = front(ef[:, 0]), front(np.maximum(ef[:, 1], 0)) & has2
    crease_e = near_e[prep.crease[near_e] & (fr0 | fr1) & has2]
    boundary_e = near_e[~has2]
    line_e = np.concatenate([contour_e, crease_e, boundary_e])
    seg_kind = np.concatenate([np.full(len(contour_e), KIND_CONTOUR), np.full(len(crease_e), KIND_CREASE),
                               np.full(len(boundary_e), KIND_BOUNDARY)]).astype(np.int64)
    line_e, first = np.unique(line_e, return_index=True)  # a contour that is also a crease is drawn once
    seg_kind = seg_kind[first]
    seg = prep.vertices[prep.edges[line_e]]  # (S, 2, 3)
    stats["contour_edges"] = int(len(contour_all))
    stats["candidate_edges"] = int(len(line_e))
    if settings.suggestive:
        sc, _ = _suggestive_segments(prep, faces_vis, front(faces_vis), cam_pos, settings)
        if len(sc):
            seg = np.concatenate([seg, sc])
            seg_kind = np.concatenate([seg_kind, np.full(len(sc), KIND_SUGGESTIVE, np.int64)])
    stats["segments"] = int(len(seg))
    polylines, kinds, npieces = _visible_polylines(seg, seg_kind, camera, size, zmax, settings)
    stats["pieces"] = npieces
    return LineDrawing(polylines, kinds, size, stats)


def _max3x3(depth: np.ndarray) -> np.ndarray:
    """Max over each pixel's 3x3 neighbourhood (+inf anywhere in it stays +inf)."""
    H, W = depth.shape
    pad = np.pad(depth, 1, mode="constant", constant_values=np.inf)
    out = np.full_like(depth, -np.inf)
    for di in range(3):
        for dj in range(3):
            np.maximum(out, pad[di:di + H, dj:dj + W], out=out)
    return out


def _maybe_visible(seg: np.ndarray, camera: Camera, size: int, zmax: np.ndarray, settings: LineSettings) -> np.ndarray:
    """(S,) bool: the start, middle or end of each 3D segment (S, 2, 3) is not behind the z-buffer (cheap pre-cull)."""
    if len(seg) == 0:
        return np.zeros(0, bool)
    t = np.linspace(0.0, 1.0, PRECULL_SAMPLES)[:, None, None]
    pts = (seg[None, :, 0] * (1.0 - t) + seg[None, :, 1] * t).reshape(-1, 3)
    uv, d = project(pts, camera)
    return _depth_test(uv, d, size, zmax, settings.depth_tolerance).reshape(PRECULL_SAMPLES, -1).any(axis=0)


def _depth_test(uv: np.ndarray, d: np.ndarray, size: int, zmax: np.ndarray, tol: float) -> np.ndarray:
    """(N,) bool: the NDC points (N, 2) at depths (N,) are inside the image and not behind ``zmax`` + tol."""
    pm = ndc_to_pixel(uv, size)
    ok = np.all(np.isfinite(pm), axis=1) & np.isfinite(d)
    col = np.floor(np.where(ok, pm[:, 0], -1)).astype(np.int64)
    row = np.floor(np.where(ok, pm[:, 1], -1)).astype(np.int64)
    inside = ok & (col >= 0) & (col < size) & (row >= 0) & (row < size)
    vis = np.zeros(len(d), bool)
    vis[inside] = d[inside] <= zmax[row[inside], col[inside]] + tol
    return vis


def _visible_polylines(seg: np.ndarray, seg_kind: np.ndarray, camera: Camera, size: int, zmax: np.ndarray,
                       settings: LineSettings) -> tuple[list, np.ndarray, int]:
    """Split 3D segments (S, 2, 3) into z-buffer-visible runs and chain them into pixel polylines.

    ``zmax`` is the (H, W) 3x3-neighbourhood maximum of the depth buffer (:func:`_max3x3`).
    """
    if len(seg) == 0:
        return [], np.zeros(0, np.int64), 0
    S = len(seg)
    uv, d = project(seg.reshape(-1, 3), camera)
    px = ndc_to_pixel(uv, size).reshape(S, 2, 2)
    ok = np.all(np.isfinite(px.reshape(S, 4)), axis=1)
    seg, seg_kind, px = seg[ok], seg_kind[ok], px[ok]
    S = len(seg)
    if S == 0:
        return [], np.zeros(0, np.int64), 0
    length = np.linalg.norm(px[:, 1] - px[:, 0], axis=1)
    npc = np.clip(np.ceil(length / settings.sample_spacing_px), 1, 4 * size).astype(np.int64)
    total = int(npc.sum())
    sid = np.repeat(np.arange(S), npc)
    k = np.arange(total) - np.repeat(np.cumsum(npc) - npc, npc)
    tm = (k + 0.5) / npc[sid]
    mid = seg[sid, 0] * (1.0 - tm)[:, None] + seg[sid, 1] * tm[:, None]
    uvm, dm = project(mid, camera)
    vis = _depth_test(uvm, dm, size, zmax, settings.depth_tolerance)
    # runs of visible pieces within each segment -> (segment, t0, t1)
    starts = np.cumsum(npc) - npc
    v_int = vis.astype(np.int8)
    prev = np.concatenate([[0], v_int[:-1]])
    nxt = np.concatenate([v_int[1:], [0]])
    first_piece = np.zeros(total, bool)
    first_piece[starts] = True
    last_piece = np.zeros(total, bool)
    last_piece[starts + npc - 1] = True
    run_start = vis & (first_piece | (prev == 0))
    run_end = vis & (last_piece | (nxt == 0))
    rs, re_ = np.nonzero(run_start)[0], np.nonzero(run_end)[0]
    rsid = sid[rs]
    t0 = k[rs] / npc[rsid]
    t1 = (k[re_] + 1) / npc[rsid]
    a = seg[rsid, 0] * (1.0 - t0)[:, None] + seg[rsid, 1] * t0[:, None]
    b = seg[rsid, 0] * (1.0 - t1)[:, None] + seg[rsid, 1] * t1[:, None]
    ua, _ = project(a, camera)
    ub, _ = project(b, camera)
    pa, pb = ndc_to_pixel(ua, size), ndc_to_pixel(ub, size)
    polylines, kinds = chain_segments(pa, pb, seg_kind[rsid])
    if polylines:
        lens = np.array([np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in polylines])
        keep = lens >= settings.min_length_px
        keep &= (kinds != KIND_SUGGESTIVE) | (lens >= settings.sc_min_length_px * size / 256.0)
        polylines = [p for p, kk in zip(polylines, keep) if kk]
        kinds = kinds[keep]
    return polylines, kinds, total


def chain_segments(a: np.ndarray, b: np.ndarray, kinds: np.ndarray) -> tuple[list, np.ndarray]:
    """Join 2D segments that share exact endpoints into polylines.

    Args:
        a, b: (S, 2) segment endpoints.
        kinds: (S,) kind of each segment; a chain only continues through segments of the same kind.

    Returns:
        (polylines, kinds): list of (N, 2) float64 arrays and (P,) kinds. Chains stop at
        junctions (points where other than two same-kind segments meet); closed loops repeat
        their first point at the end.
    """
    S = len(a)
    if S == 0:
        return [], np.zeros(0, np.int64)
    pts = np.concatenate([a, b])
    keys = np.concatenate([pts, np.concatenate([kinds, kinds])[:, None].astype(np.float64)], axis=1)
    uniq, node = np.unique(keys, axis=0, return_inverse=True)
    node = node.reshape(-1)
    na, nb = node[:S], node[S:]
    nonzero = na != nb
    adj: dict[int, list[int]] = {}
    for s in np.nonzero(nonzero)[0].tolist():
        adj.setdefault(int(na[s]), []).append(s)
        adj.setdefault(int(nb[s]), []).append(s)
    used = np.zeros(S, bool)
    used[~nonzero] = True
    out, out_k = [], []
    na_l, nb_l = na.tolist(), nb.tolist()

    def walk(start_node: int, s: int) -> list[int]:
        nodes = [start_node]
        cur = start_node
        while True:
            used[s] = True
            nxt = nb_l[s] if na_l[s] == cur else na_l[s]
            nodes.append(nxt)
            cur = nxt
            nbrs = adj.get(cur, [])
            if len(nbrs) != 2:
                return nodes
            s2 = nbrs[0] if nbrs[1] == s else nbrs[1]
            if used[s2]:
                return nodes
            s = s2

    for n0, segs in adj.items():  # open chains start at ends and junctions
        if len(segs) == 2:
            continue
        for s in segs:
            if not used[s]:
                nodes = walk(n0, s)
                out.append(uniq[nodes, :2])
                out_k.append(kinds[s])
    for s in range(S):  # what is left are closed loops
        if not used[s]:
            nodes = walk(na_l[s], s)
            out.append(uniq[nodes, :2])
            out_k.append(kinds[s])
    return out, np.asarray(out_k, dtype=np.int64)


def rasterize_polylines(polylines: list, size: int, width: float | np.ndarray = SKETCH_STROKE_WIDTH_PX,
                        intensity: float | np.ndarray = 1.0) -> np.ndarray:
    """Draw anti-aliased strokes exactly as the engine draws a user's sketch: (H, W) float32, 1 = ink.

    Uses :func:`engine.preprocess.draw_segments` (coverage ``clip(width / 2 + 0.5 - d, 0, 1)``,
    round caps, exact width), so clean training drawings and preprocessed user sketches share
    one stroke style.

    Args:
        polylines: list of (N_i, 2) pixel coordinates (x = col, y = row; pixel centres at k + 0.5).
        size: output size H = W.
        width: stroke width in output pixels, scalar or (P,) per polyline.
        intensity: ink darkness in [0, 1], scalar or (P,) per polyline (overlaps take the max).
    """
    from engine.preprocess import draw_segments

    if not isinstance(size, (int, np.integer)) or size <= 0:
        raise ValueError(f"size must be a positive int, got {size!r}")
    P = len(polylines)
    widths = np.broadcast_to(np.asarray(width, np.float64), (P,))
    inks = np.broadcast_to(np.asarray(intensity, np.float64), (P,))
    if P and not (np.all(np.isfinite(widths)) and np.all(widths > 0)):
        raise ValueError("stroke widths must be finite and > 0")
    if P and not (np.all(np.isfinite(inks)) and np.all((inks >= 0) & (inks <= 1))):
        raise ValueError("stroke intensities must be in [0, 1]")
    groups: dict[tuple[float, float], list] = {}
    for i, p in enumerate(polylines):
        p = np.asarray(p, np.float64)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 1 or not np.all(np.isfinite(p)):
            raise ValueError(f"polyline {i} must be a finite (N, 2) array, got shape {p.shape}")
        if len(p) == 1:
            p = np.concatenate([p, p])
        key = (round(float(widths[i]), WIDTH_DECIMALS), round(float(inks[i]), WIDTH_DECIMALS))
        groups.setdefault(key, []).append(np.stack([p[:-1], p[1:]], axis=1))
    out = np.zeros((size, size), np.float32)
    for (w, ink), segs in groups.items():
        cov = draw_segments(np.concatenate(segs), size, w)
        np.maximum(out, cov * np.float32(ink), out=out)
    return out


def sketch_to_file_image(sketch: np.ndarray) -> np.ndarray:
    """(H, W) float 1 = ink -> (H, W) uint8 dark strokes on white (the image-file representation)."""
    s = np.clip(np.asarray(sketch, np.float64), 0.0, 1.0)
    return np.round(255.0 * (1.0 - s)).astype(np.uint8)
