"""``sketchmesh bench overfit``: can the mesh predictor learn a handful of shapes as well as a direct fit?

The first check to make before tuning anything: trained on a few shapes with their ground-truth
normal images (mode ``mesh``, no sketches, no augmentation) for a fixed wall time, the predictor
must reproduce those same shapes about as well as direct optimisation of one mesh per shape
(:func:`training.bench.fit.fit_mesh`, the ceiling of the template and the 2D losses). If it
cannot, something between the data and the loss is wrong (a camera, an image convention, a
scale, a biased gradient), not the amount of training.

Both are scored the same way, on the shapes' own dataset views (24 azimuths at 30 degrees):

* **silhouette IoU**: the mesh rendered from every dataset view at 64 x 64 against the stored
  silhouette, averaged over views. The predictor's mesh is predicted from ``--input-views``
  input views per shape (view frame, rotated back to the world) and each is scored on all views.
* **voxel IoU** (32^3) against the shape's mesh, and the time each took.

The predictor's learning rate decays along half a cosine over ``--iters`` iterations (the
default 4,700 is what 20 minutes hold on the 2-core reference machine; a faster machine ends
sooner, a slower one stops at ``--minutes`` before the rate has decayed).

Steps (each resumes): build ``OUT/data`` (``--shapes`` procedural train-split shapes, one per
category in turn) unless ``--data`` names a dataset, train ``OUT/run`` for ``--minutes``, fit
every shape directly (cached per dataset), write ``OUT/overfit.json`` and ``OUT/overfit.png`` (each
shape's dataset normal images above the predicted mesh from the same views) and print the table.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from engine.errors import SketchmeshError
from engine.fileio import atomic_write_text
from engine.mesh import Mesh

DEFAULT_SHAPES = 8
DEFAULT_MINUTES = 20.0
DEFAULT_INPUT_VIEWS = (0, 6, 12, 18)
GAP_TARGET = 0.05
"""The predictor passes when its mean silhouette IoU is within this of the direct fit's."""


def overfit_jobs(n: int):
    """``n`` procedural train-split shapes: the first of each category in turn, then the second..."""
    from training.data.dataset import Job
    from training.data.shapes import CATEGORIES, shape_id, split_of

    jobs, per_cat = [], {c: 0 for c in CATEGORIES}
    while len(jobs) < n:
        for c in CATEGORIES:
            if len(jobs) == n:
                break
            i = per_cat[c]
            while split_of(c, i) != "train":
                i += 1
            per_cat[c] = i + 1
            jobs.append(Job(c, shape_id(c, i), "train", "procedural", i))
    return jobs


