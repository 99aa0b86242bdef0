"""Fit the icosphere template to one target mesh through the differentiable rasterizer only.

This is the proof that the renderer's gradients (paper Eq. 1) and the losses (Eq. 2-6) work:
starting from :func:`engine.icosphere.icosphere`, Adam moves a per-vertex local offset and one
global offset (the paper's deformation ``v + dv_local + dv_global``) so that the normal images
and silhouettes rendered from N views match the target's, rendered by the same rasterizer. No
3D supervision is used; 3D metrics (:mod:`training.evaluation.metrics`) are only computed at the end.

Views (:func:`fit_views`): ``N - N_extra`` azimuths evenly spread at the paper's 30 degree
elevation, plus ``N_extra = min(2, N // 3)`` views that constrain depth and the underside: one
from high above (elevation 75) and one from below (elevation -30). Each camera is framed on
the target with :func:`engine.camera.frame_camera` exactly as the data generator frames its
views, so the target fills ``1 - 2 * FRAME_MARGIN`` of every image.

The target is first normalised with :func:`engine.camera.normalize_vertices` (centred, longest
side 1), the frame the template and the metrics use.

``sketchmesh bench fit`` (argparse in :mod:`training.cli.bench`) calls :func:`main_fit`.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from engine.camera import Camera, frame_camera, look_at, normalize_vertices
from engine.errors import MeshInputError, SketchmeshError
from engine.export import export_mesh
from engine.fileio import atomic_write_text
from engine.icosphere import PAPER_LEVEL, TEMPLATE_SHAPES, template_mesh
from engine.mesh import Mesh
from training._torch import require_torch
from training.evaluation.metrics import (
    DEFAULT_VOXEL_RESOLUTION,
    silhouette_iou,
    solid_voxels,
    support_count,
    surface_metrics,
    voxel_iou,
)
from training.model.losses import NORMAL_REGIONS, LossWeights, MeshLoss

FIT_ELEVATION_DEG = 30.0
TOP_ELEVATION_DEG = 75.0
BOTTOM_ELEVATION_DEG = -30.0

DEFAULT_LR = 0.03
"""Adam step size on the offsets (normalised units: the shape spans 1)."""

DEFAULT_FIT_WEIGHTS = LossWeights(normal=0.002, silhouette=0.9, edge=0.9, smoothness=0.01)
"""The paper's weights (the normal term is rescaled to 64 x 64 pixels, see :mod:`training.losses`)."""

INIT_JITTER = 1e-3
"""Std of the seeded random perturbation of the template's vertices at the start."""

DEFAULT_FIT_THREADS = 1
"""torch intra-op threads for ``bench fit``: its tensors are small (642 vertices, N x 64 x 64 images),
so extra threads buy little, and on a busy 2-core machine they spin: measured 100 iterations
(6 views, 48 x 48) at 3.2 s CPU / 7.4 s wall with 1 thread against 24.5 s CPU / 52 s wall with 2."""

DEFAULT_ITERS = 1000

DEFAULT_SMOOTHING = 4.0
"""lambda of the large-steps parametrisation the fit uses by default (see :func:`fit_mesh`).

Measured with ``sketchmesh bench fit --procedural 1 --smoothing L`` (``reproduce_models.sh fit-damping-v31``:
the first training shape of each of the 13 categories, 8 views, 1,000 iterations): mean voxel IoU 0.795 / 0.812 /
0.814 / 0.757 at lambda 2 / 4 / 8 / 16, and 4 is the best on the legged shapes (table 0.688 against 0.174 at 16,
where the fit leaves an arch under the top instead of legs; chair 0.357 against 0.277; bench 0.950 against 0.808).
The default was 16 (the predictor basis's damping) before: the figures published with it pass ``--smoothing 16``."""

DEFAULT_NORMAL_REGION = "target"
"""Where the fit's normal term counts by default (inside the target silhouette).

Measured with ``sketchmesh bench fit --procedural 1`` (13 categories, 8 views, 64 px; after the
silhouette-gradient fix): the paper's whole-image normal term with plain offsets, 300 iterations
at lr 0.01, reaches mean silhouette IoU 0.815 / voxel IoU 0.560 and collapses thin shapes (rifle
0.03, airplane 0.49: at the paper's weights the summed normal term outweighs the IoU term and
rendering nothing is its local minimum). Inside the target with ``(I + 16 L)^-1`` offsets, 1000
iterations at lr 0.03: 0.933 / 0.733. On the four hardest shapes (airplane, lamp, rifle, bench),
300 iterations at lr 0.01: image region + smoothing 0.37 (thin shapes vanish), target region
without smoothing 0.18 (crumples), target region + smoothing 0.74."""

