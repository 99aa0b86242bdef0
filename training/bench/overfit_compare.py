"""``sketchmesh bench overfit-compare``: several ``bench overfit`` runs of the same shapes side by side.

The overfit check's variants (batch, learning rate, basis damping, ...) are compared at equal wall-clock
time, as the developers' guide asks: each ``NAME=DIR`` names a folder that ``sketchmesh bench overfit
--out DIR`` wrote. The command reads ``DIR/overfit.json`` (the per-shape scores of the predictor and of
the direct fits) and ``DIR/run/log.csv`` (the training curve), prints one row per variant (training
minutes, iterations, samples seen in all, a second and per shape, mean silhouette gap to the direct fit,
mean predicted voxel IoU and the scores of the worst shape), and writes ``compare.md``, ``compare.json``
and ``compare.png`` to ``--out``: the training silhouette term against wall-clock minutes, every variant
on one axes, beside each shape's predicted voxel IoU with the direct fit's as the ceiling. With ``--shape SHAPE_ID`` it
also writes ``compare_SHAPE_ID.png``: that shape's views, then each variant's predicted mesh from the
same views, cut from the runs' ``overfit.png`` sheets, to look at beside the numbers.

Only runs of the same shapes compare: a different shape list is an error, and so is a missing or
corrupt file. Training time comes from the run's log (``wall_s`` restarts when a run resumes; the
pieces are added up), so a resumed run counts all its training.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from engine.errors import SketchmeshError
from engine.fileio import atomic_write_bytes, atomic_write_text


def training_curve(log_csv: Path) -> dict:
    """Iterations, cumulative training minutes and the silhouette term from a run's ``log.csv``.

    ``wall_s`` counts from the start of each call, so where it falls (a resumed run) the minutes
    before are carried over."""
    try:
        with open(log_csv, newline="") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as exc:
        raise SketchmeshError(f"cannot read {log_csv}: {exc.strerror or exc}") from None
    its, minutes, sil = [], [], []
    offset = last = 0.0
    for row in rows:
        try:
            it, wall, s = int(row["iteration"]), float(row["wall_s"]), float(row["mesh_silhouette"])
        except (KeyError, TypeError, ValueError):
            raise SketchmeshError(f"{log_csv} is not a mesh-training log (needs iteration, wall_s and "
                                  "mesh_silhouette columns)") from None
        if wall < last:
            offset += last
        last = wall
        its.append(it)
        minutes.append((offset + wall) / 60.0)
        sil.append(s)
    if not its:
        raise SketchmeshError(f"{log_csv} has no logged iterations")
    return {"iteration": its, "minutes": minutes, "silhouette": sil}


def load_variant(name: str, folder: Path) -> dict:
    """One overfit run: its scores (``overfit.json``) and its training curve (``run/log.csv``)."""
    path = folder / "overfit.json"
    if not path.is_file():
        raise SketchmeshError(f"{folder} has no overfit.json (write one with: sketchmesh bench overfit --out {folder})")
    try:
        record = json.loads(path.read_text())
        fit, pred = record["fit"], record["predictor"]
        config = record["config"]
        shapes = [r["shape_id"] for r in pred]
        batch = int(config["batch"])
    except (OSError, ValueError, KeyError, TypeError):
        raise SketchmeshError(f"{path} is not a bench overfit result") from None
    if not shapes or [r["shape_id"] for r in fit] != shapes:
        raise SketchmeshError(f"{path} is not a bench overfit result (no shapes, or fit and predictor rows differ)")
    curve = training_curve(folder / "run" / "log.csv")
    fit_sil = np.array([r["silhouette_iou"] for r in fit], float)
    pred_sil = np.array([r["silhouette_iou"] for r in pred], float)
    fit_vox = np.array([r["voxel_iou"] for r in fit], float)
    pred_vox = np.array([r["voxel_iou"] for r in pred], float)
    if not all(np.isfinite(a).all() for a in (fit_sil, pred_sil, fit_vox, pred_vox)):
        raise SketchmeshError(f"{path} holds a score that is not a finite number")
    gaps = fit_sil - pred_sil
    worst = int(np.argmax(gaps))
    iterations = curve["iteration"][-1]
    return {
        "name": name, "folder": str(folder), "shapes": shapes, "batch": batch,
        "minutes": curve["minutes"][-1], "iterations": iterations, "samples": iterations * batch,
        "fit_iters": record.get("fit_iters"),
        "gap": float(gaps.mean()), "pred_silhouette": float(pred_sil.mean()), "fit_silhouette": float(fit_sil.mean()),
        "pred_voxel": float(pred_vox.mean()), "fit_voxel": float(fit_vox.mean()),
        "per_shape_pred_voxel": pred_vox.tolist(), "per_shape_fit_voxel": fit_vox.tolist(),
        "worst_shape": shapes[worst], "worst_gap": float(gaps[worst]),
        "curve": curve,
    }


def compare(named: list[tuple[str, Path]]) -> dict:
    """Load every variant and check that they scored the same shapes."""
    if not named:
        raise SketchmeshError("name at least one overfit folder")
    names = [n for n, _ in named]
    if len(set(names)) != len(names):
        raise SketchmeshError(f"variant names repeat: {', '.join(names)}")
    variants = [load_variant(n, p) for n, p in named]
    first = variants[0]
    for v in variants[1:]:
        if v["shapes"] != first["shapes"]:
            raise SketchmeshError(f"{v['name']} ({v['folder']}) scored other shapes than {first['name']} "
                                  f"({first['folder']}): only runs of the same shapes compare")
    return {"benchmark": "overfit-compare", "shapes": first["shapes"], "variants": variants}


def markdown_table(record: dict) -> str:
    lines = ["| variant | train min | iterations | samples | samples/s | per shape | sil gap to fit | pred sil | "
             "pred vox | fit vox | worst shape (gap) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for v in record["variants"]:
        rate = v["samples"] / (60.0 * v["minutes"]) if v["minutes"] > 0 else float("nan")
        lines.append(f"| {v['name']} | {v['minutes']:.1f} | {v['iterations']} | {v['samples']} | {rate:.0f} | "
                     f"{v['samples'] / len(v['shapes']):.0f} | {v['gap']:.3f} | "
                     f"{v['pred_silhouette']:.3f} | {v['pred_voxel']:.3f} | {v['fit_voxel']:.3f} | "
                     f"{v['worst_shape']} ({v['worst_gap']:.3f}) |")
    return "\n".join(lines) + "\n"


def plot_png(record: dict) -> bytes:
    """Training silhouette term against minutes (left) and each shape's predicted voxel IoU (right)."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shapes = record["shapes"]
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6), gridspec_kw={"width_ratios": [1, 1.4]})
    for v in record["variants"]:
        c = v["curve"]
        sil = np.asarray(c["silhouette"], float)
        k = max(1, min(25, len(sil) // 20))  # a running mean over k logged points: the raw term is noisy
        smooth = np.convolve(sil, np.ones(k) / k, mode="valid")
        axes[0].plot(np.asarray(c["minutes"])[k - 1:], smooth, label=f"{v['name']} (batch {v['batch']})")
    axes[0].set_xlabel("training wall time (minutes)")
    axes[0].set_ylabel("silhouette term (1 - IoU), running mean")
    axes[0].set_title("training curve")
    axes[0].grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    x = np.arange(len(shapes))
    width = 0.8 / len(record["variants"])
    for i, v in enumerate(record["variants"]):
        axes[1].bar(x - 0.4 + width * (i + 0.5), v["per_shape_pred_voxel"], width,
                    label=f"{v['name']}: mean {v['pred_voxel']:.3f}")
    axes[1].scatter(x, record["variants"][0]["per_shape_fit_voxel"], marker="_", s=300, color="k", zorder=3,
                    label="direct fit (ceiling)")
    axes[1].set_xticks(x, [s.rsplit("_", 1)[0] for s in shapes], rotation=45, ha="right", fontsize=8)
    axes[1].set_ylim(0, 1)
    axes[1].set_ylabel("voxel IoU (32^3)")
    axes[1].set_title("predicted mesh per shape, its own views")
    axes[1].legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


LABEL_WIDTH = 120
"""Width in pixels of the strip that names each row of a shape's sheet."""


def shape_sheet(record: dict, shape_id: str, scale: int = 2) -> np.ndarray:
    """One shape from every variant's ``overfit.png``: the dataset's views, then each variant's predicted
    mesh from the same views, each row named on the left (an RGB uint8 image).

    ``bench overfit`` writes per shape a block of two rows of ``S``-pixel tiles (the views, then the
    prediction) and a 2-pixel gap, so the block of shape ``i`` starts at ``i * (2 S + 2)``. Tiles are
    enlarged ``scale`` times (nearest pixel)."""
    from PIL import Image, ImageDraw

    shapes = record["shapes"]
    if shape_id not in shapes:
        raise SketchmeshError(f"--shape {shape_id}: not among the compared shapes ({', '.join(shapes)})")
    i = shapes.index(shape_id)
    rows, names = [], []
    for k, v in enumerate(record["variants"]):
        path = Path(v["folder"]) / "overfit.png"
        try:
            with Image.open(path) as im:
                sheet = np.asarray(im.convert("RGB"))
        except (OSError, ValueError):
            raise SketchmeshError(f"cannot read {path} (bench overfit writes it beside overfit.json)") from None
        block, rest = divmod(sheet.shape[0], len(shapes))
        size = (block - 2) // 2
        if rest or size < 1 or block != 2 * size + 2:
            raise SketchmeshError(f"{path} is not a bench overfit sheet of {len(shapes)} shapes "
                                  f"({sheet.shape[0]} pixels high)")
        top = i * block
        if k == 0:
            rows.append(sheet[top:top + size])
            names.append("dataset views")
        rows.append(sheet[top + size:top + 2 * size])
        names.append(v["name"])
    rows = [np.repeat(np.repeat(r, scale, 0), scale, 1) for r in rows]
    width = max(r.shape[1] for r in rows)
    height = rows[0].shape[0]
    canvas = Image.new("RGB", (LABEL_WIDTH + width, height * len(rows)), "white")
    draw = ImageDraw.Draw(canvas)
    for r, (row, name) in enumerate(zip(rows, names)):
        canvas.paste(Image.fromarray(np.ascontiguousarray(row)), (LABEL_WIDTH, r * height))
        draw.text((4, r * height + height // 2 - 6), name[:18], fill="black")
    return np.asarray(canvas)


def main_overfit_compare(args) -> int:
    """``sketchmesh bench overfit-compare``; see the module docstring."""
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise SketchmeshError(f"--out {out} is a file, not a folder")
    record = compare(args.runs)
    # the sheets first: an unknown shape or a sheet of another layout is refused before anything is written
    sheets = {shape_id: shape_sheet(record, shape_id) for shape_id in dict.fromkeys(args.shape or [])}
    out.mkdir(parents=True, exist_ok=True)
    fits = {v["fit_iters"] for v in record["variants"]}
    table = markdown_table(record)
    print(f"overfit-compare: {len(record['variants'])} variants on the same {len(record['shapes'])} shapes")
    print(table, end="")
    if len(fits) > 1 or any(f in (0, None) for f in fits):
        print("note: the direct fits differ between variants or are missing (--fit-iters 0): gaps are not comparable")
    atomic_write_text(out / "compare.json", json.dumps(record, indent=2, allow_nan=False) + "\n")
    atomic_write_text(out / "compare.md", table)
    atomic_write_bytes(out / "compare.png", plot_png(record))
    print(f"wrote {out / 'compare.md'}, {out / 'compare.json'} and {out / 'compare.png'}")
    from training.loop.trainer import write_png

    for shape_id, sheet in sheets.items():
        path = out / f"compare_{shape_id}.png"
        write_png(path, sheet)
        print(f"wrote {path} (the dataset's views of {shape_id}, then each variant's predicted mesh)")
    return 0
