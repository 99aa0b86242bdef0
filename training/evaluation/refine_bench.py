"""``sketchmesh bench refine``: what refining the mesh to the sketch's outline buys, and what it costs.

For every test-split sketch, clean and strongly augmented (``augment_strength`` 1.0: broken,
doubled and wobbly strokes), the bundled ONNX pipeline (:class:`engine.pipeline.SketchEngine`,
result cache off) predicts a mesh, and :func:`engine.refine.refine_prediction` refines it with
N steps for each ``--steps`` N (0 = the unrefined prediction). Per N it reports, as means over
categories:

* ``sil_iou_target`` -- silhouette IoU at 256x256 between the mesh seen from the sketch camera
  (:func:`engine.refine.fit_camera` of the unrefined prediction and the target, the camera the
  engine refines in) and the target outline (the drawing's filled region, or the generator's
  silhouette where the drawing is not closed): what the artist sees;
* ``sil_iou_gt`` -- the same mesh rendered with the *true* framed camera of the view against the
  true silhouette of the shape;
* ``voxel_iou`` -- solid 32^3 voxel IoU against the ground-truth shape (the paper's metric);
* ``refine_ms_p50`` and ``latency_ms_p50`` -- the refinement alone and sketch -> refined mesh
  (generator + predictor + refinement), medians over the sketches, on ``--threads`` threads; the refinement timed
  as the engine calls it, the target outline and the camera fit included (before 2026-11-30 the camera was fitted
  outside the timed call, which left about 8 ms of the refinement out);
* ``self_intersections`` (mean count) and ``warnings`` (how many sketches fell back);
* with ``--repair-folds``, the fold repair (:func:`engine.postprocess.repair_folds`) runs on
  each final mesh, after the N refinement steps, as on the mesh the app exports (and the engine's
  ``repair_folds`` stage: no check again of a refined mesh the refinement counted free of crossings); its time
  counts in the latency, and ``repair_ms_p50`` / ``_p90`` / ``_max`` report it alone;
* ``target_iou_gt``: the target outline's own IoU against the true silhouette (how true what refinement aims for is);
* with ``--true-camera``, ``voxel_iou_true_camera``: the same refinement done in the view's *true*
  framed camera instead of the estimated one -- a diagnostic the engine cannot run (it does not
  know the true shape's framing), which separates what refinement costs in 3D through the
  camera estimate from what it costs by itself (N = 0: the unrefined mesh, the same either way); and how far
  the engine's camera is from the true one: ``camera_focal_error`` (mean ``|log(focal / true focal)|``),
  ``bbox_focal_error`` (the same for the prediction's own bounding-box framing, before the fit) and
  ``camera_principal_error`` (the principal point's distance, NDC).

Outputs in ``--out``: ``refine.json``, ``refine.md`` (the table) and ``refine.png`` (both IoUs
against latency, one line per sketch style).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from engine.errors import SketchmeshError
from engine.fileio import atomic_write_bytes, atomic_write_text
from engine.mesh import Mesh

STYLES = {"clean": 0.0, "strong": 1.0}
"""Sketch styles measured: name -> augmentation strength."""


class RefineBenchError(SketchmeshError):
    """The refinement benchmark cannot run (empty split, bad steps)."""


def _mean_over_categories(records: list[dict], key: str) -> float:
    per: dict[str, list[float]] = defaultdict(list)
    for r in records:
        per[r["category"]].append(r[key])
    return float(np.nanmean([np.nanmean(v) for v in per.values()]))


def run_refine_bench(
    data_dir: str | Path,
    *,
    steps: tuple[int, ...] = (0, 1, 2, 4, 8),
    models_dir: str | Path | None = None,
    max_samples: int = 0,
    threads: int = 2,
    styles: tuple[str, ...] = tuple(STYLES),
    voxel_resolution: int = 32,
    voxel_surface: bool = True,
    self_intersections: bool = True,
    progress: bool = True,
    mirror_average: bool = False,
    true_camera: bool = False,
    repair_folds: bool = False,
    split: str = "test",
) -> list[dict]:
    """Measure every (style, N); see the module docstring (``mirror_average``: the engine's, as in the app;
    ``repair_folds``: the fold repair after the refinement, as in the app's exports;
    ``true_camera``: also refine in the view's true camera, a diagnostic; ``split``: the sketches' split, "test", or
    "val" to choose a setting before the test split is looked at). Returns one record per (style, N)."""
    from tqdm import tqdm

    from engine.camera import Camera
    from engine.pipeline import SketchEngine
    from engine.postprocess import repair_folds as repair_after
    from engine.postprocess import self_intersections as count_intersections
    from engine.refine import (
        fit_camera,
        pixel_coords,
        refine_prediction,
        render_silhouette,
        silhouette_iou,
        sketch_camera,
        target_outline,
    )
    from training.data.dataset import ShapeViewDataset
    from training.evaluation.evaluate import _pair_metrics, world_vertices
    from training.evaluation.metrics import finite_mean, solid_voxels

    if not steps or any(s < 0 for s in steps):
        raise RefineBenchError(f"--steps must be integers >= 0, got {steps}")
    unknown = [s for s in styles if s not in STYLES]
    if unknown:
        raise RefineBenchError(f"unknown style(s) {unknown}; choose from {', '.join(STYLES)}")
    engine = SketchEngine(models_dir, threads=threads, cache_size=0, mirror_average=mirror_average)
    engine.load()
    gt: dict[tuple[str, str], tuple[Mesh, np.ndarray]] = {}
    records: list[dict] = []
    for style in styles:
        data = ShapeViewDataset(Path(data_dir), split, extra_views=0, augment_strength=STYLES[style])
        if len(data) == 0:
            raise RefineBenchError(f"the {split} split of {data_dir} is empty")
        indices = np.arange(len(data))
        if max_samples and max_samples < len(indices):
            indices = np.unique(np.linspace(0, len(data) - 1, max_samples).round().astype(int))
        per_n: dict[int, list[dict]] = {n: [] for n in steps}
        model_ms: list[float] = []
        refine_ms: dict[int, list[float]] = {n: [] for n in steps}
        repair_ms: dict[int, list[float]] = {n: [] for n in steps}
        engine.predict(data[int(indices[0])]["sketch"][0].numpy())  # warm-up
        for i in tqdm(indices, desc=f"refine {style}", unit="sketch", disable=not progress):
            it = data[int(i)]
            sketch = it["sketch"][0].numpy()
            cam16 = it["camera"].numpy().astype(np.float64)
            t0 = time.perf_counter()
            pred = engine.predict(sketch, want_normals=True)
            model_ms.append((time.perf_counter() - t0) * 1e3)
            key = (it["category"], it["shape_id"])
            if key not in gt:
                m = data.load_mesh(*key)
                gt[key] = (m, solid_voxels(m, voxel_resolution, voxel_surface))
            gmesh, gvox = gt[key]
            target, source = target_outline(sketch, pred.normals)
            cam = fit_camera(pred.mesh, target)  # what refine_mesh uses when given no camera
            true_cam = Camera(np.eye(3), cam16[9:12], float(cam16[12]), (float(cam16[13]), float(cam16[14])))
            cam_errors = {k: float("nan") for k in ("camera_focal_error", "bbox_focal_error", "camera_principal_error")}
            if true_camera:  # how far the engine's camera (and the prediction's own bounding-box framing) is from the true
                cam_errors = {
                    "camera_focal_error": abs(float(np.log(cam.focal / true_cam.focal))),
                    "bbox_focal_error": abs(float(np.log(sketch_camera(pred.mesh).focal / true_cam.focal))),
                    "camera_principal_error": float(np.hypot(*np.subtract(cam.principal, true_cam.principal))),
                }
            gt_sil = it["silhouette"][0].numpy() > 0.5
            target_iou = silhouette_iou(target, gt_sil)  # how true the target itself is
            for n in steps:
                t1 = time.perf_counter()
                # the engine's call: its own target outline and camera fit (the same as ``cam``) inside the time
                res = refine_prediction(pred.mesh, sketch, pred.normals, n)
                refine_ms[n].append((time.perf_counter() - t1) * 1e3)
                mesh = res.mesh
                t2 = time.perf_counter()
                if repair_folds:  # the engine's policy: no check again where the refinement counted no crossing
                    mesh = repair_after(mesh, res.crossings if n else None).mesh
                repair_ms[n].append((time.perf_counter() - t2) * 1e3 if repair_folds else 0.0)
                px, _ = pixel_coords(mesh.vertices, cam, target.shape[0])
                sil = render_silhouette(px, mesh.faces, target.shape[0])
                px_true, _ = pixel_coords(mesh.vertices, true_cam, gt_sil.shape[0])
                sil_true = render_silhouette(px_true, mesh.faces, gt_sil.shape[0])
                world = Mesh(world_vertices(np.asarray(mesh.vertices, np.float64), cam16), mesh.faces)
                rec = _pair_metrics(world, gmesh, gvox, voxel_resolution, voxel_surface)
                rec["voxel_iou_true_camera"] = float("nan")
                if true_camera:  # the diagnostic: the same steps in the camera that drew the sketch
                    oracle = refine_prediction(pred.mesh, sketch, pred.normals, n, camera=true_cam).mesh
                    oracle_world = Mesh(world_vertices(np.asarray(oracle.vertices, np.float64), cam16), oracle.faces)
                    rec["voxel_iou_true_camera"] = _pair_metrics(oracle_world, gmesh, gvox, voxel_resolution,
                                                                 voxel_surface)["voxel_iou"]
                rec.update(cam_errors)
                rec.update(category=it["category"], sil_iou_target=silhouette_iou(sil, target), target_iou_gt=target_iou,
                           sil_iou_gt=silhouette_iou(sil_true, gt_sil), target_is_drawing=source == "drawing",
                           warning=res.warning is not None and n > 0, note=res.note is not None and n > 0,
                           self_intersections=float(count_intersections(mesh)) if self_intersections else float("nan"))
                per_n[n].append(rec)
        for n in steps:
            rs = per_n[n]
            total = np.asarray(model_ms) + np.asarray(refine_ms[n]) + np.asarray(repair_ms[n])
            records.append({
                "style": style,
                "augment_strength": STYLES[style],
                "steps": n,
                "sil_iou_target": _mean_over_categories(rs, "sil_iou_target"),
                "sil_iou_gt": _mean_over_categories(rs, "sil_iou_gt"),
                "voxel_iou": _mean_over_categories(rs, "voxel_iou"),
                "voxel_iou_true_camera": _mean_over_categories(rs, "voxel_iou_true_camera") if true_camera else None,
                **{k: _mean_over_categories(rs, k) if true_camera else None
                   for k in ("camera_focal_error", "bbox_focal_error", "camera_principal_error")},
                "chamfer_l1": _mean_over_categories(rs, "chamfer_l1"),
                "refine_ms_p50": float(np.percentile(refine_ms[n], 50)),
                "refine_ms_p90": float(np.percentile(refine_ms[n], 90)),
                "latency_ms_p50": float(np.percentile(total, 50)),
                "self_intersections": finite_mean([r["self_intersections"] for r in rs]),  # NaN: not counted
                "repair_ms_p50": float(np.percentile(repair_ms[n], 50)),  # 0.0 with the repair off
                "repair_ms_p90": float(np.percentile(repair_ms[n], 90)),
                "repair_ms_max": float(np.max(repair_ms[n])),
                "warnings": int(sum(r["warning"] for r in rs)),
                "notes": int(sum(r["note"] for r in rs)),
                "target_is_drawing": float(np.mean([r["target_is_drawing"] for r in rs])),
                "target_iou_gt": _mean_over_categories(rs, "target_iou_gt"),
                "split": split,
                "samples": len(rs),
                "threads": threads,
                "mirror_average": bool(mirror_average),
                "repair_folds": bool(repair_folds),
            })
    return records


def markdown_table(records: list[dict]) -> str:
    """The table; a column for the true-camera diagnostic when the records carry it."""
    oracle = any(r.get("voxel_iou_true_camera") is not None for r in records)
    lines = ["| sketches | N | silhouette IoU vs target | silhouette IoU vs true outline | voxel IoU | "
             + ("voxel IoU, refined in the true camera (diagnostic) | " if oracle else "")
             + "Chamfer-L1 | refine p50 ms | sketch->mesh p50 ms | self-intersections | fallbacks |",
             "|---|---:|---:|---:|---:|" + ("---:|" if oracle else "") + "---:|---:|---:|---:|---:|"]
    for r in records:
        extra = f"{r['voxel_iou_true_camera']:.4f} | " if oracle else ""
        lines.append(f"| {r['style']} | {r['steps']} | {r['sil_iou_target']:.3f} | {r['sil_iou_gt']:.3f} | "
                     f"{r['voxel_iou']:.4f} | {extra}{r['chamfer_l1']:.4f} | {r['refine_ms_p50']:.1f} | "
                     f"{r['latency_ms_p50']:.1f} | {r['self_intersections']:.1f} | {r['warnings']}/{r['samples']} |")
    return "\n".join(lines) + "\n"


def plot(records: list[dict], path: str | Path) -> None:
    """Silhouette IoU (against the target) and voxel IoU against p50 latency, one line per style."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), dpi=110)
    for style, colour in zip(STYLES, ("tab:blue", "tab:orange")):
        rs = sorted((r for r in records if r["style"] == style), key=lambda r: r["steps"])
        if not rs:
            continue
        x = [r["latency_ms_p50"] for r in rs]
        for ax, key in zip(axes, ("sil_iou_target", "voxel_iou")):
            ax.plot(x, [r[key] for r in rs], "o-", color=colour, label=f"{style} sketches")
            for r in rs:
                ax.annotate(f"N={r['steps']}", (r["latency_ms_p50"], r[key]), textcoords="offset points",
                            xytext=(4, -10), fontsize=7)
    threads = records[0]["threads"] if records else "?"
    for ax, label in zip(axes, ("silhouette IoU against the target outline (256^2)", "voxel IoU 32^3 (test split)")):
        ax.set_xlabel(f"sketch -> refined mesh, median ms ({threads} threads)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Refinement to the sketch's outline: accuracy against run time (N = steps)")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def main_refine_bench(args: argparse.Namespace) -> int:
    load_start = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    records = run_refine_bench(args.data, steps=tuple(args.steps), models_dir=getattr(args, "models", None), max_samples=args.max_samples,
                               threads=args.threads, styles=tuple(args.styles),
                               self_intersections=not args.no_intersections, progress=not args.quiet,
                               voxel_surface=not args.voxel_centres, mirror_average=args.mirror_average,
                               true_camera=args.true_camera, repair_folds=args.repair_folds, split=args.split)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table = markdown_table(records)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    repair = "off"
    if args.repair_folds:
        repair = "on, after the refinement (" + "; ".join(
            f"{r['style']} N = {r['steps']}: {r['repair_ms_p50']:.1f} / {r['repair_ms_p90']:.1f} / "
            f"{r['repair_ms_max']:.0f} ms p50 / p90 / max" for r in records) + ")"
    targets = "; ".join(f"{r['style']} {r['target_iou_gt']:.3f} (the drawing for {100 * r['target_is_drawing']:.0f} %)"
                        for r in records if r["steps"] == records[0]["steps"])
    if args.true_camera:
        targets += "; the engine's camera against the true one (mean |log focal ratio| / the prediction's bounding-box " \
                   "framing's / principal point off by, NDC): " + "; ".join(
                       f"{r['style']} {r['camera_focal_error']:.3f} / {r['bbox_focal_error']:.3f} / "
                       f"{r['camera_principal_error']:.3f}" for r in records if r["steps"] == records[0]["steps"])
    loads = (f"{args.split} split; the target outline against the true silhouette, IoU: {targets}; "
             f"mirror averaging {'on' if args.mirror_average else 'off'}; "
             f"fold repair {repair}; "
             f"load average (1 min) at the start {load_start:.2f}, at the end {load:.2f}")
    atomic_write_text(out / "refine.md", table + f"\n{loads}\n")
    atomic_write_text(out / "refine.json", json.dumps({"records": records, "loadavg_1min": [load_start, load]}, indent=2))
    plot(records, out / "refine.png")
    print(table)
    print(loads)
    print(f"wrote {out / 'refine.md'}, {out / 'refine.json'}, {out / 'refine.png'}")
    return 0


__all__ = ["RefineBenchError", "STYLES", "main_refine_bench", "markdown_table", "plot", "run_refine_bench"]
