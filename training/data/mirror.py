"""Mirrored training items: the scene reflected in the input camera's vertical plane (``--mirror P``).

A mirrored item is another item of the same kind: the shape's mirror image, seen by mirrored cameras.
The reflection is the one that flips the input view left to right: in the input camera's space it
is ``M = diag(-1, 1, 1)``, in the world ``p' = S p + s`` with ``S = R0^T M R0`` and
``s = R0^T (M - I) t0`` (``s = 0`` for a camera on the plane ``x_cam = 0`` through the origin, which
every :func:`engine.camera.look_at` camera is). Camera ``j`` (``R_j``, ``t_j``, principal point
``(cx, cy)``) becomes ``R_j' = M R_j S``, ``t_j' = M t_j + M R_j s`` and ``(-cx, cy)``: then a
mirrored point lands in camera ``j'`` at ``M`` times where the original landed in camera ``j``, so
every image of the item flips left to right and every camera-space normal has its x negated. The
input camera is its own mirror apart from ``cx``.

Images follow exactly (pixel centres are symmetric about ``u = 0``): silhouettes flip; a normal
image's red channel, ``alpha (n_x + 1) / 2`` for a pixel covered by ``alpha``, becomes
``alpha - red``. Targets (the dataset's rasterised normals) are covered wholly or not at all, with
``alpha`` their silhouette. The predictor's input may be the generator's image, whose coverage is
not known: there ``alpha = clip(2 blue, 0, 1)``, exact at the outline (where a surface turns away,
``n_z = 0`` and blue is ``alpha / 2``) and 1 inside wherever the surface faces the camera.
That flipped image only approximates what the generator makes of the flipped drawing (the generator
is not mirror-equivariant); a run with ``mirror_inputs`` reads the generator's image of the flipped
drawing instead (``sketchmesh data generated --mirror``, :mod:`training.data.generated`), and an
item that reads the true image gets the true image mirrored with its silhouette as ``alpha``.

Why: the predictor underfits and generalises worse than it fits (model card); mirroring doubles the
shapes and views it sees without rendering anything, and the mirrored shape is as plausible a shape
of its category as the original.
"""

from __future__ import annotations

import torch

_MIRROR = torch.tensor([-1.0, 1.0, 1.0])


def mirror_cameras(input_cameras: torch.Tensor, cameras: torch.Tensor) -> torch.Tensor:
    """(B, ..., 16) cameras of the mirrored scene (module doc); ``input_cameras`` (B, 16) define the mirror plane."""
    b = input_cameras.shape[0]
    lead = cameras.shape[1:-1]
    flat = cameras.reshape(b, -1, 16)
    dt = cameras.dtype
    m = _MIRROR.to(device=cameras.device, dtype=dt)
    r0 = input_cameras[:, :9].reshape(b, 1, 3, 3).to(dt)
    t0 = input_cameras[:, 9:12].reshape(b, 1, 3, 1).to(dt)
    s_mat = r0.transpose(-1, -2) @ (m[:, None] * r0)  # R0^T M R0
    s_vec = r0.transpose(-1, -2) @ ((m - 1.0)[:, None] * t0)  # R0^T (M - I) t0
    r = flat[..., :9].reshape(b, -1, 3, 3)
    t = flat[..., 9:12].reshape(b, -1, 3, 1)
    r_new = m[:, None] * (r @ s_mat)
    t_new = m[:, None] * (t + r @ s_vec)
    rest = flat[..., 12:].clone()
    rest[..., 1] = -rest[..., 1]  # cx
    out = torch.cat([r_new.reshape(b, -1, 9), t_new.reshape(b, -1, 3), rest], dim=-1)
    return out.reshape(b, *lead, 16)


def mirror_normal_image(normals: torch.Tensor, coverage: torch.Tensor | None = None) -> torch.Tensor:
    """(..., 3, H, W) encoded normal images, mirrored: flipped left to right, red = coverage - red.

    ``coverage`` (..., H, W) in [0, 1] (a silhouette); None estimates it from blue (module doc).
    """
    if coverage is None:
        coverage = (2.0 * normals[..., 2, :, :]).clamp(0.0, 1.0)
    red = (coverage.to(normals.dtype) - normals[..., 0, :, :]).clamp(0.0, 1.0)
    out = torch.cat([red.unsqueeze(-3), normals[..., 1:, :, :]], dim=-3)
    return out.flip(-1)


