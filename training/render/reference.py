"""Slow, loop-based reference of :func:`training.render.rasterize.rasterize` (tests only).

Same conventions, same forward and the same Eq. 1 backward as the fast rasterizer (read
:mod:`training.render.rasterize` for the definitions), written as plain Python loops over
pixels, faces and pixel pairs in float64, so each rule can be checked by reading it:

* inside test: oriented affine edge functions ``e_k = A_k * px + (B_k * py + C_k)``
  (canonical endpoint order) with the top-left rule for ``e_k == 0``;
* depth: ``sum(e) / sum(e * inv_w)``; nearest depth wins, then the smallest face index;
* shading with scalar torch ops per pixel (so autograd gives the interior gradient);
* edge gradient: a loop over every horizontally / vertically adjacent pixel pair, with the
  silhouette walk across faces done one face at a time with a dict of shared edges.

Only for tiny images (8x8 to 16x16) and a few faces: it is O(pixels x faces).
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from engine.camera import NEAR
from training.render.rasterize import (
    AREA_EPS,
    BARY_EPS,
    MAX_WALK_STEPS,
    MIN_EDGE_DISTANCE_PX,
    NORMAL_EPS_SQ,
    RenderOutput,
    _check_inputs,
)


def _project_one(vx, vy, vz, cam, S):
    """Project one vertex with scalar torch ops (same operation order as the fast path)."""
    xs = [vx * cam[3 * r] + vy * cam[3 * r + 1] + vz * cam[3 * r + 2] + cam[9 + r] for r in range(3)]
    w = -xs[2]
    valid = float(w.detach()) > NEAR
    if not valid:
        zero = vx * 0.0
        return xs, zero, zero, 0.0, False
    u = cam[12] * xs[0] / w + cam[13]
    v = cam[12] * xs[1] / w + cam[14]
    px = (u + 1.0) * (0.5 * S)
    py = (1.0 - v) * (0.5 * S)
    if not (math.isfinite(float(px.detach())) and math.isfinite(float(py.detach()))):
        zero = vx * 0.0
        return xs, zero, zero, 0.0, False
    return xs, px, py, 1.0 / w, True


def _edge_coefficients(xy, k, sgn):
    """(A, B, C) of edge k (opposite vertex k) of a face with vertices xy [(x, y)] * 3, as floats."""
    ax, ay = xy[(k + 1) % 3]
    bx, by = xy[(k + 2) % 3]
    ex, ey = bx - ax, by - ay
    swap = (bx < ax) or (bx == ax and by < ay)
    phi = -1.0 if swap else 1.0
    cx, cy = (bx, by) if swap else (ax, ay)
    A = -sgn * ey
    B = sgn * ex
    C = (sgn * phi) * ((phi * ey) * cx - (phi * ex) * cy)
    return A, B, C


def _face_info(xy, valid, cull):
    """Per-face dict with coefficients, ownership and keep flag (floats and bools)."""
    (x0, y0), (x1, y1), (x2, y2) = xy
    # doubled signed area, e_0 at vertex 0: cross(v2 - v1, v0 - v1)
    area2 = (x2 - x1) * (y0 - y1) - (y2 - y1) * (x0 - x1)
    keep = valid and abs(area2) > AREA_EPS and math.isfinite(area2)
    if cull:
        keep = keep and area2 < 0
    sgn = 1.0 if area2 >= 0 else -1.0
    edges = [_edge_coefficients(xy, k, sgn) for k in range(3)]
    own = [A > 0 or (A == 0 and B > 0) for A, B, _ in edges]
    return dict(edges=edges, own=own, keep=keep)


def _evals(info, px, py):
    return [A * px + (B * py + C) for A, B, C in info["edges"]]


def _inside(info, px, py):
    for e, own in zip(_evals(info, px, py), info["own"]):
        if not (e > 0 or (e == 0 and own)):
            return False
    return True


def _depth(e, iw):
    """Depth on a face's plane from its edge values (inf when not in front)."""
    den = (e[0] + e[1]) + e[2]
    num = (e[0] * iw[0] + e[1] * iw[1]) + e[2] * iw[2]
    if den > 0 and num > 0:
        return den / num
    return math.inf