MAX_RESOLUTION = 512
MAX_VIEWS = 64
MAX_ITERS = 100_000
LR_DECAY_START = 0.6
"""Fraction of the iterations after which the step size decays (cosine) to 10 % at the end."""


@dataclass(frozen=True)
class FitResult:
    """What :func:`fit_mesh` returns.

    Attributes:
        mesh: the fitted mesh (template topology), in the normalised target frame.
        target: the normalised target mesh the fit and metrics used.
        silhouette_iou: per-view IoU of the fitted mesh's silhouette against the target's,
            at the fit resolution, one float per view (same order as ``views``).
        voxel_iou: solid voxel IoU at 32^3 against the normalised target.
        chamfer_l1: Chamfer-L1 (Occupancy Networks definition) against the normalised target.
        normal_consistency: normal consistency against the normalised target (1 is best).
        seconds: wall time of the fit: target rendering, the iterations and the final render
            (one-time imports and the 3D metrics excluded).
        views: (azimuth_deg, elevation_deg) per view.
        history: one dict per iteration: ``iter``, ``seconds`` (elapsed), the unweighted loss
            terms, ``total`` and ``silhouette_iou`` (mean over views of the hard IoU of that
            iteration's render, before the step).
    """

    mesh: Mesh
    target: Mesh
    silhouette_iou: list[float]
    voxel_iou: float
    chamfer_l1: float
    normal_consistency: float
    seconds: float
    views: list[tuple[float, float]]
    history: list[dict[str, float]] = field(default_factory=list)


