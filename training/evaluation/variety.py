"""How varied the procedural library is: the nearest-training-shape voxel IoU of held-out shapes.

The retrieval baseline (:mod:`training.evaluation.evaluate`) answers a test sketch with the
nearest training shape, so its score is bounded by how close the nearest training shape of
the same category is. :func:`nearest_train_iou` measures that bound directly on the meshes:
for the first ``n`` shapes of each category, every held-out (val / test split) shape's best
voxel IoU (:func:`training.evaluation.metrics.voxel_iou`, 32^3 by default) against the
category's train-split shapes. Lower means more variety, i.e. a test split that measures
generalisation rather than look-up.

The meshes are compared as the dataset stores them (``make_shape`` output, normalised with
:func:`engine.camera.normalize_vertices`: centred, longest side 1); they are renormalised here
so a generator that does not normalise is measured the same way.

Command: ``sketchmesh bench variety --shapes-per-category 100 [--json PATH]``. Usage (about 5 s
for 13 x 30 shapes on one core)::

    from training.evaluation.variety import nearest_train_iou
    table = nearest_train_iou(30)            # {category: {"test": ..., "held_out": ..., ...}}
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from engine.camera import normalize_vertices
from engine.errors import SketchmeshError
from engine.mesh import Mesh


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two boolean voxel grids, exactly as :func:`training.evaluation.metrics.voxel_iou` computes it."""
    union = int(np.count_nonzero(a | b))
    return 1.0 if union == 0 else int(np.count_nonzero(a & b)) / union


def shape_voxels(mesh: Mesh, resolution: int = 32, surface: bool = True) -> np.ndarray:
    """(R, R, R) bool solid voxels of ``mesh`` after the dataset's normalisation (``surface``: see solid_voxels)."""
    from training.evaluation.metrics import solid_voxels

    m = Mesh(normalize_vertices(mesh.vertices).astype(np.float32), mesh.faces)
    return solid_voxels(m, resolution, surface)


def nearest_train_iou(
    n: int,
    categories: Sequence[str] | None = None,
    make: Callable[[str, int], Mesh] | None = None,
    split: Callable[[str, int], str] | None = None,
    resolution: int = 32,
    surface: bool = True,
) -> dict[str, dict[str, float]]:
    """Per category, the mean best voxel IoU of held-out shapes against the train shapes.

    Args:
        n: shapes 0 .. n-1 of each category are generated.
        categories: default every category of :mod:`training.data.shapes`.
        make: ``make(category, index) -> Mesh``; default :func:`training.data.shapes.make_shape`
            (pass another generator, e.g. an older version of the library, to compare).
        split: ``split(category, index) -> "train" | "val" | "test"``; default
            :func:`training.data.shapes.split_of`.
        resolution: voxel grid side.
        surface: the surface's cells count as solid (default); False: centres only.

    Returns:
        ``{category: {"test": mean over test shapes, "held_out": mean over val + test shapes,
        "n_train": int, "n_test": int, "n_held_out": int}}`` (a mean is NaN when there are no
        such shapes), plus ``"mean"`` averaging each field over the categories.
    """
    from training.data import shapes

    make = shapes.make_shape if make is None else make
    split = shapes.split_of if split is None else split
    cats = list(shapes.CATEGORIES if categories is None else categories)
    out: dict[str, dict[str, float]] = {}
    for c in cats:
        vox = {i: shape_voxels(make(c, i), resolution, surface) for i in range(int(n))}
        splits = {i: split(c, i) for i in vox}
        train = [i for i in vox if splits[i] == "train"]
        best = {i: max((_iou(vox[i], vox[j]) for j in train), default=float("nan")) for i in vox if splits[i] != "train"}
        test = [b for i, b in best.items() if splits[i] == "test"]
        out[c] = {
            "test": float(np.mean(test)) if test else float("nan"),
            "held_out": float(np.mean(list(best.values()))) if best else float("nan"),
            "n_train": len(train),
            "n_test": len(test),
            "n_held_out": len(best),
        }
    keys = ("test", "held_out", "n_train", "n_test", "n_held_out")
    from training.evaluation.metrics import finite_mean

    out["mean"] = {k: finite_mean([out[c][k] for c in cats]) for k in keys}
    return out


def variety_markdown(table: dict[str, dict[str, float]]) -> str:
    """The table of :func:`nearest_train_iou` as markdown, one row per category and the mean."""
    lines = ["| category | test | val + test | train shapes | test shapes |", "|---|---:|---:|---:|---:|"]
    for c, r in table.items():
        name = "**mean**" if c == "mean" else c
        lines.append(f"| {name} | {r['test']:.3f} | {r['held_out']:.3f} | {r['n_train']:.0f} | {r['n_test']:.0f} |")
    return "\n".join(lines) + "\n"


def main_variety(args) -> int:
    """``sketchmesh bench variety``: print (and write) the nearest-train voxel IoU table."""
    import json

    from engine.fileio import atomic_write_text
    from training.data.shapes import CATEGORIES

    cats = list(args.categories or CATEGORIES)
    unknown = [c for c in cats if c not in CATEGORIES]
    if unknown:
        raise SketchmeshError(f"unknown categories {unknown}; choose from {list(CATEGORIES)}")
    table: dict[str, dict[str, float]] = {}
    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(cats, desc="variety", unit="category", leave=False)
    for c in bar if bar is not None else cats:
        table[c] = nearest_train_iou(args.shapes_per_category, [c], resolution=args.voxel_resolution,
                                    surface=not args.voxel_centres)[c]
    keys = ("test", "held_out", "n_train", "n_test", "n_held_out")
    table["mean"] = {k: float(np.nanmean([table[c][k] for c in cats])) for k in keys}
    md = variety_markdown(table)
    print(f"nearest-train voxel IoU ({args.voxel_resolution}^3) of held-out procedural shapes, "
          f"{args.shapes_per_category} per category (lower: more variety)")
    print(md, end="")
    if args.json:
        atomic_write_text(args.json, json.dumps({"shapes_per_category": args.shapes_per_category,
                                                 "voxel_resolution": args.voxel_resolution, "table": table}, indent=1))
        print(f"wrote {args.json}")
    return 0