def reference_fragments(screen_xy, inv_w, valid, faces, S, cull):
    """Loop rasterization of one image.

    Args:
        screen_xy: list of V (px, py) floats; inv_w: list of V floats; valid: list of V bools;
        faces: list of F (i, j, k); S: image side; cull: back-face culling.

    Returns:
        face_index (S x S nested lists, -1 background), depth (S x S, inf background), infos.
    """
    infos = []
    for f in faces:
        xy = [screen_xy[i] for i in f]
        infos.append(_face_info(xy, all(valid[i] for i in f), cull))
    face_index = [[-1] * S for _ in range(S)]
    depth = [[math.inf] * S for _ in range(S)]
    for row in range(S):
        for col in range(S):
            px, py = col + 0.5, row + 0.5
            best, best_f = math.inf, -1
            for fid, (f, info) in enumerate(zip(faces, infos)):
                if not info["keep"] or not _inside(info, px, py):
                    continue
                e = _evals(info, px, py)
                den = max((e[0] + e[1]) + e[2], BARY_EPS)
                iw = [inv_w[i] for i in f]
                num = max((e[0] * iw[0] + e[1] * iw[1]) + e[2] * iw[2], BARY_EPS * 1e-12)
                d = den / num
                if d < best:  # strict: equal depth keeps the smaller face index seen first
                    best, best_f = d, fid
            face_index[row][col] = best_f
            depth[row][col] = best
    return face_index, depth, infos


def _normalize(n):
    return n / torch.sqrt(torch.clamp((n * n).sum(), min=NORMAL_EPS_SQ))


def _first_exit(es, et):
    """(tau, k): where the segment s -> t leaves a face whose edge values are es, et (tau 2.0: never)."""
    best_tau, best_k = 2.0, -1
    for k in range(3):
        if et[k] < es[k]:
            e0 = max(es[k], 0.0)
            tau = e0 / (e0 - et[k])
            if tau < best_tau:
                best_tau, best_k = tau, k
    return best_tau, best_k