def fit_views(n: int) -> list[tuple[float, float]]:
    """(azimuth_deg, elevation_deg) of ``n`` fit views (see the module docstring)."""
    if not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_VIEWS:
        raise ValueError(f"number of views must be an integer in [1, {MAX_VIEWS}], got {n!r}")
    n_extra = min(2, n // 3)
    n_main = n - n_extra
    views = [(360.0 * k / n_main, FIT_ELEVATION_DEG) for k in range(n_main)]
    half = 180.0 / n_main
    extras = [(half, TOP_ELEVATION_DEG), (180.0 + half, BOTTOM_ELEVATION_DEG)]
    return views + extras[:n_extra]


def fit_cameras(target: Mesh, views: list[tuple[float, float]]) -> list[Camera]:
    """One camera per view, framed on the (normalised) target like the data generator's views."""
    pts = np.asarray(target.vertices, dtype=np.float64)
    return [frame_camera(look_at(az, el), pts) for az, el in views]


def normalized_mesh(mesh: Mesh) -> Mesh:
    """The mesh centred and scaled by :func:`engine.camera.normalize_vertices`."""
    return mesh.with_vertices(normalize_vertices(mesh.vertices))


def fit_mesh(
    target: Mesh,
    *,
    views: int = 8,
    iters: int = DEFAULT_ITERS,
    resolution: int = 64,
    lr: float = DEFAULT_LR,
    weights: LossWeights | None = None,
    seed: int = 0,
    progress: bool = True,
    level: int = PAPER_LEVEL,
    delta: float = 1.0,
    shading: str = "flat",
    voxel_resolution: int = DEFAULT_VOXEL_RESOLUTION,
    voxel_surface: bool = True,
    normal_region: str = DEFAULT_NORMAL_REGION,
    smoothing: float = DEFAULT_SMOOTHING,
    edge_range: int = 1,
    silhouette: str = "eq1",
    soft_sigma: float = 1e-4,
    template: str = "sphere",
) -> FitResult:
    """Deform the icosphere so its renders match the target's from ``views`` views.

    Args:
        target: the target mesh (any frame; it is normalised first).
        views: number of views N (see :func:`fit_views`).
        iters: Adam iterations (0 returns the template's metrics).
        resolution: rendered image side S (normal images (N, 3, S, S), silhouettes (N, S, S)).
        lr: Adam step size.
        weights: Eq. 6 weights (default :data:`DEFAULT_FIT_WEIGHTS`, the paper's).
        seed: seeds the template jitter (:data:`INIT_JITTER`) and the surface sampling.
        progress: show a tqdm bar.
        level: icosphere subdivision level (3: 642 vertices / 1280 faces, the paper's).
        delta: the rasterizer's Eq. 1 gradient strength.
        shading: ``"flat"`` or ``"smooth"`` normals in the rendered images (target and fit).
        voxel_resolution: grid of the final voxel IoU.
        voxel_surface: the surface's cells count as solid (default); False: centres only
            (``--voxel-centres``, :func:`training.evaluation.metrics.solid_voxels`).
        normal_region: where the normal term counts: ``"image"`` (the paper's Eq. 2) or
            ``"target"`` (inside the target silhouette only), see :class:`training.model.losses.MeshLoss`.
        smoothing: ``lambda`` of the large-steps parametrisation (Nicolet et al. 2021): Adam moves
            ``u`` and the local offsets are ``(I + lambda L)^-1 u``; 0 moves the offsets directly.
        edge_range, silhouette, soft_sigma: the silhouette-gradient variant (see
            :func:`training.render.soft.rasterize_for_loss`); the final scores use the hard silhouette.
        template: the template's shape (:data:`engine.icosphere.TEMPLATE_SHAPES`: the sphere, or the sphere
            with four legs), at ``level``.

    Returns:
        :class:`FitResult`.

    Raises:
        ValueError: bad arguments or a target with no faces / zero size.
    """
    torch = require_torch()
    if not isinstance(target, Mesh):
        raise ValueError(f"fit_mesh target must be an engine.mesh.Mesh, got {type(target).__name__}")
    if target.num_faces == 0:
        raise ValueError("fit_mesh target has no faces")
    if not isinstance(iters, (int, np.integer)) or not 0 <= iters <= MAX_ITERS:
        raise ValueError(f"iters must be an integer in [0, {MAX_ITERS}], got {iters!r}")
    if not isinstance(resolution, (int, np.integer)) or not 8 <= resolution <= MAX_RESOLUTION:
        raise ValueError(f"resolution must be an integer in [8, {MAX_RESOLUTION}], got {resolution!r}")
    if not (isinstance(lr, (int, float)) and math.isfinite(lr) and lr > 0):
        raise ValueError(f"lr must be finite and > 0, got {lr!r}")
    weights = weights if weights is not None else DEFAULT_FIT_WEIGHTS
    if not isinstance(weights, LossWeights):
        raise ValueError(f"fit_mesh weights must be a LossWeights, got {type(weights).__name__}")
    if normal_region not in NORMAL_REGIONS:
        raise ValueError(f"normal_region must be one of {NORMAL_REGIONS}, got {normal_region!r}")
    if not (isinstance(smoothing, (int, float)) and math.isfinite(smoothing) and smoothing >= 0):
        raise ValueError(f"smoothing must be finite and >= 0, got {smoothing!r}")
    if template not in TEMPLATE_SHAPES:
        raise ValueError(f"template must be one of {TEMPLATE_SHAPES}, got {template!r}")
    view_list = fit_views(views)

    from training.render import cameras_to_tensor, rasterize
    from training.render.soft import rasterize_for_loss

    dtype = torch.float32
    template = template_mesh(level, shape=template)
    gen = torch.Generator().manual_seed(int(seed))
    base = torch.tensor(np.array(template.vertices), dtype=dtype)  # (V, 3)
    base = base + INIT_JITTER * torch.randn(base.shape, generator=gen, dtype=dtype)
    faces = torch.tensor(np.array(template.faces), dtype=torch.int64)
    mesh_loss = MeshLoss(template, weights, normal_region=normal_region)
    smoother = None
    if smoothing > 0:
        from training.model.networks import smoothing_operator

        smoother = torch.as_tensor(smoothing_operator(np.asarray(template.faces), template.num_vertices, smoothing))
    local = torch.zeros_like(base, requires_grad=True)  # (V, 3): offsets, or u when smoothing
    global_offset = torch.zeros(3, dtype=dtype, requires_grad=True)
    optimizer = torch.optim.Adam([local, global_offset], lr=float(lr))  # first use imports torch._dynamo (~2 s)

    start = time.perf_counter()  # timed from here: target rendering, the iterations, the final render
    target_n = normalized_mesh(target)
    cams = fit_cameras(target_n, view_list)
    cam_t = cameras_to_tensor(cams, dtype=dtype)  # (N, 16)
    n_views = len(cams)
    with torch.no_grad():
        tv = torch.tensor(np.array(target_n.vertices), dtype=dtype)[None].expand(n_views, -1, -1)
        tf = torch.tensor(np.array(target_n.faces), dtype=torch.int64)
        tgt = rasterize(tv, tf, cam_t, resolution, delta=delta, shading=shading)
        target_normals, target_sil = tgt.normals.clone(), tgt.silhouette.clone()  # (N, 3, S, S), (N, S, S)
    decay_from = int(LR_DECAY_START * iters)

    def lr_factor(step: int) -> float:
        if step < decay_from or iters <= decay_from:
            return 1.0
        t = (step - decay_from) / max(1, iters - decay_from)
        return 0.1 + 0.9 * 0.5 * (1.0 + math.cos(math.pi * t))

    scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, lr_factor)

    def current_vertices():
        offsets = local if smoother is None else smoother @ local
        return base + offsets + global_offset  # (V, 3)

    history: list[dict[str, float]] = []
    bar = None
    if progress and iters > 0:
        from tqdm import tqdm

        bar = tqdm(total=iters, desc="fit", unit="it", leave=False)
    try:
        for it in range(iters):
            verts = current_vertices().expand(n_views, -1, -1)  # (N, V, 3)
            out = rasterize_for_loss(verts, faces, cam_t, resolution, delta=delta, shading=shading,
                                     edge_range=edge_range, silhouette=silhouette, soft_sigma=soft_sigma)
            loss, log = mesh_loss(verts, out.normals, target_normals, out.silhouette, target_sil)
            # the edge and smoothness terms are per mesh: the N copies average to the one mesh's value
            if not math.isfinite(log["total"]):
                raise FloatingPointError(f"fit loss became non-finite at iteration {it}: {log}")
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            scheduler.step()
            with torch.no_grad():
                hard = out.silhouette > 0.5
                tgt_hard = target_sil > 0.5
                inter = (hard & tgt_hard).flatten(1).sum(1).double()
                union = (hard | tgt_hard).flatten(1).sum(1).double()
                mean_iou = float(torch.where(union > 0, inter / union.clamp(min=1), torch.ones_like(union)).mean())
            log.update(iter=float(it), seconds=time.perf_counter() - start, silhouette_iou=mean_iou)
            history.append(log)
            if bar is not None:
                bar.set_postfix(loss=f"{log['total']:.4f}", iou=f"{mean_iou:.3f}", refresh=False)
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()

    with torch.no_grad():
        final_v = current_vertices().detach()
        out = rasterize(final_v[None].expand(n_views, -1, -1), faces, cam_t, resolution, delta=delta, shading=shading)
    seconds = time.perf_counter() - start
    fitted = Mesh(final_v.numpy().astype(np.float32), template.faces)
    sil = [silhouette_iou(out.silhouette[k].numpy() > 0.5, target_sil[k].numpy() > 0.5) for k in range(n_views)]
    try:
        surf = surface_metrics(fitted, target_n, seed=int(seed))
    except ValueError:  # a fit collapsed to zero area: worst scores rather than a crash
        surf = {"chamfer_l1": float("nan"), "normal_consistency": 0.0}
    return FitResult(
        mesh=fitted,
        target=target_n,
        silhouette_iou=sil,
        voxel_iou=voxel_iou(fitted, target_n, voxel_resolution, voxel_surface),
        chamfer_l1=surf["chamfer_l1"],
        normal_consistency=surf["normal_consistency"],
        seconds=seconds,
        views=view_list,
        history=history,
    )


