"""``sketchmesh bench tradeoff``: 3D accuracy against sketch-to-mesh latency of exported models.

Where ``sketchmesh eval`` measures the torch networks, this measures what the app runs: each
variant is a folder of ONNX models (``sketchmesh export``) driven by :class:`engine.pipeline.SketchEngine`
with the result cache off, on the clean test sketches of a dataset. For every variant it reports
the per-category-mean voxel IoU at 32^3 (the paper's Table 1 metric) and Chamfer-L1 against the
ground-truth shapes, and the median / 90th-percentile wall time of one sketch -> mesh prediction
on ``--threads`` cores. So every speed figure comes with the accuracy it buys.

Axes of the trade-off:

* model folders (``--variant LABEL=DIR``): generator widths, predictor sizes;
* precision (``--precisions fp32 int8-predictor int8 int8w``): dynamic int8 quantisation of the
  predictor only, or of both networks, or every network's large weights stored in int8 and computed in
  float32 (:func:`engine.bench.make_variant`, :func:`engine.bench.compact_model`); each may carry the suffix
  ``+mirror`` (``fp32+mirror``): the engine's mirror averaging on (:mod:`engine.pipeline`), both
  networks run a second time on the drawing flipped left to right;
* template level (``--levels 2 3 4``): the predictor is trained on one icosphere level L. Icosphere
  levels nest (level L-1's vertices are the first vertices of level L, see :mod:`engine.icosphere`),
  so a coarser mesh keeps the predicted positions of those vertices with level L-1's faces, and a
  finer one is Loop-subdivided (:func:`engine.postprocess.subdivide`). The resampling time is part
  of the measured latency.

Outputs in ``--out``: ``tradeoff.json``, ``tradeoff.md`` (the table) and ``tradeoff.png`` (mean
IoU against latency; ``--bundled LABEL`` is marked with a star).
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from engine.bench import MIRROR_SUFFIX, split_variant
from engine.errors import SketchmeshError
from engine.fileio import atomic_write_bytes, atomic_write_text
from engine.icosphere import TEMPLATE_RADIUS, icosphere
from engine.mesh import Mesh


class TradeoffError(SketchmeshError):
    """The trade-off benchmark cannot run (bad variant spec, empty split, level out of range)."""


def parse_variant(spec: str) -> tuple[str, Path]:
    """``LABEL=DIR`` -> (label, folder). Raises TradeoffError for a malformed spec or missing folder."""
    label, sep, folder = spec.partition("=")
    if not sep or not label or not folder:
        raise TradeoffError(f"--variant must be LABEL=DIR, got {spec!r}")
    path = Path(folder)
    if not path.is_dir():
        raise TradeoffError(f"--variant {label}: model folder {folder} does not exist")
    return label, path


def resample_level(mesh: Mesh, from_level: int, to_level: int) -> Mesh:
    """The predicted mesh on another icosphere level (see the module docstring).

    Raises:
        TradeoffError: the mesh does not have level ``from_level``'s vertex count.
    """
    from engine.postprocess import subdivide

    expected = icosphere(from_level, TEMPLATE_RADIUS).num_vertices
    if mesh.num_vertices != expected:
        raise TradeoffError(f"mesh has {mesh.num_vertices} vertices, not level {from_level}'s {expected}")
    if to_level == from_level:
        return mesh
    if to_level < from_level:
        coarse = icosphere(to_level, TEMPLATE_RADIUS)
        return Mesh(np.asarray(mesh.vertices)[: coarse.num_vertices], coarse.faces)
    return subdivide(mesh, to_level - from_level, method="loop")


def _mean_over_categories(records: list[dict], key: str) -> float:
    per: dict[str, list[float]] = defaultdict(list)
    for r in records:
        per[r["category"]].append(r[key])
    return float(np.nanmean([np.nanmean(v) for v in per.values()]))


def run_tradeoff(
    variants: list[tuple[str, Path]],
    data_dir: str | Path,
    *,
    precisions: tuple[str, ...] = ("fp32",),
    levels: tuple[int, ...] = (),
    max_samples: int = 0,
    threads: int = 2,
    warmup: int = 2,
    voxel_resolution: int = 32,
    voxel_surface: bool = True,
    work_dir: str | Path | None = None,
    progress: bool = True,
) -> list[dict]:
    """Measure every (variant, precision, level); see the module docstring.

    Returns:
        One record per combination: label, precision, level, vertices, voxel_iou, chamfer_l1
        (means over categories), latency_ms_p50 / p90, samples, model_mb (MiB, 2**20 bytes).
    """
    import tempfile

    from tqdm import tqdm

    from engine.bench import folder_bytes, make_variant
    from engine.pipeline import SketchEngine
    from training.data.dataset import ShapeViewDataset
    from training.evaluation.evaluate import _pair_metrics, world_vertices
    from training.evaluation.metrics import solid_voxels

    if not variants:
        raise TradeoffError("give at least one --variant LABEL=DIR")
    for p in precisions:
        split_variant(p)  # every precision checked before anything runs
    test = ShapeViewDataset(Path(data_dir), "test", extra_views=0, augment_strength=0.0)
    if len(test) == 0:
        raise TradeoffError(f"the test split of {data_dir} is empty")
    indices = np.arange(len(test))
    if max_samples and max_samples < len(indices):
        indices = np.unique(np.linspace(0, len(test) - 1, max_samples).round().astype(int))
    items = [test[int(i)] for i in indices]
    gt: dict[tuple[str, str], tuple[Mesh, np.ndarray]] = {}
    for it in items:
        key = (it["category"], it["shape_id"])
        if key not in gt:
            mesh = test.load_mesh(*key)
            gt[key] = (mesh, solid_voxels(mesh, voxel_resolution, voxel_surface))

    tmp_ctx = tempfile.TemporaryDirectory(prefix="sketchmesh-tradeoff-") if work_dir is None else None
    work = Path(tmp_ctx.name if tmp_ctx else work_dir)
    records: list[dict] = []
    try:
        combos = [(label, folder, prec) for label, folder in variants for prec in precisions]
        for label, folder, prec in combos:
            precision, mirror = split_variant(prec)
            vfolder = make_variant(folder, precision, work / label)
            engine = SketchEngine(vfolder, threads=threads, cache_size=0, mirror_average=mirror)
            engine.load()
            model_level = int(engine.model_info()["template_level"])
            model_mb = folder_bytes(vfolder) / 2**20
            for it in items[:warmup]:
                engine.predict(it["sketch"][0].numpy())
            run_levels = tuple(levels) or (model_level,)
            for lv in run_levels:
                if not 0 <= lv <= model_level + 2:
                    raise TradeoffError(f"level {lv} out of range for a level-{model_level} predictor")
            per_level: dict[int, list[dict]] = {lv: [] for lv in run_levels}
            times: dict[int, list[float]] = {lv: [] for lv in run_levels}
            bar = tqdm(items, desc=f"{label} {prec}", unit="sketch", disable=not progress)
            for it in bar:
                cam = it["camera"].numpy()
                t0 = time.perf_counter()
                pred = engine.predict(it["sketch"][0].numpy())
                t_model = time.perf_counter() - t0
                gmesh, gvox = gt[(it["category"], it["shape_id"])]
                for lv in run_levels:
                    t1 = time.perf_counter()
                    mesh = resample_level(pred.mesh, model_level, lv)
                    times[lv].append((t_model + time.perf_counter() - t1) * 1e3)
                    world = Mesh(world_vertices(np.asarray(mesh.vertices, np.float64), cam), mesh.faces)
                    rec = _pair_metrics(world, gmesh, gvox, voxel_resolution, voxel_surface)
                    rec["category"] = it["category"]
                    per_level[lv].append(rec)
            for lv in run_levels:
                ms = np.asarray(times[lv])
                records.append({
                    "label": label,
                    "precision": prec,
                    "level": lv,
                    "native_level": model_level,
                    "vertices": icosphere(lv, TEMPLATE_RADIUS).num_vertices,
                    "voxel_iou": _mean_over_categories(per_level[lv], "voxel_iou"),
                    "chamfer_l1": _mean_over_categories(per_level[lv], "chamfer_l1"),
                    "latency_ms_p50": float(np.percentile(ms, 50)),
                    "latency_ms_p90": float(np.percentile(ms, 90)),
                    "samples": len(items),
                    "threads": threads,
                    "model_mb": round(model_mb, 2),
                })
    finally:
        if tmp_ctx is not None:
            tmp_ctx.cleanup()
    return records


def markdown_table(records: list[dict], bundled: str | None = None) -> str:
    lines = ["| models | precision | level (vertices) | size MiB | voxel IoU | Chamfer-L1 | latency p50 ms | p90 ms |",
             "|---|---|---|---:|---:|---:|---:|---:|"]
    for r in records:
        mark = " (bundled)" if bundled and _is_bundled(r, bundled) else ""
        lines.append(f"| {r['label']}{mark} | {r['precision']} | {r['level']} ({r['vertices']}) | {r['model_mb']:.1f} | "
                     f"{r['voxel_iou']:.3f} | {r['chamfer_l1']:.4f} | {r['latency_ms_p50']:.1f} | {r['latency_ms_p90']:.1f} |")
    return "\n".join(lines) + "\n"


def _is_bundled(record: dict, bundled: str) -> bool:
    """``bundled`` is ``LABEL`` (fp32) or ``LABEL:PRECISION``; only the predictor's own level counts."""
    label, _, precision = bundled.partition(":")
    return (record["label"] == label and record["precision"] == (precision or "fp32")
            and record["level"] == record["native_level"])


