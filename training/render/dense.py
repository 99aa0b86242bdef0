"""Dense baseline rasterizer: every face tested against every pixel (benchmark only).

Same outputs, conventions, shading and Eq. 1 backward as :func:`training.render.rasterize`
(it reuses them); only the fragment stage differs: instead of expanding each face's pixel
box, it evaluates the three edge functions of **all** F faces at **all** S x S pixel
centres of an image, (F, S, S) at a time, and takes the nearest inside face per pixel.
Memory is about 40 * F * S^2 bytes per image (e.g. 210 MB for 1280 faces at 64x64, 3.4 GB
at 256x256); images are processed one at a time. ``sketchmesh bench renderer`` uses it to
show what culling the work to each face's pixels buys; nothing else should.
"""

from __future__ import annotations

import importlib

import torch
from torch import Tensor

_R = importlib.import_module("training.render.rasterize")


def dense_bytes_per_image(num_faces: int, image_size: int) -> int:
    """Rough peak working memory of :func:`dense_rasterize` per image, in bytes."""
    return 40 * num_faces * image_size * image_size


def _dense_fragments(screen: Tensor, inv_w: Tensor, vvalid: Tensor, faces: Tensor, S: int, cull: bool):
    """(face_index, depth, coef, keep) like :func:`training.render.rasterize._rasterize_fragments`, densely."""
    with torch.no_grad():
        B = screen.shape[0]
        F = faces.shape[0]
        dtype = screen.dtype
        coef, own, keep, _ = _R._face_setup(screen, inv_w, vvalid, faces, cull)
        c = torch.arange(S, device=screen.device, dtype=dtype) + 0.5
        px = c[None, None, :]  # (1, 1, S) columns
        py = c[None, :, None]  # (1, S, 1) rows
        fis, deps = [], []
        for b in range(B):
            cf = coef[b * F : (b + 1) * F].t()  # (12, F)
            ow = own[:, b * F : (b + 1) * F]
            inside = keep[b * F : (b + 1) * F, None, None].expand(F, S, S).clone()
            es = []
            for k in range(3):
                e = cf[k, :, None, None] * px + (cf[3 + k, :, None, None] * py + cf[6 + k, :, None, None])
                inside &= torch.where(ow[k, :, None, None], e >= 0, e > 0)
                es.append(e)
            depth = _R._fragment_depth(es[0], es[1], es[2], cf[9:12, :, None, None])
            depth = torch.where(inside, depth, torch.full_like(depth, float("inf")))
            best, idx = depth.min(dim=0)  # first minimum = smallest face index on ties
            fis.append(torch.where(torch.isinf(best), torch.full_like(idx, -1), idx))
            deps.append(best)
        return torch.stack(fis), torch.stack(deps), coef, keep


def dense_rasterize(vertices, faces, cameras, image_size, *, delta=1.0, shading="flat", cull_backfaces=False):
    """Dense-fragment version of :func:`training.render.rasterize` (same arguments and outputs)."""
    vertices, faces, cams = _R._check_inputs(vertices, faces, cameras, image_size, delta, shading)
    S = int(image_size)
    p_cam, screen, inv_w, vvalid = _R.project_vertices(vertices, cams, S)
    face_index, depth, coef, keep = _dense_fragments(screen.detach(), inv_w.detach(), vvalid, faces, S, cull_backfaces)
    image = _R._shade(p_cam, screen, inv_w, faces, face_index, shading)
    if image.requires_grad or screen.requires_grad:
        image = _R._EdgeGradient.apply(image, screen, face_index, coef, keep, faces, float(delta), 1)
    return _R.RenderOutput(normals=image[:, :3], silhouette=image[:, 3], depth=depth, face_index=face_index)