# --------------------------------------------------------------------------- CLI


def load_target_mesh(path: str) -> Mesh:
    """Read any mesh file trimesh reads (scenes are merged); MeshInputError names the path on failure."""
    import os

    import trimesh

    if not os.path.isfile(path):
        raise MeshInputError(f"mesh file not found: {path}")
    try:
        tm = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for corrupt files
        raise MeshInputError(f"cannot read mesh file {path}: {type(exc).__name__}: {exc}") from None
    faces = getattr(tm, "faces", None)
    vertices = getattr(tm, "vertices", None)
    if faces is None or vertices is None or len(faces) == 0:
        raise MeshInputError(f"mesh file {path} has no triangles")
    try:
        mesh = Mesh(np.asarray(vertices), np.asarray(faces))
        normalize_vertices(mesh.vertices)
    except ValueError as exc:
        raise MeshInputError(f"mesh file {path} is not usable: {exc}") from None
    return mesh


def _fit_options(args) -> dict:
    """The optional fit settings given on the command line (``--normal-region``, ``--smoothing``, ``--lr``,
    ``--template``, ``--voxel-centres``)."""
    opts = {k: getattr(args, k) for k in ("normal_region", "smoothing", "lr", "template")
            if getattr(args, k, None) is not None}
    if getattr(args, "voxel_centres", False):
        opts["voxel_surface"] = False
    return opts