def silhouette_ious(world_vertices: np.ndarray, faces: np.ndarray, cameras: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """(N,) IoU of one world-frame mesh's silhouettes from N cameras against (N, S, S) targets."""
    import torch

    from training.evaluation.metrics import silhouette_iou
    from training.render import rasterize

    n, size = targets.shape[0], targets.shape[-1]
    v = torch.from_numpy(np.ascontiguousarray(world_vertices, dtype=np.float64))[None].expand(n, -1, -1)
    with torch.no_grad():
        out = rasterize(v, torch.from_numpy(np.array(faces, np.int64)), torch.from_numpy(np.array(cameras, np.float64)), size)
    sil = out.silhouette.numpy() > 0.5
    return np.array([silhouette_iou(sil[k], targets[k] > 0.5) for k in range(n)])


SHEET_VIEWS = (0, 3, 6, 9, 12, 18)
"""Dataset views shown in ``overfit.png`` (the predictor's mesh is predicted from view 0)."""


def score_predictor(run_dir: Path, dataset, input_views, sheet: Path | None = None,
                    voxel_surface: bool = True) -> list[dict]:
    """Per shape: mean silhouette IoU over all views and voxel IoU, predicted from ``input_views``.

    With ``sheet``, also writes a PNG: per shape, the dataset's normal images from
    :data:`SHEET_VIEWS` above the mesh predicted from view 0 rendered from the same views.
    """
    import torch

    from training.evaluation.evaluate import world_vertices
    from training.evaluation.metrics import grid_iou, solid_voxels, support_count
    from training.loop.trainer import load_run, write_png
    from training.render import rasterize

    cfg, models, state = load_run(run_dir)
    predictor = models["predictor"]
    faces = predictor.template_faces.numpy()
    rows, tiles = [], []
    for category, sid, _ in dataset.shapes():
        mesh = dataset.load_mesh(category, sid)
        cams, sils, n64 = (dataset.shape_array(category, sid, k) for k in ("cameras", "silhouette64", "normals64"))
        views = [v for v in input_views if v < len(cams)]
        inp = torch.from_numpy(np.ascontiguousarray(n64[views].transpose(0, 3, 1, 2), np.float32))
        with torch.no_grad():
            local, glob = predictor(inp)
            verts = predictor.vertices(local, glob).double().numpy()
        ious, vox, sup = [], [], []
        gt_vox = solid_voxels(mesh, surface=voxel_surface)  # once a shape, each view's mesh once a view
        true_supports = support_count(gt_vox)
        for k, v in enumerate(views):
            world = world_vertices(verts[k], cams[v])
            pred_vox = solid_voxels(Mesh(world.astype(np.float32), faces), surface=voxel_surface)
            ious.append(float(silhouette_ious(world, faces, cams, sils).mean()))
            vox.append(grid_iou(pred_vox, gt_vox))
            sup.append(support_count(pred_vox))
        rows.append({"category": category, "shape_id": sid, "silhouette_iou": float(np.mean(ious)),
                     "voxel_iou": float(np.mean(vox)), "true_supports": true_supports,
                     "separate": float(np.mean([n >= 2 for n in sup])) if sup else float("nan"),
                     "same": float(np.mean([n == true_supports for n in sup])) if sup else float("nan")})
        if sheet is not None and views and views[0] == 0:
            shown = [v for v in SHEET_VIEWS if v < len(cams)]
            world = torch.from_numpy(world_vertices(verts[0], cams[0]))[None].expand(len(shown), -1, -1)
            with torch.no_grad():
                rendered = rasterize(world, torch.from_numpy(np.array(faces, np.int64)),
                                     torch.from_numpy(np.array(cams[shown], np.float64)), n64.shape[1])
            pred = rendered.normals.numpy().transpose(0, 2, 3, 1)
            tiles.append(np.concatenate([np.concatenate([n64[v] for v in shown], 1),
                                         np.concatenate(list(pred), 1)], 0))
    if sheet is not None and tiles:
        width = max(t.shape[1] for t in tiles)
        tiles = [np.pad(t, ((0, 2), (0, width - t.shape[1]), (0, 0)), constant_values=1.0) for t in tiles]
        write_png(sheet, (np.clip(np.concatenate(tiles, 0), 0, 1) * 255).astype(np.uint8))
    return rows


def score_fit(dataset, *, iters: int, views: int, seed: int, progress: bool, **fit_kwargs) -> list[dict]:
    """Per shape: direct fit (:func:`training.bench.fit.fit_mesh`), scored on the dataset's views.

    The rows are cached in ``DATA/.cache/overfit_fit.json`` under a key of the shapes and every fit
    setting (derived data, safe to delete), so comparing predictor variants on one dataset fits once.
    """
    from training.bench.fit import fit_mesh
    from training.data.mesh_cache import CACHE_DIR
    from training.evaluation.metrics import grid_iou, solid_voxels, support_count

    shapes = [sid for _, sid, _ in dataset.shapes()]
    # the voxel measure is always part of the key: rows scored by cell centres are never reused for the surface measure
    measure = "surface" if fit_kwargs.get("voxel_surface", True) else "centres"
    # "rows": 2 since the rows carry the fit's supports: rows cached before are fitted again rather than shown without them
    key = json.dumps({"shapes": shapes, "iters": iters, "views": views, "seed": seed, "voxels": measure, "rows": 2,
                      **{k: v for k, v in fit_kwargs.items() if k != "voxel_surface"}}, sort_keys=True)
    cache_path = Path(dataset.root) / CACHE_DIR / "overfit_fit.json"
    try:
        cached = json.loads(cache_path.read_text())
    except (OSError, ValueError):
        cached = {}
    if isinstance(cached, dict) and key in cached:
        return cached[key]
    rows = []
    for category, sid, _ in dataset.shapes():
        mesh = dataset.load_mesh(category, sid)
        cams, sils = (dataset.shape_array(category, sid, k) for k in ("cameras", "silhouette64"))
        res = fit_mesh(mesh, views=views, iters=iters, seed=seed, progress=progress, **fit_kwargs)
        fitted = res.mesh  # the normalised target frame, which the dataset's meshes are already in
        ious = silhouette_ious(fitted.vertices, fitted.faces, cams, sils)
        surface = fit_kwargs.get("voxel_surface", True)
        fit_vox = solid_voxels(fitted, surface=surface)  # once, for the IoU and the supports
        rows.append({"category": category, "shape_id": sid, "silhouette_iou": float(ious.mean()),
                     "voxel_iou": grid_iou(fit_vox, solid_voxels(mesh, surface=surface)),
                     "supports": support_count(fit_vox), "seconds": res.seconds})
    try:
        cache_path.parent.mkdir(exist_ok=True)
        atomic_write_text(cache_path, json.dumps({**(cached if isinstance(cached, dict) else {}), key: rows}) + "\n")
    except OSError:
        pass  # a read-only dataset: fit again next time
    return rows


def _supports_cell(fit: dict, pred: dict) -> str:
    """'fit N, pred A / B': the fit's support count (when its row has one) and the shares of the predictor's views whose
    mesh stands on two or more / on the shape's own count (when its row has them), against the shape's count."""
    if "true_supports" not in pred:
        return ""
    fit_n = f"fit {fit['supports']}, " if "supports" in fit else ""
    return f"{pred['true_supports']}: {fit_n}pred {pred['separate']:.2f} / {pred['same']:.2f}"


def format_table(fit_rows: list[dict], pred_rows: list[dict]) -> str:
    """The per-shape table of fit against predictor (silhouette gap, voxel IoU; the supports: the shape's count, the
    fit's, and the shares of predicted views on two or more / on as many), then the means."""
    lines = [f"{'shape':<22} {'fit sil':>8} {'pred sil':>8} {'gap':>7} {'fit vox':>8} {'pred vox':>8}  supports"]
    for f, p in zip(fit_rows, pred_rows):
        lines.append(f"{f['shape_id']:<22} {f['silhouette_iou']:>8.3f} {p['silhouette_iou']:>8.3f} "
                     f"{f['silhouette_iou'] - p['silhouette_iou']:>7.3f} {f['voxel_iou']:>8.3f} {p['voxel_iou']:>8.3f}"
                     f"  {_supports_cell(f, p)}")
    fs = float(np.mean([r["silhouette_iou"] for r in fit_rows]))
    ps = float(np.mean([r["silhouette_iou"] for r in pred_rows]))
    fv = float(np.mean([r["voxel_iou"] for r in fit_rows]))
    pv = float(np.mean([r["voxel_iou"] for r in pred_rows]))
    lines.append(f"{'mean':<22} {fs:>8.3f} {ps:>8.3f} {fs - ps:>7.3f} {fv:>8.3f} {pv:>8.3f}")
    return "\n".join(lines)


def main_overfit(args) -> int:
    """``sketchmesh bench overfit``; see the module docstring."""
    import torch

    from training.data.dataset import BuildSettings, ShapeViewDataset, build_dataset
    from training.loop.config import TrainConfig
    from training.loop.trainer import Trainer

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise SketchmeshError(f"--out {out} is a file, not a folder")
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(int(args.threads))
    if args.data:
        data_dir = Path(args.data)
        if not (data_dir / "manifest.json").is_file():
            raise SketchmeshError(f"--data {data_dir} is not a dataset (no manifest.json; make one with sketchmesh data)")
    else:
        data_dir = out / "data"
        build_dataset(data_dir, overfit_jobs(args.shapes), BuildSettings(), workers=1, progress=not args.quiet)
    first = ShapeViewDataset(data_dir, "train", extra_views=0, augment_strength=0.0).shapes()[: args.shapes]
    if not first:
        raise SketchmeshError(f"the train split of {data_dir} has no shapes")
    shape_ids = [s for _, s, _ in first]
    categories = sorted({c for c, _, _ in first})
    dataset = ShapeViewDataset(data_dir, "train", extra_views=0, augment_strength=0.0, shape_ids=shape_ids)

    overrides = dict(args.set or [])
    cfg = TrainConfig(mode="mesh", data_dir=str(data_dir), out_dir=str(out / "run"), iters=args.iters,
                      max_minutes=float(args.minutes), batch=args.batch, augment_strength=0.0, val_every=0,
                      ckpt_every=200, plot_every=200, categories=tuple(categories), seed=args.seed)
    if overrides:
        try:
            cfg = TrainConfig.from_dict({**cfg.to_dict(), **overrides})
        except (ValueError, TypeError) as exc:
            raise SketchmeshError(f"--set: {exc}") from None
    train_set = ShapeViewDataset(data_dir, "train", extra_views=cfg.extra_views, seed=cfg.seed, shape_ids=shape_ids,
                                 fields="mesh")
    from training.bench.fit import DEFAULT_ITERS

    fit_iters = DEFAULT_ITERS if args.fit_iters is None else args.fit_iters
    t0 = time.perf_counter()
    Trainer(cfg, progress=not args.quiet, train_set=train_set, val_set=None).run()
    train_s = time.perf_counter() - t0
    surface = not args.voxel_centres
    pred_rows = score_predictor(out / "run", dataset, DEFAULT_INPUT_VIEWS, sheet=out / "overfit.png",
                                voxel_surface=surface)
    fit_kwargs = {k: v for k, v in (("normal_region", args.fit_normal_region), ("smoothing", args.fit_smoothing),
                                    ("lr", args.fit_lr)) if v is not None}
    fit_kwargs["voxel_surface"] = surface
    fit_rows = score_fit(dataset, iters=fit_iters, views=8, seed=args.seed, progress=not args.quiet, **fit_kwargs)
    print(f"overfit: {len(shape_ids)} shapes of {data_dir}, predictor trained {train_s / 60:.1f} min this call "
          f"(run {out / 'run'}); direct fit {fit_iters} iterations per shape, "
          f"{np.mean([r['seconds'] for r in fit_rows]):.1f} s each")
    print(format_table(fit_rows, pred_rows))
    gap = float(np.mean([r["silhouette_iou"] for r in fit_rows]) - np.mean([r["silhouette_iou"] for r in pred_rows]))
    passed = None
    if fit_iters == 0:
        print("no verdict: --fit-iters 0 scores the template sphere, not a direct fit")
    else:
        passed = gap <= GAP_TARGET
        print(f"{'PASS' if passed else 'FAIL'}: predictor within {gap:.3f} silhouette IoU of the direct fit "
              f"(target <= {GAP_TARGET})")
    record = {"benchmark": "overfit", "data": str(data_dir), "shapes": shape_ids,
              "train_minutes": train_s / 60.0, "config": cfg.to_dict(), "fit": fit_rows, "predictor": pred_rows,
              "fit_iters": fit_iters, "gap": gap, "pass": passed, "voxel_surface": surface}
    atomic_write_text(out / "overfit.json", json.dumps(record, indent=2) + "\n")
    print(f"wrote {out / 'overfit.json'} and {out / 'overfit.png'} (per shape: dataset views, then the predicted mesh)")
    return 0
