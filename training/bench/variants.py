"""``sketchmesh bench variants``: mesh-predictor configurations compared at equal wall-clock time.

Each variant is a set of :class:`training.loop.config.TrainConfig` overrides on a shared base (mesh
mode, the dataset of ``--data``). Every variant trains for ``--minutes`` of wall time in ``--points``
equal chunks (each chunk resumes the variant's run from its checkpoint; a chunk killed after a
checkpoint, by a session that ended, counts the training that checkpoint holds towards the next
call's chunk, from the trainer's cumulative ``train_seconds``); after each chunk its
newest checkpoint is scored on the test split with ground-truth normal images as input
(:func:`training.evaluation.evaluate.evaluate` with ``gt_normals=True``: the mesh step alone,
voxel IoU at 32^3, Chamfer-L1 and silhouette IoU). Training time excludes the scoring.

Outputs in ``--out``: ``runs/NAME/`` (the training runs), ``variants.json`` (every point; the
command resumes from it: finished chunks are not trained or scored again), ``variants.md`` (the
table) and ``variants.png`` (test voxel IoU and silhouette IoU against training minutes, one
curve per variant). Run the variants one after another on an otherwise idle machine: they are
compared by time, so two runs at once would each get half the cores.

A variant whose config sets ``supervision = "3d"`` is the diagnostic ceiling (Chamfer distance to
the true surface), never the method: it is labelled so in the table and the plot.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from engine.errors import SketchmeshError
from engine.fileio import atomic_write_bytes, atomic_write_text

RESULT_FILE = "variants.json"
FORMAT = 1


def parse_variant(text: str) -> tuple[str, dict]:
    """``NAME`` or ``NAME:FIELD=VALUE,FIELD=VALUE`` -> (name, overrides); values parsed as JSON when they parse."""
    name, _, rest = text.partition(":")
    name = name.strip()
    if not name or not all(c.isalnum() or c in "-_." for c in name):
        raise SketchmeshError(f"--variant {text!r}: the name must be letters, digits, '-', '_' or '.'")
    overrides: dict = {}
    for part in filter(None, (p.strip() for p in rest.split(","))):
        key, sep, value = part.partition("=")
        if not sep or not key:
            raise SketchmeshError(f"--variant {text!r}: expected FIELD=VALUE, got {part!r}")
        try:
            overrides[key.strip().replace("-", "_")] = json.loads(value)
        except json.JSONDecodeError:
            overrides[key.strip().replace("-", "_")] = value.strip()
    return name, overrides


def is_diagnostic(cfg_dict: dict) -> bool:
    """True for a 3D-supervised run: a diagnostic ceiling, not the paper's 2D-only method."""
    return cfg_dict.get("supervision", "2d") == "3d"


def is_reference(cfg_dict: dict) -> bool:
    """True for a run with SoftRas's soft silhouette: an outside reference, not the paper's Eq. 1."""
    return cfg_dict.get("silhouette", "eq1") == "soft"


def label(name: str, cfg_dict: dict) -> str:
    if is_diagnostic(cfg_dict):
        return f"{name} (3D-supervised diagnostic)"
    return f"{name} (SoftRas silhouette, reference)" if is_reference(cfg_dict) else name


def _load(out: Path) -> dict:
    path = out / RESULT_FILE
    if not path.is_file():
        return {"format": FORMAT, "points": []}
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise SketchmeshError(f"{path} is unreadable ({exc}); delete it to start the comparison again") from None
    if not isinstance(record, dict) or record.get("format") != FORMAT or not isinstance(record.get("points"), list):
        raise SketchmeshError(f"{path} is not a variants record of format {FORMAT}; delete it to start again")
    return record


def markdown_table(record: dict) -> str:
    """One row per scored point, grouped by variant: training minutes, iterations, test metrics."""
    lines = ["| variant | train min | iterations | voxel IoU | silhouette IoU | Chamfer-L1 |",
             "|---|---:|---:|---:|---:|---:|"]
    order = list(dict.fromkeys(p["variant"] for p in record["points"]))
    for p in sorted(record["points"], key=lambda p: (order.index(p["variant"]), p["chunk"])):
        lines.append(f"| {label(p['variant'], p['config'])} | {p['train_minutes']:.1f} | {p['iteration']} | "
                     f"{p['voxel_iou']:.4f} | {p['silhouette_iou']:.4f} | {p['chamfer_l1']:.4f} |")
    return "\n".join(lines) + "\n"


