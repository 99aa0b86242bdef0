"""Check the Eq. 1 silhouette gradient against finite differences of the silhouette's area.

The rasterized silhouette is piecewise constant, so its finite differences are useless. The
quantity the edge gradient stands in for is the *area* the silhouette covers: for the loss
``L = sign * sum(silhouette)`` (``sign = -1`` asks the mesh to grow, ``+1`` to shrink) its
smooth counterpart is ``sign * area`` in px^2, and ``d area / d vertex`` is what the
approximate gradient should point along.

The area is measured by supersampling a small window around each checked vertex: moving one
vertex changes the silhouette only inside the screen box of its incident faces, so the area
outside that window cancels in a central difference. The window is rendered through a zoomed
camera (same view, focal and principal point rescaled) at ``window_res`` pixels, i.e. about
``window_res / window_px`` samples per pixel side, with the exact forward rasterizer (itself
checked pixel for pixel against the loop reference).

What to expect from Eq. 1: the *direction* of the area gradient (sign agreement, cosine), on
growing and shrinking alike. Its *size* is larger by a roughly constant factor: for a pixel
at distance ``D`` (uniform in (0, 1) px) from the edge, Eq. 1 divides the colour change by
``D``, whose mean ``E[1 / max(D, D_min)] = 1 + ln(1 / D_min)`` is 5.6 for ``D_min = 0.01`` px.
The factor must be about the same for growing and shrinking; a shrink/grow imbalance is the
bias that makes a mesh shrink when it should not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from engine.camera import Camera
from engine.mesh import Mesh
from training.render.rasterize import cameras_to_tensor, face_adjacency, project_vertices, rasterize

__all__ = ["GradCheck", "silhouette_gradient_check", "silhouette_edge_vertices"]


@dataclass
class GradCheck:
    """Result of :func:`silhouette_gradient_check` for one loss sign.

    Attributes:
        direction: ``"grow"`` (loss ``-sum(silhouette)``) or ``"shrink"`` (``+sum``).
        sign_agreement: fraction of significant finite-difference components (``|fd| >= 10 %``
            of the largest) whose sign the approximate gradient matches.
        cosine: cosine between the stacked approximate and finite-difference gradients.
        scale: ``|approx| / |fd|`` over the checked vertices (Eq. 1's size factor).
        components: number of significant components compared.
        vertices: number of vertices checked.
    """

    direction: str
    sign_agreement: float
    cosine: float
    scale: float
    components: int
    vertices: int


def silhouette_edge_vertices(faces: np.ndarray, screen: np.ndarray) -> np.ndarray:
    """Vertices of screen-space silhouette edges: edges whose two faces face opposite ways on screen.

    Args:
        faces: (F, 3) int; screen: (V, 2) pixel coordinates.

    Returns:
        (K,) int64 sorted vertex indices.
    """
    faces = np.array(faces, dtype=np.int64)  # a writable copy: torch.from_numpy warns on a read-only one
    d1 = screen[faces[:, 1]] - screen[faces[:, 0]]
    d2 = screen[faces[:, 2]] - screen[faces[:, 0]]
    orient = np.sign(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    neighbour = face_adjacency(torch.from_numpy(faces))[0].numpy()  # (F, 3), edge k opposite vertex k
    f, k = np.nonzero(neighbour >= 0)
    fold = orient[f] != orient[neighbour[f, k]]
    ends = np.stack([faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]], axis=1)
    return np.unique(ends[fold]).astype(np.int64)


def _zoomed(cam: np.ndarray, S: int, x0: float, y0: float, width: float) -> np.ndarray:
    """The camera array that renders the pixel window [x0, x0 + width] x [y0, y0 + width] full frame."""
    z = cam.copy()
    k = S / width
    z[12] = cam[12] * k
    z[13] = k * (cam[13] + 1.0) - 2.0 * x0 / width - 1.0
    z[14] = 1.0 - k * (1.0 - cam[14]) + 2.0 * y0 / width
    return z


def _window_area(v: torch.Tensor, f: torch.Tensor, zcam: torch.Tensor, res: int, width: float) -> float:
    out = rasterize(v[None], f, zcam, res)
    return float((out.face_index >= 0).sum()) * (width / res) ** 2


def silhouette_gradient_check(
    mesh: Mesh,
    camera: Camera,
    *,
    image_size: int = 64,
    num_vertices: int = 16,
    step_px: float = 0.25,
    window_res: int = 256,
    delta: float = 1.0,
    seed: int = 0,
    edge_range: int = 1,
) -> list[GradCheck]:
    """Compare Eq. 1's silhouette gradient with central differences of the supersampled area.

    Args:
        mesh: the mesh, in the camera's world frame.
        camera: the view.
        image_size: S, the side of the rendered image the gradient is taken on.
        num_vertices: how many vertices to check (drawn among the silhouette-edge vertices and
            those the approximate gradient moves).
        step_px: finite-difference step, as a screen displacement in pixels (converted per
            vertex to a 3D step through its depth).
        window_res: side of the supersampled window render.
        delta: Eq. 1 strength.
        seed: vertex sampling seed.
        edge_range: the gradient's reach in pixels (1: adjacent pairs; see :func:`rasterize`).

    Returns:
        Two :class:`GradCheck`, for growing and shrinking.
    """
    v = torch.tensor(np.asarray(mesh.vertices, dtype=np.float64))
    f = torch.tensor(np.asarray(mesh.faces, dtype=np.int64))
    cam = cameras_to_tensor([camera], dtype=torch.float64)
    approx = {}
    for direction, sign in (("grow", -1.0), ("shrink", 1.0)):
        vg = v.clone().requires_grad_()
        (sign * rasterize(vg[None], f, cam, image_size, delta=delta, edge_range=edge_range).silhouette.sum()).backward()
        approx[direction] = vg.grad.numpy()
    _, screen, inv_w, _ = project_vertices(v[None], cam, image_size)
    screen = screen[0].numpy()
    moved = np.nonzero(np.abs(approx["grow"]).sum(1) + np.abs(approx["shrink"]).sum(1) > 0)[0]
    cand = np.union1d(silhouette_edge_vertices(np.asarray(mesh.faces), screen), moved)
    if cand.size == 0:
        raise ValueError("the mesh shows no silhouette from this camera; nothing to check")
    rng = np.random.default_rng(seed)
    idx = np.sort(rng.choice(cand, size=min(num_vertices, cand.size), replace=False))
    faces_np = np.asarray(mesh.faces)
    cam_np = cam[0].numpy()
    depth = 1.0 / inv_w[0].numpy()
    # one pixel of screen motion is about depth / (focal * S / 2) world units
    px_to_world = depth / (cam_np[12] * image_size / 2.0)
    fd = np.zeros((len(idx), 3))
    for i, vi in enumerate(idx):
        ring = np.unique(faces_np[np.any(faces_np == vi, axis=1)])
        lo = screen[ring].min(0) - 2.0 * step_px - 1.0
        hi = screen[ring].max(0) + 2.0 * step_px + 1.0
        width = float(max(hi - lo))
        zcam = torch.tensor(_zoomed(cam_np, image_size, float(lo[0]), float(lo[1]), width))
        h = step_px * float(px_to_world[vi])
        for c in range(3):
            vp, vm = v.clone(), v.clone()
            vp[vi, c] += h
            vm[vi, c] -= h
            fd[i, c] = (_window_area(vp, f, zcam, window_res, width) - _window_area(vm, f, zcam, window_res, width)) / (
                2.0 * h
            )
    results = []
    for direction, sign in (("grow", -1.0), ("shrink", 1.0)):
        ref = sign * fd
        ap = approx[direction][idx]
        sig = np.abs(ref) >= 0.1 * np.abs(ref).max() if np.abs(ref).max() > 0 else np.zeros_like(ref, bool)
        agree = float((np.sign(ap[sig]) == np.sign(ref[sig])).mean()) if sig.any() else float("nan")
        nr, na = float(np.linalg.norm(ref)), float(np.linalg.norm(ap))
        cos = float((ap * ref).sum() / (na * nr)) if na > 0 and nr > 0 else float("nan")
        results.append(GradCheck(direction, agree, cos, na / nr if nr > 0 else float("inf"), int(sig.sum()), len(idx)))
    return results