def _int_arg(args, name: str, lo: int, hi: int, default: int) -> int:
    value = getattr(args, name, None)
    value = default if value is None else value
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or not lo <= value <= hi:
        raise SketchmeshError(f"--{name} must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


def format_fit_report(result: FitResult, iters: int, resolution: int) -> str:
    """The table ``sketchmesh bench fit`` prints: per-view IoU, IoU against time, 3D metrics."""
    lines = [f"{'view':>4}  {'azimuth':>7}  {'elev':>5}  {'silhouette IoU':>14}"]
    for k, ((az, el), iou) in enumerate(zip(result.views, result.silhouette_iou)):
        lines.append(f"{k:>4}  {az:>7.1f}  {el:>5.1f}  {iou:>14.4f}")
    lines.append("")
    if result.history:
        lines.append(f"{'iter':>6}  {'seconds':>8}  {'mean sil IoU':>12}  {'loss':>9}")
        marks = sorted({0, *(int(round(f * (len(result.history) - 1))) for f in (0.1, 0.25, 0.5, 0.75, 1.0))})
        for i in marks:
            h = result.history[i]
            lines.append(f"{int(h['iter']):>6}  {h['seconds']:>8.2f}  {h['silhouette_iou']:>12.4f}  {h['total']:>9.4f}")
        lines.append("")
    per_iter = result.seconds / iters if iters else float("nan")
    lines += [
        f"min / mean silhouette IoU : {min(result.silhouette_iou):.4f} / {float(np.mean(result.silhouette_iou)):.4f}",
        f"voxel IoU (32^3)          : {result.voxel_iou:.4f}",
        f"chamfer-L1 / normal cons. : {result.chamfer_l1:.4f} / {result.normal_consistency:.4f}",
        f"time                      : {result.seconds:.2f} s ({iters} iterations, {per_iter * 1e3:.1f} ms/iter, "
        f"{len(result.views)} views at {resolution}x{resolution})",
    ]
    return "\n".join(lines)


def main_fit(args) -> int:
    """``sketchmesh bench fit``: fit the icosphere to ``--target`` and report accuracy against time.

    Reads ``args.target`` (path), ``args.views``, ``args.iters``, ``args.resolution``,
    ``args.json`` (path or None) and ``args.seed``. Prints the per-view silhouette IoU, the IoU
    against elapsed time, voxel IoU at 32^3, Chamfer-L1 and the time; with ``--json`` writes
    (atomically) a record with at least ``silhouette_iou`` (list), ``voxel_iou`` and ``seconds``.
    """
    torch = require_torch()
    target_path = getattr(args, "target", None)
    per_category = getattr(args, "procedural", None)
    if bool(target_path) == bool(per_category):
        raise SketchmeshError("bench fit needs exactly one of --target MESH_FILE or --procedural N")
    if per_category:
        return main_fit_procedural(args)
    for flag in ("categories", "meshes", "split"):
        if getattr(args, flag, None):
            raise SketchmeshError(f"--{flag} goes with --procedural N, not --target")
    views = _int_arg(args, "views", 1, MAX_VIEWS, 8)
    iters = _int_arg(args, "iters", 0, MAX_ITERS, DEFAULT_ITERS)
    resolution = _int_arg(args, "resolution", 8, MAX_RESOLUTION, 64)
    seed = _int_arg(args, "seed", 0, 2**31 - 1, 0)
    level = _int_arg(args, "level", 0, 5, PAPER_LEVEL)  # optional flag; the paper's level 3 when absent
    threads = _int_arg(args, "threads", 1, 256, DEFAULT_FIT_THREADS)  # optional flag
    template = getattr(args, "template", None) or "sphere"  # optional flag
    json_path = getattr(args, "json", None)
    target = load_target_mesh(str(target_path))
    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        result = fit_mesh(target, views=views, iters=iters, resolution=resolution, seed=seed, progress=True, level=level,
                          **_fit_options(args))
    finally:
        torch.set_num_threads(before)
    print(f"fit: {target_path} ({target.num_vertices} vertices, {target.num_faces} faces) "
          f"<- {template} template, icosphere level {level} "
          f"({result.mesh.num_vertices} vertices)")
    print(format_fit_report(result, iters, resolution))
    if json_path:
        record = {
            "benchmark": "fit",
            "target": str(target_path),
            "views": [{"azimuth_deg": az, "elevation_deg": el} for az, el in result.views],
            "iters": iters,
            "resolution": resolution,
            "seed": seed,
            "template_level": level,
            "template": template,
            "silhouette_iou": result.silhouette_iou,
            "voxel_iou": result.voxel_iou,
            "chamfer_l1": result.chamfer_l1,
            "normal_consistency": result.normal_consistency,
            "seconds": result.seconds,
            "threads": threads,
            "ms_per_iter": 1e3 * result.seconds / iters if iters else None,
            "history": [
                {k: h[k] for k in ("iter", "seconds", "silhouette_iou", "total")} for h in result.history
            ],
        }
        atomic_write_text(json_path, json.dumps(record, indent=2) + "\n")
        print(f"wrote {json_path}")
    return 0


def procedural_targets(per_category: int, split: str = "train",
                       categories: tuple[str, ...] | None = None) -> list[tuple[str, str, Mesh]]:
    """(category, shape id, mesh) of the first ``per_category`` procedural shapes of ``split`` per category
    (of ``categories`` only when given, in the library's order)."""
    from training.data.shapes import CATEGORIES, make_shape, shape_id, split_of

    out = []
    for c in CATEGORIES:
        if categories is not None and c not in categories:
            continue
        i, found = 0, 0
        while found < per_category:
            if split_of(c, i) == split:
                out.append((c, shape_id(c, i), make_shape(c, i)))
                found += 1
            i += 1
    return out


def parse_categories(text: str | None) -> tuple[str, ...] | None:
    """``--categories``' comma-separated names, checked against the procedural library (None: every category)."""
    from training.data.shapes import CATEGORIES

    if text is None:
        return None
    names = tuple(dict.fromkeys(n.strip() for n in str(text).split(",") if n.strip()))
    unknown = [n for n in names if n not in CATEGORIES]
    if not names or unknown:
        raise SketchmeshError(f"--categories takes a comma-separated list of {', '.join(CATEGORIES)}; "
                              f"got {text!r}" + (f" ({', '.join(unknown)} unknown)" if unknown else ""))
    return names


def main_fit_procedural(args) -> int:
    """``sketchmesh bench fit --procedural N``: the direct-fit ceiling on the first N shapes of the split (``--split``,
    default train) of every category (``--categories``: of those only).

    Prints one row per shape (mean / min silhouette IoU over the fit views, voxel IoU, Chamfer-L1, the separate
    supports the fit and the target stand on (:func:`~training.evaluation.metrics.support_count` at the voxel
    grid), seconds) and the means; ``--json`` writes them, ``--meshes DIR`` each fitted mesh as ``SHAPE_ID.obj``
    in the normalised target frame.
    """
    torch = require_torch()
    per_category = _int_arg(args, "procedural", 1, 1000, 1)
    views = _int_arg(args, "views", 1, MAX_VIEWS, 8)
    iters = _int_arg(args, "iters", 0, MAX_ITERS, DEFAULT_ITERS)
    resolution = _int_arg(args, "resolution", 8, MAX_RESOLUTION, 64)
    seed = _int_arg(args, "seed", 0, 2**31 - 1, 0)
    level = _int_arg(args, "level", 0, 5, PAPER_LEVEL)
    threads = _int_arg(args, "threads", 1, 256, DEFAULT_FIT_THREADS)
    extra = _fit_options(args)
    json_path = getattr(args, "json", None)
    mesh_dir = getattr(args, "meshes", None)
    split = getattr(args, "split", None) or "train"
    targets = procedural_targets(per_category, split, categories=parse_categories(getattr(args, "categories", None)))
    if mesh_dir:
        os.makedirs(mesh_dir, exist_ok=True)
    voxel_surface = extra.get("voxel_surface", True)
    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    rows = []
    try:
        from tqdm import tqdm

        for category, sid, mesh in tqdm(targets, desc="fit shapes", unit="shape"):
            r = fit_mesh(mesh, views=views, iters=iters, resolution=resolution, seed=seed, progress=False,
                         level=level, **extra)
            rows.append({"category": category, "shape_id": sid, "silhouette_iou": float(np.mean(r.silhouette_iou)),
                         "min_silhouette_iou": float(min(r.silhouette_iou)), "voxel_iou": r.voxel_iou,
                         "chamfer_l1": r.chamfer_l1, "seconds": r.seconds,
                         "supports": support_count(solid_voxels(r.mesh, DEFAULT_VOXEL_RESOLUTION, voxel_surface)),
                         "target_supports": support_count(solid_voxels(r.target, DEFAULT_VOXEL_RESOLUTION,
                                                                       voxel_surface))})
            if mesh_dir:
                export_mesh(r.mesh, os.path.join(mesh_dir, f"{sid}.obj"))
    finally:
        torch.set_num_threads(before)
    print(f"fit: {len(rows)} procedural {split} shapes <- icosphere level {level}, {iters} iterations, "
          f"{views} views at {resolution}x{resolution}, {extra or 'default settings'}")
    print(f"{'shape':<20} {'sil IoU':>8} {'min':>6} {'voxel':>6} {'chamfer':>8} {'supports':>8} {'s':>6}")
    for r in rows:
        print(f"{r['shape_id']:<20} {r['silhouette_iou']:>8.3f} {r['min_silhouette_iou']:>6.3f} {r['voxel_iou']:>6.3f} "
              f"{r['chamfer_l1']:>8.4f} {str(r['supports']) + ' / ' + str(r['target_supports']):>8} {r['seconds']:>6.1f}")
    mean = {k: float(np.nanmean([r[k] for r in rows])) for k in ("silhouette_iou", "min_silhouette_iou", "voxel_iou",
                                                               "chamfer_l1", "seconds")}
    print(f"{'mean':<20} {mean['silhouette_iou']:>8.3f} {mean['min_silhouette_iou']:>6.3f} {mean['voxel_iou']:>6.3f} "
          f"{mean['chamfer_l1']:>8.4f} {'':>8} {mean['seconds']:>6.1f}")
    if json_path:
        record = {"benchmark": "fit-procedural", "split": split, "per_category": per_category, "iters": iters,
                  "views": views,
                  "resolution": resolution, "template_level": level, "settings": extra, "shapes": rows, "mean": mean}
        atomic_write_text(json_path, json.dumps(record, indent=2) + "\n")
        print(f"wrote {json_path}")
    return 0


def ceiling_rows(fit_records: list[dict], eval_record: dict, column: str) -> list[dict]:
    """Each fitted shape beside what a model folder made of its drawings: the direct fit as the ceiling.

    Args:
        fit_records: ``bench fit --procedural --json`` records (their ``shapes`` rows).
        eval_record: an ``eval --models --json`` record (its ``rows``, with ``per_view`` ``iou`` and ``supports``)
            on a dataset holding the same shapes.
        column: the model folder's column in ``eval_record``.

    Returns:
        One dict a fitted shape found in ``eval_record`` (in the fits' order): ``category``, ``shape_id``,
        ``true_supports``, ``fit_voxel_iou``, ``fit_supports``, ``drawings``, ``model_voxel_iou`` (the mean over its
        drawings), ``model_separate`` (the share of its drawings whose mesh stands on two or more supports) and
        ``model_same`` (on as many as the shape). A shape the eval does not hold is left out.

    Raises:
        SketchmeshError: ``column`` is not one of the eval's model columns; a record measures voxels on another grid
            (resolution or surface cells) than the other; a fit row has no support counts (a record written before
            they were counted); the fit's and the eval's count of a shape's own supports differ (not the same
            shape); or no drawing of a fitted shape has a score in ``column``.
    """
    columns = [c for c in eval_record.get("columns", []) if c != "template"]
    if column not in columns:
        raise SketchmeshError(f"no model column {column!r} in the eval record (its columns: {', '.join(columns)})")
    eval_grid = (int(eval_record.get("voxel_resolution", DEFAULT_VOXEL_RESOLUTION)),
                 bool(eval_record.get("voxel_surface", True)))
    by_id = {r["shape_id"]: r for r in eval_record["rows"]}
    out = []
    for rec in fit_records:
        fit_grid = (DEFAULT_VOXEL_RESOLUTION, (rec.get("settings") or {}).get("voxel_surface", True) is not False)
        if fit_grid != eval_grid:
            raise SketchmeshError(f"the fits count voxels at {fit_grid[0]}^3 with surface cells {fit_grid[1]}, the "
                                  f"eval at {eval_grid[0]}^3 with surface cells {eval_grid[1]}: not comparable")
        for f in rec["shapes"]:
            if "supports" not in f or "target_supports" not in f:
                raise SketchmeshError(f"{f.get('shape_id')}: the fit record has no support counts (rerun bench fit)")
            e = by_id.get(f["shape_id"])
            if e is None:
                continue
            if e["category"] != f["category"] or e["true_supports"] != f["target_supports"]:
                raise SketchmeshError(f"{f['shape_id']}: the fit's shape ({f['category']}, {f['target_supports']} "
                                      f"supports) is not the eval's ({e['category']}, {e['true_supports']})")
            views = [v for v in e["per_view"] if v["iou"].get(column) is not None]
            if not views:
                raise SketchmeshError(f"{f['shape_id']}: no drawing of it has a {column!r} score")
            sup = [v["supports"][column] for v in views]
            out.append({"category": f["category"], "shape_id": f["shape_id"], "true_supports": f["target_supports"],
                        "fit_voxel_iou": f["voxel_iou"], "fit_supports": f["supports"], "drawings": len(views),
                        "model_voxel_iou": float(np.mean([v["iou"][column] for v in views])),
                        "model_separate": float(np.mean([s >= 2 for s in sup])),
                        "model_same": float(np.mean([s == f["target_supports"] for s in sup]))})
    return out


def ceiling_table(rows: list[dict]) -> str:
    """:func:`ceiling_rows` as markdown: a line a shape, then a line a category (its shapes' means; the supports over
    its shapes on two or more)."""
    lines = ["| shape | supports | fit: voxel / supports | model: voxel / on 2+ / on as many |",
             "|---|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['shape_id']} | {r['true_supports']} | {r['fit_voxel_iou']:.3f} / {r['fit_supports']} | "
                     f"{r['model_voxel_iou']:.3f} / {r['model_separate']:.2f} / {r['model_same']:.2f} |")
    lines += ["", "| category | shapes | fit voxel | model voxel | standing shapes | fit on 2+ / on as many | "
              "model on 2+ / on as many |", "|---|---:|---:|---:|---:|---:|---:|"]
    def share(vals):
        return f"{np.mean(vals):.2f}" if vals else "-"

    for c in dict.fromkeys(r["category"] for r in rows):
        rs = [r for r in rows if r["category"] == c]
        st = [r for r in rs if r["true_supports"] >= 2]
        lines.append(
            f"| {c} | {len(rs)} | {np.mean([r['fit_voxel_iou'] for r in rs]):.3f} | "
            f"{np.mean([r['model_voxel_iou'] for r in rs]):.3f} | {len(st)} | "
            f"{share([r['fit_supports'] >= 2 for r in st])} / {share([r['fit_supports'] == r['true_supports'] for r in st])} | "
            f"{share([r['model_separate'] for r in st])} / {share([r['model_same'] for r in st])} |")
    return "\n".join(lines)