def mirror_batch(batch: dict, flags: torch.Tensor) -> dict:
    """A mesh-mode batch with the items where ``flags`` (B,) is true mirrored (module doc); others untouched.

    Reads and returns ``normals64``, ``silhouette64``, ``camera``, ``other_*`` and ``input64`` where present.
    ``input64_mirror`` (the dataset's exact inputs of the mirrored items, ``mirror_inputs``), where
    present, replaces a mirrored item's ``input64`` instead of the flipped image, and is dropped
    from the batch returned.
    """
    flags = flags.to(torch.bool)
    exact = batch.get("input64_mirror")
    if exact is not None:
        batch = {k: v for k, v in batch.items() if k != "input64_mirror"}
    if not bool(flags.any()):
        return batch
    out = dict(batch)
    sel = flags.nonzero().flatten()

    def put(key: str, value: torch.Tensor) -> None:
        full = batch[key].clone()
        full[sel] = value.to(full.dtype)
        out[key] = full

    cam = batch["camera"][sel]
    put("normals64", mirror_normal_image(batch["normals64"][sel], batch["silhouette64"][sel]))
    put("silhouette64", batch["silhouette64"][sel].flip(-1))
    put("camera", mirror_cameras(cam, cam[:, None])[:, 0])
    if "other_cameras" in batch:
        put("other_normals64", mirror_normal_image(batch["other_normals64"][sel], batch["other_silhouette64"][sel]))
        put("other_silhouette64", batch["other_silhouette64"][sel].flip(-1))
        put("other_cameras", mirror_cameras(cam, batch["other_cameras"][sel]))
    if "input64" in batch:
        put("input64", exact[sel] if exact is not None else mirror_normal_image(batch["input64"][sel]))
    return out


def counterpart_inputs(before: dict, after: dict, flags: torch.Tensor) -> torch.Tensor:
    """(B, 3, H, W) each item's mirror counterpart of the input it reads after :func:`mirror_batch` (``mirror_consistency``).

    ``before`` / ``after``: the batch before and after ``mirror_batch(before, flags)``. An unflagged item's
    counterpart is the generator's image of its flipped drawing (``input64_mirror``) or, without it, its input
    mirrored; a flagged item's is its unmirrored input. A run that reads true normal images gets them mirrored
    exactly (the silhouette as coverage), which is also the flagged items' unmirrored image.
    """
    if "input64" not in after:
        return mirror_normal_image(after["normals64"], after["silhouette64"])
    plain = before["input64"]
    exact = before.get("input64_mirror")
    flipped = exact.to(plain.dtype) if exact is not None else mirror_normal_image(plain)
    return torch.where(flags.to(torch.bool).view(-1, 1, 1, 1), plain, flipped)


def mirror_consistency(vertices: torch.Tensor, counterpart: torch.Tensor, perm: torch.Tensor) -> torch.Tensor:
    """Mean squared distance between (B, V, 3) view-frame predictions and the (B, V, 3) predictions of their mirror
    counterparts mirrored back (x negated, vertex i taking its reflection ``perm[i]``'s place; the torch twin of
    :func:`engine.icosphere.mirror_average`). 0 for a mirror-equivariant predictor."""
    back = counterpart[:, perm] * _MIRROR.to(device=counterpart.device, dtype=counterpart.dtype)
    return ((vertices - back) ** 2).sum(-1).mean()


def mirror_points(input_camera: torch.Tensor, points: torch.Tensor) -> torch.Tensor:
    """(N, 3) world points reflected in the plane of ``input_camera`` (16,): ``S p + s`` (module doc)."""
    dt = points.dtype
    m = _MIRROR.to(device=points.device, dtype=dt)
    r0 = input_camera[:9].reshape(3, 3).to(dt)
    t0 = input_camera[9:12].to(dt)
    s_mat = r0.T @ (m[:, None] * r0)
    s_vec = r0.T @ ((m - 1.0) * t0)
    return points @ s_mat.T + s_vec