def plot(records: list[dict], path: str | Path, bundled: str | None = None) -> None:
    """Mean voxel IoU against p50 latency, one marker per precision (hollow: +mirror), one colour per model folder."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    markers = {"fp32": "o", "int8-predictor": "s", "int8": "^", "int8w": "D"}
    labels = sorted({r["label"] for r in records})
    colours = {lab: plt.get_cmap("tab10")(i % 10) for i, lab in enumerate(labels)}
    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=110)
    for r in records:
        marker = markers[r["precision"].removesuffix(MIRROR_SUFFIX)]
        if r["precision"].endswith(MIRROR_SUFFIX):
            ax.scatter(r["latency_ms_p50"], r["voxel_iou"], marker=marker, facecolor="none", edgecolor=colours[r["label"]],
                       linewidths=1.4, s=40)
        else:
            ax.scatter(r["latency_ms_p50"], r["voxel_iou"], marker=marker, color=colours[r["label"]], s=40)
        ax.annotate(f"L{r['level']}", (r["latency_ms_p50"], r["voxel_iou"]), textcoords="offset points",
                    xytext=(4, 3), fontsize=7)
        if bundled and _is_bundled(r, bundled):
            ax.scatter(r["latency_ms_p50"], r["voxel_iou"], marker="*", s=320, facecolor="none", edgecolor="red",
                       linewidths=1.5, zorder=5)
    for lab in labels:
        ax.scatter([], [], color=colours[lab], marker="o", label=lab)
    for prec, m in markers.items():
        if any(r["precision"] == prec for r in records):
            ax.scatter([], [], color="grey", marker=m, label=prec)
        if any(r["precision"] == prec + MIRROR_SUFFIX for r in records):
            ax.scatter([], [], facecolor="none", edgecolor="grey", marker=m, label=prec + MIRROR_SUFFIX)
    if bundled:
        ax.scatter([], [], marker="*", s=120, facecolor="none", edgecolor="red", label="bundled")
    threads = records[0]["threads"] if records else "?"
    ax.set_xlabel(f"sketch -> mesh latency, median ms ({threads} threads, ONNX Runtime)")
    ax.set_ylabel("mean voxel IoU 32^3 (test split)")
    ax.set_title("Accuracy against run time (Lk = template level)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def main_tradeoff(args: argparse.Namespace) -> int:
    variants = [parse_variant(s) for s in args.variant]
    records = run_tradeoff(variants, args.data, precisions=tuple(args.precisions), levels=tuple(args.levels or ()),
                           max_samples=args.max_samples, threads=args.threads, progress=not args.quiet,
                           voxel_surface=not args.voxel_centres)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table = markdown_table(records, args.bundled)
    atomic_write_text(out / "tradeoff.md", table)
    atomic_write_text(out / "tradeoff.json", json.dumps(records, indent=2))
    plot(records, out / "tradeoff.png", args.bundled)
    print(table)
    print(f"wrote {out / 'tradeoff.md'}, {out / 'tradeoff.json'}, {out / 'tradeoff.png'}")
    return 0


__all__ = ["TradeoffError", "main_tradeoff", "markdown_table", "parse_variant", "plot", "resample_level", "run_tradeoff"]