def reference_edge_gradient(image, grad_image, face_index, screen_xy, inv_w, faces, infos, delta, edge_range=1):
    """Loop version of the Eq. 1 gradient for one image.

    Args:
        image, grad_image: (4, S, S) float64 tensors; face_index: S x S lists; screen_xy: V (px, py);
        inv_w: V floats; faces: F triples; infos: from :func:`reference_fragments`; delta: > 0.

    Returns:
        V x 2 nested list, dL/dscreen.
    """
    S = image.shape[-1]
    V = len(screen_xy)
    img = image.tolist()
    gimg = grad_image.tolist()
    grad = [[0.0, 0.0] for _ in range(V)]
    edge_faces: dict[tuple[int, int], list[int]] = {}
    for fid, f in enumerate(faces):
        for k in range(3):
            a_, b_ = f[(k + 1) % 3], f[(k + 2) % 3]
            edge_faces.setdefault((min(a_, b_), max(a_, b_)), []).append(fid)

    def colour(r, c):
        return [img[ch][r][c] for ch in range(4)]

    def gcol(r, c):
        return [gimg[ch][r][c] for ch in range(4)]

    for axis in (0, 1):
        for row in range(S - (axis == 1)):
            for col in range(S - (axis == 0)):
                rq, cq = (row, col + 1) if axis == 0 else (row + 1, col)
                fp, fq = face_index[row][col], face_index[rq][cq]
                if fp == fq:
                    continue
                pc = (col + 0.5, row + 0.5)
                qc = (cq + 0.5, rq + 0.5)
                mid = ((pc[0] + qc[0]) / 2, (pc[1] + qc[1]) / 2)
                depths = []
                for f in (fp, fq):
                    if f < 0:
                        depths.append(math.inf)
                    else:
                        depths.append(_depth(_evals(infos[f], *mid), [inv_w[i] for i in faces[f]]))
                kp = fp if fp >= 0 else len(faces)
                kq = fq if fq >= 0 else len(faces)
                p_wins = depths[0] < depths[1] or (depths[0] == depths[1] and kp < kq)
                fstar, s, t = (fp, pc, qc) if p_wins else (fq, qc, pc)
                sigma = 1.0 if p_wins else -1.0
                ftgt = fq if p_wins else fp
                face, (tau, best_k) = fstar, _first_exit(_evals(infos[fstar], *s), _evals(infos[fstar], *t))
                steps = 0
                while tau <= 1.0:  # walk across edges of the same visible sheet (see rasterize)
                    a_, b_ = faces[face][(best_k + 1) % 3], faces[face][(best_k + 2) % 3]
                    others = [g for g in edge_faces.get((min(a_, b_), max(a_, b_)), []) if g != face]
                    if len(edge_faces[(min(a_, b_), max(a_, b_))]) != 2 or not infos[others[0]]["keep"]:
                        break
                    g = others[0]
                    if g == ftgt:
                        break
                    far = [i for i in faces[g] if i not in (a_, b_)][0]
                    if _evals(infos[face], *screen_xy[far])[best_k] >= 0:
                        break  # the neighbour folds back under this face: a silhouette edge
                    steps += 1
                    if steps > MAX_WALK_STEPS:
                        tau = 2.0
                        break
                    face = g
                    tau, best_k = _first_exit(_evals(infos[g], *s), _evals(infos[g], *t))
                if tau > 1.0:
                    continue
                tau = min(max(tau, 0.0), 1.0)
                Ip = colour(row, col)
                Iq = colour(rq, cq)
                gp, gq = gcol(row, col), gcol(rq, cq)
                lq = sum(gq[c] * (Ip[c] - Iq[c]) for c in range(4))  # q takes p's colour
                lp = sum(gp[c] * (Iq[c] - Ip[c]) for c in range(4))  # p takes q's colour
                dl_t, dl_s = (lq, lp) if p_wins else (lp, lq)
                d_t = max(1.0 - tau, MIN_EDGE_DISTANCE_PX)
                d_s = max(tau, MIN_EDGE_DISTANCE_PX)
                dldc = 0.0
                if dl_t < 0:
                    dldc += sigma * dl_t / (delta * d_t)
                if dl_s < 0:
                    dldc -= sigma * dl_s / (delta * d_s)
                # far range: pixels beyond t take s's colour, pixels beyond s take t's colour
                sp, tp = ((row, col), (rq, cq)) if p_wins else ((rq, cq), (row, col))
                silhouette_pair = face_index[tp[0]][tp[1]] < 0
                for start, new, sgn, d0, factor in ((tp, colour(*sp), sigma, 1.0 - tau, sigma),
                                                     (sp, colour(*tp), -sigma, tau, -sigma)):
                    f0 = face_index[start[0]][start[1]]
                    for j in range(1, edge_range):
                        r, c = start
                        if axis == 0:
                            c = int(c + sgn * j)
                        else:
                            r = int(r + sgn * j)
                        if not (0 <= r < S and 0 <= c < S):
                            break
                        fj = face_index[r][c]
                        if (silhouette_pair and (fj >= 0) != (f0 >= 0)) or (not silhouette_pair and fj != f0):
                            break
                        lj = sum(gcol(r, c)[ch] * (new[ch] - colour(r, c)[ch]) for ch in range(4))
                        if lj < 0:
                            dldc += factor * lj / (delta * (d0 + j))
                va = faces[face][(best_k + 1) % 3]
                vb = faces[face][(best_k + 2) % 3]
                pa, pb = screen_xy[va], screen_xy[vb]
                cross = [s[0], s[1]]
                cross[axis] += sigma * tau
                ab = (pb[0] - pa[0], pb[1] - pa[1])
                u = ((cross[0] - pa[0]) * ab[0] + (cross[1] - pa[1]) * ab[1]) / max(ab[0] ** 2 + ab[1] ** 2, BARY_EPS)
                u = min(max(u, 0.0), 1.0)
                grad[va][axis] += (1.0 - u) * dldc
                grad[vb][axis] += u * dldc
    return grad


class _RefEdge(torch.autograd.Function):
    @staticmethod
    def forward(ctx, image, screen, face_index, screen_xy, inv_w, faces, infos, delta, edge_range):
        ctx.stuff = (image.detach(), face_index, screen_xy, inv_w, faces, infos, delta, edge_range)
        return image.clone()

    @staticmethod
    def backward(ctx, grad_image):
        image, face_index, screen_xy, inv_w, faces, infos, delta, edge_range = ctx.stuff
        g = reference_edge_gradient(image, grad_image, face_index, screen_xy, inv_w, faces, infos, delta, edge_range)
        return grad_image, torch.tensor(g, dtype=image.dtype), None, None, None, None, None, None, None