def plot_png(record: dict) -> bytes:
    """Test voxel IoU and silhouette IoU against training minutes, one curve per variant (PNG bytes)."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    names = list(dict.fromkeys(p["variant"] for p in record["points"]))
    for name in names:
        pts = [p for p in record["points"] if p["variant"] == name]
        t = [0.0] + [p["train_minutes"] for p in pts]
        style = "--" if is_diagnostic(pts[0]["config"]) else ":" if is_reference(pts[0]["config"]) else "-"
        for ax, key in zip(axes, ("voxel_iou", "silhouette_iou")):
            start = record.get("template", {}).get(key, np.nan)
            ax.plot(t, [start] + [p[key] for p in pts], style, marker="o", ms=3, label=label(name, pts[0]["config"]))
    for ax, title in zip(axes, ("test voxel IoU (32^3)", "test silhouette IoU")):
        ax.set_xlabel("training wall time on this machine (minutes)")
        ax.set_title(title + ", ground-truth normal images in")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def _write(out: Path, record: dict) -> None:
    atomic_write_text(out / RESULT_FILE, json.dumps(record, indent=2) + "\n")
    atomic_write_text(out / "variants.md", markdown_table(record))
    if record["points"]:
        atomic_write_bytes(out / "variants.png", plot_png(record))


def _template_scores(base, run: Path, test_set, max_samples: int, voxel_surface: bool = True) -> dict:
    """Test metrics of the untrained predictor, whose offsets are ~0: the template sphere, where
    every curve starts. ``run`` receives its checkpoint."""
    import torch

    from training.evaluation.evaluate import evaluate
    from training.loop.trainer import Trainer

    run.mkdir(parents=True, exist_ok=True)
    Trainer(base.replace(out_dir=str(run)), progress=False).save()  # the untrained predictor: offsets ~ 0
    with torch.no_grad():
        res = evaluate(run, base.data_dir, gt_normals=True, retrieval=False, max_samples=max_samples,
                       progress=False, test_set=test_set, voxel_surface=voxel_surface)
    return {k: float(res["mean"][k]) for k in ("voxel_iou", "silhouette_iou", "chamfer_l1")}


def _already_trained(train_seconds: float, last_point: dict | None) -> float:
    """Seconds of training a resumed run holds (``train_seconds``, from its newest checkpoint) beyond
    the last scored point.

    Zero unless a chunk was killed after writing a checkpoint: the trainer records its cumulative
    training time in every checkpoint and each point records it as ``run_seconds``, so the
    difference is what the killed chunk trained. A point from before this was recorded gives 0
    (unknown).
    """
    if last_point is not None and "run_seconds" not in last_point:
        return 0.0
    base = float(last_point["run_seconds"]) if last_point is not None else 0.0
    return max(0.0, float(train_seconds) - base)


def main_variants(args) -> int:
    """``sketchmesh bench variants``; see the module docstring."""
    import torch

    from training.evaluation.evaluate import evaluate
    from training.loop.config import TrainConfig
    from training.loop.trainer import Trainer, make_dataset

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise SketchmeshError(f"--out {out} is a file, not a folder")
    data = Path(args.data)
    if not (data / "manifest.json").is_file():
        raise SketchmeshError(f"--data {data} is not a dataset (no manifest.json; make one with sketchmesh data)")
    variants = [parse_variant(v) for v in args.variant]
    names = [n for n, _ in variants]
    if len(set(names)) != len(names):
        raise SketchmeshError(f"--variant names must differ, got {names}")
    base_over = dict(args.set or [])
    try:
        base = TrainConfig.from_dict({**TrainConfig(mode="mesh").to_dict(), "mode": "mesh", "data_dir": str(data),
                                      "iters": 10**8, "val_every": 0, "plot_every": 0, "ckpt_every": 100,
                                      "seed": args.seed, **base_over})
        configs = {n: TrainConfig.from_dict({**base.to_dict(), **o, "out_dir": str(out / "runs" / n)})
                   for n, o in variants}
    except (ValueError, TypeError) as exc:
        raise SketchmeshError(f"--set / --variant: {exc}") from None
    if base.mode != "mesh":
        raise SketchmeshError("bench variants compares mesh-mode configurations (mode=mesh)")
    chunk = float(args.minutes) / int(args.points)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(int(args.threads))
    record = _load(out)
    surface = not args.voxel_centres
    # a record's points were all scored with one voxel measure (records from before the choice: cell centres)
    measure = record.get("voxel_surface", False) if (record.get("points") or "template" in record) else surface
    if measure != surface:
        raise SketchmeshError(f"{out} was scored with voxels by {'surface' if measure else 'cell centres'}; "
                              f"{'drop' if measure else 'add'} --voxel-centres or use another --out")
    record["voxel_surface"] = surface
    test_set = make_dataset(base.replace(extra_views=0, augment_strength=0.0, categories=()), "test")
    if len(test_set) == 0:
        raise SketchmeshError(f"the test split of {data} is empty")
    if "template" not in record:
        record["template"] = _template_scores(base, out / "runs" / "_template", test_set, args.max_samples,
                                              voxel_surface=surface)
    record["settings"] = {"data": str(data), "minutes": args.minutes, "points": args.points,
                          "max_samples": args.max_samples, "threads": args.threads}  # the latest call's
    for name, cfg in configs.items():
        done = [p for p in record["points"] if p["variant"] == name]
        # a record from before a config field existed was run with its legacy value (LEGACY_DEFAULTS)
        if done and TrainConfig.from_dict(done[0]["config"]).to_dict() != cfg.to_dict():
            raise SketchmeshError(f"variant {name} was run with another config before; use a new name or --out")
        trained_s = done[-1]["train_minutes"] * 60.0 if done else 0.0
        for k in range(len(done), int(args.points)):
            t0 = time.perf_counter()
            trainer = Trainer(cfg, progress=not args.quiet)
            # a chunk killed after a checkpoint (a session that ended) already trained part of this one
            already = _already_trained(trainer.train_seconds, done[-1] if done else None)
            if not args.quiet:
                note = f", {already / 60:.2f} min of it trained before a kill" if already else ""
                print(f"{label(name, cfg.to_dict())}: chunk {k + 1}/{args.points} ({chunk:g} min{note})", flush=True)
            trainer.run(max_minutes=max(chunk - already / 60.0, 1e-6))
            trained_s += time.perf_counter() - t0 + already
            with torch.no_grad():
                res = evaluate(cfg.out_dir, data, gt_normals=True, retrieval=False, max_samples=args.max_samples,
                               progress=False, test_set=test_set, voxel_surface=surface)
            m = res["mean"]
            point = {"variant": name, "chunk": k + 1, "train_minutes": trained_s / 60.0,
                     "iteration": trainer.iteration, "run_seconds": trainer.train_seconds,
                     "voxel_iou": float(m["voxel_iou"]),
                     "silhouette_iou": float(m["silhouette_iou"]), "chamfer_l1": float(m["chamfer_l1"]),
                     "samples": int(res["samples"]), "config": cfg.to_dict()}
            record["points"].append(point)
            done.append(point)  # this variant's newest point, which the next chunk's killed-chunk check reads
            _write(out, record)
            if not args.quiet:
                print(f"  {trained_s / 60:.1f} min, iteration {trainer.iteration}: voxel IoU {point['voxel_iou']:.4f}, "
                      f"silhouette IoU {point['silhouette_iou']:.4f}", flush=True)
    print(f"template sphere: voxel IoU {record['template']['voxel_iou']:.4f}, "
          f"silhouette IoU {record['template']['silhouette_iou']:.4f}")
    _write(out, record)  # also when every chunk was already done: the table and plot follow the code
    print(markdown_table(record), end="")
    print(f"wrote {out / RESULT_FILE}, {out / 'variants.md'} and {out / 'variants.png'}")
    return 0