def reference_rasterize(
    vertices: Tensor,
    faces: Tensor,
    cameras: Tensor,
    image_size: int,
    *,
    delta: float = 1.0,
    shading: str = "flat",
    cull_backfaces: bool = False,
    edge_range: int = 1,
) -> RenderOutput:
    """Loop reference with the signature and outputs of :func:`~training.render.rasterize.rasterize`.

    Use float64 vertices, tiny images and a few faces.
    """
    vertices, faces_t, cams = _check_inputs(vertices, faces, cameras, image_size, delta, shading)
    S = int(image_size)
    B, V, _ = vertices.shape
    faces_l = [tuple(int(i) for i in f) for f in faces_t.tolist()]
    normals_out, sil_out, depth_out, fi_out = [], [], [], []
    for b in range(B):
        cam = cams[b]
        proj = [_project_one(vertices[b, i, 0], vertices[b, i, 1], vertices[b, i, 2], cam, S) for i in range(V)]
        p_cam = [torch.stack(pr[0]) for pr in proj]
        screen = [torch.stack([pr[1], pr[2]]) for pr in proj]
        screen_t = torch.stack(screen)  # (V, 2) differentiable
        screen_xy = [(float(s[0].detach()), float(s[1].detach())) for s in screen]
        inv_w_t = [pr[3] for pr in proj]  # differentiable (smooth shading's perspective weights)
        inv_w = [float(x) if isinstance(x, float) else float(x.detach()) for x in inv_w_t]
        valid = [pr[4] for pr in proj]
        fi, depth, infos = reference_fragments(screen_xy, inv_w, valid, faces_l, S, cull_backfaces)
        # camera-space normals
        raw = [torch.linalg.cross(p_cam[f[1]] - p_cam[f[0]], p_cam[f[2]] - p_cam[f[0]]) for f in faces_l]
        if shading == "smooth":
            acc = [vertices.new_zeros(3) for _ in range(V)]
            for f, n in zip(faces_l, raw):
                for i in f:
                    acc[i] = acc[i] + n
            vn = [_normalize(a) for a in acc]
        pixels = []
        for row in range(S):
            for col in range(S):
                f = fi[row][col]
                if f < 0:
                    pixels.append(vertices.new_zeros(4))
                    continue
                if shading == "flat":
                    n = _normalize(raw[f])
                else:
                    px, py = col + 0.5, row + 0.5
                    xy = [screen[i] for i in faces_l[f]]
                    e = []
                    for k in range(3):
                        a, c = xy[(k + 1) % 3], xy[(k + 2) % 3]
                        e.append((c[0] - a[0]) * (py - a[1]) - (c[1] - a[1]) * (px - a[0]))
                    den = e[0] + e[1] + e[2]
                    if abs(float(den.detach())) < BARY_EPS:
                        den = den * 0.0 + BARY_EPS
                    mu = [e[k] / den * inv_w_t[faces_l[f][k]] for k in range(3)]
                    tot = torch.clamp(mu[0] + mu[1] + mu[2], min=BARY_EPS)
                    n = _normalize(sum(mu[k] / tot * vn[faces_l[f][k]] for k in range(3)))
                pixels.append(torch.cat([(n + 1.0) * 0.5, n.new_ones(1)]))
        image = torch.stack(pixels).view(S, S, 4).permute(2, 0, 1)
        if image.requires_grad or screen_t.requires_grad:
            image = _RefEdge.apply(image, screen_t, fi, screen_xy, inv_w, faces_l, infos, float(delta), int(edge_range))
        normals_out.append(image[:3])
        sil_out.append(image[3])
        depth_out.append(torch.tensor(depth, dtype=vertices.dtype))
        fi_out.append(torch.tensor(fi, dtype=torch.int64))
    return RenderOutput(
        normals=torch.stack(normals_out),
        silhouette=torch.stack(sil_out),
        depth=torch.stack(depth_out),
        face_index=torch.stack(fi_out),
    )
