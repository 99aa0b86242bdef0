"""Registers ``sketchmesh bench renderer``, ``bench fit``, ``bench overfit``, ``bench overfit-compare``, ``bench train``, ``bench variants``, ``bench tradeoff``, ``bench refine``, ``bench supports`` and ``sketchmesh gallery``.

Cheap to import (argparse only): torch and the implementations are imported inside the
command functions, through :func:`training._torch.require_torch`.
"""

from __future__ import annotations

import argparse
import math

from engine.cliutil import float_in, int_in, one_line_errors, positive_int
from engine.contract import MIRRORED_VARIANTS
from engine.icosphere import TEMPLATE_SHAPES

_resolution = int_in(1, 2048)
_non_negative_float = float_in(0.0, math.inf)


def _lazy(module: str, function: str):
    """A command function that checks for torch, then imports ``module`` and calls ``function(args)``."""

    def command(args) -> int:
        import importlib

        from training._torch import require_torch

        require_torch()
        return getattr(importlib.import_module(module), function)(args)

    command.__name__ = f"_cmd_{function}"
    return command


_cmd_bench_renderer = _lazy("training.bench.renderer", "main_bench_renderer")
_cmd_bench_fit = _lazy("training.bench.fit", "main_fit")
_cmd_bench_overfit = _lazy("training.bench.overfit", "main_overfit")
_cmd_bench_overfit_compare = _lazy("training.bench.overfit_compare", "main_overfit_compare")
_cmd_bench_train = _lazy("training.bench.train", "main_bench_train")
_cmd_bench_variants = _lazy("training.bench.variants", "main_variants")
_cmd_bench_tradeoff = _lazy("training.evaluation.tradeoff", "main_tradeoff")
_cmd_bench_refine = _lazy("training.evaluation.refine_bench", "main_refine_bench")
_cmd_bench_supports = _lazy("training.evaluation.supports_bench", "main_supports_bench")
_cmd_gallery = _lazy("training.evaluation.gallery", "main_gallery")
_cmd_bench_variety = _lazy("training.evaluation.variety", "main_variety")


def voxel_centres_flag(parser: argparse.ArgumentParser) -> None:
    """``--voxel-centres``: score voxel IoU with cell centres only, the measure of the tables made before the
    surface's cells counted (``training.evaluation.metrics.solid_voxels``; thin parts vanish)."""
    parser.add_argument("--voxel-centres", action="store_true",
                        help="voxel IoU from cell centres only (the earlier tables' measure; thin parts vanish)")


def _named_dir(text: str):
    """``NAME=DIR`` (or a bare ``DIR``) for ``bench overfit-compare``."""
    from pathlib import Path

    name, sep, path = text.partition("=")
    if not sep:
        return Path(text).name or text, Path(text)
    if not name or not path:
        raise argparse.ArgumentTypeError(f"expected NAME=DIR, got {text!r}")
    return name, Path(path)


def _key_value(text: str) -> tuple[str, object]:
    """``FIELD=VALUE`` -> (field, value parsed as JSON when it parses, else the string)."""
    import json

    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected FIELD=VALUE, got {text!r}")
    try:
        return key.replace("-", "_"), json.loads(value)
    except json.JSONDecodeError:
        return key.replace("-", "_"), value


def register(commands, bench) -> None:
    """Add ``bench renderer``, ``bench fit``, ``bench overfit``, ``bench train``, ``bench tradeoff``, ``bench refine`` and ``bench supports`` to ``bench``, and ``gallery`` to ``commands``."""
    p = one_line_errors(bench.add_parser(
        "renderer",
        help="speed, memory and accuracy of the differentiable rasterizer (and the dense baseline)",
        description="Forward and forward+backward time (median), peak memory and error against a "
        "4x-supersampled render, on bumpy 642-vertex spheres from random views.",
    ))
    p.add_argument("--resolutions", type=_resolution, nargs="+", default=[32, 64, 128, 256], metavar="R")
    p.add_argument("--batches", type=positive_int, nargs="+", default=[1, 16, 64], metavar="B")
    p.add_argument("--repeats", type=positive_int, default=5, help="timed runs per configuration (median)")
    p.add_argument("--threads", type=positive_int, default=2, help="torch intra-op threads (default 2)")
    p.add_argument("--dense-max-mb", type=_non_negative_float, default=1024.0,
                   help="run the dense baseline where its estimated memory per image is below this (0: never)")
    p.add_argument("--dense-max-batch", type=positive_int, default=16,
                   help="largest batch at which the (slow) dense baseline runs")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--timeout", type=positive_int, default=1800, help="seconds per configuration")
    p.add_argument("--in-process", action="store_true",
                   help="measure in this process (faster to start; peak_mb then accumulates across rows)")
    p.add_argument("--json", metavar="PATH", help="write the records as a JSON list")
    p.set_defaults(func=_cmd_bench_renderer)

    q = one_line_errors(bench.add_parser(
        "fit",
        help="fit the template sphere to a target mesh's multi-view renders through the rasterizer",
    ))
    q.add_argument("--target", metavar="MESH_FILE", help="target mesh file")
    q.add_argument("--procedural", type=int_in(1, 1000), metavar="N",
                   help="instead of --target: fit the first N procedural shapes of the split (--split, default train) of "
                        "every category (--categories: of those) and print the means")
    q.add_argument("--categories", metavar="C1,C2",
                   help="with --procedural: only these categories (comma-separated), e.g. chair,table")
    q.add_argument("--meshes", metavar="DIR", help="with --procedural: write each fitted mesh to DIR/SHAPE_ID.obj")
    q.add_argument("--split", choices=("train", "val", "test"), default=None,
                   help="with --procedural: the split whose first N shapes are fitted (default train)")
    q.add_argument("--views", type=positive_int, default=8)
    q.add_argument("--iters", type=positive_int, default=None, help="Adam iterations (default 1000)")
    q.add_argument("--level", type=int_in(0, 5), default=None, help="icosphere level of the template (default 3)")
    q.add_argument("--template", choices=TEMPLATE_SHAPES, default=None,
                   help="the template's shape: the icosphere (default), or the icosphere with four legs")
    q.add_argument("--lr", type=float_in(1e-6, 10.0), default=None)
    q.add_argument("--smoothing", type=float_in(0.0, 1e4), default=None,
                   help="lambda of the large-steps offsets (I + lambda L)^-1 u (0: plain offsets; default 4)")
    q.add_argument("--normal-region", choices=("image", "target"), default=None,
                   help="where the normal term counts (the whole image, or inside the target silhouette)")
    q.add_argument("--threads", type=positive_int, default=None)
    q.add_argument("--resolution", type=_resolution, default=64)
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--json", metavar="PATH", help="write the results as JSON")
    voxel_centres_flag(q)
    q.set_defaults(func=_cmd_bench_fit)

    o = one_line_errors(bench.add_parser(
        "overfit",
        help="train the mesh predictor on a few shapes and compare it with direct fits of the same shapes",
        description="Builds (or reads) a few procedural shapes, trains the predictor on their ground-truth "
        "normal images for a fixed wall time, fits each shape directly, and prints silhouette and voxel IoU "
        "of both on the shapes' own views.",
    ))
    o.add_argument("--out", required=True, metavar="DIR", help="work folder (data/, run/, overfit.json); resumes")
    o.add_argument("--data", metavar="DIR", help="use the first --shapes train shapes of this dataset instead")
    o.add_argument("--shapes", type=int_in(1, 1000), default=8)
    o.add_argument("--minutes", type=float_in(0.0, 10_000.0), default=20.0,
                   help="predictor training time (this call; 0: no limit, train to --iters)")
    o.add_argument("--iters", type=int_in(1, 10**9), default=4700,
                   help="predictor iterations, the horizon of its cosine learning-rate decay (default 4700: what "
                   "20 minutes hold on 2 cores)")
    o.add_argument("--batch", type=positive_int, default=32)
    o.add_argument("--set", type=_key_value, action="append", metavar="FIELD=VALUE",
                   help="override a training config field (repeat), e.g. --set lr_mesh=3e-4")
    o.add_argument("--fit-iters", type=int_in(0, 100_000), default=None,
                   help="direct-fit iterations per shape (default: bench fit's; 0 skips the fit and the verdict)")
    o.add_argument("--fit-lr", type=float_in(1e-6, 10.0), default=None)
    o.add_argument("--fit-smoothing", type=float_in(0.0, 1e4), default=None,
                   help="the direct fits' large-steps lambda (default: bench fit's, 4)")
    o.add_argument("--fit-normal-region", choices=("image", "target"), default=None)
    o.add_argument("--threads", type=positive_int, default=2)
    o.add_argument("--seed", type=int_in(0, 2**31 - 1), default=0)
    o.add_argument("--quiet", action="store_true")
    voxel_centres_flag(o)
    o.set_defaults(func=_cmd_bench_overfit)

    oc = one_line_errors(bench.add_parser(
        "overfit-compare",
        help="several bench overfit runs of the same shapes side by side: a table and one plot",
        description="Reads each NAME=DIR's overfit.json and run/log.csv (folders written by sketchmesh bench "
        "overfit --out DIR), prints training minutes, iterations, samples, the silhouette gap to the direct fit "
        "and voxel IoU per variant, and writes compare.md, compare.json and compare.png (training curves against "
        "wall-clock minutes, each shape's predicted voxel IoU beside its fit's) to --out.",
    ))
    oc.add_argument("runs", nargs="+", type=_named_dir, metavar="NAME=DIR", help="a bench overfit --out folder")
    oc.add_argument("--out", required=True, metavar="DIR", help="folder for compare.md, compare.json, compare.png")
    oc.add_argument("--shape", action="append", metavar="SHAPE_ID",
                    help="also write compare_SHAPE_ID.png: the shape's views, then each variant's predicted mesh (repeat)")
    oc.set_defaults(func=_cmd_bench_overfit_compare)

    tr = one_line_errors(bench.add_parser(
        "train",
        help="end-to-end mesh training throughput at batch 64, per stage, and the rasterizer's own in the same run",
        description="Times real mesh-mode training steps (loader, predictor, rasterizer, losses, optimizer) on "
        "--data or on procedural data it builds once, then the rasterizer alone on the same meshes and cameras.",
    ))
    tr.add_argument("--data", metavar="DIR", help="dataset folder (its train split; default: build procedural data)")
    tr.add_argument("--data-out", metavar="DIR", default="data/bench-train",
                    help="where the procedural data is built once and reused (default data/bench-train)")
    tr.add_argument("--shapes-per-category", type=int_in(1, 1000), default=2,
                    help="procedural train shapes per category (default 2: 26 shapes, 624 views)")
    tr.add_argument("--batch", type=positive_int, default=64)
    tr.add_argument("--steps", type=int_in(1, 100_000), default=10, help="timed steps (default 10)")
    tr.add_argument("--warmup", type=int_in(0, 100_000), default=3, help="untimed steps first (default 3)")
    tr.add_argument("--set", type=_key_value, action="append", metavar="FIELD=VALUE",
                    help="override a training config field (repeat), e.g. --set predictor_hidden=256")
    tr.add_argument("--loader", choices=("cache", "npz"), default="cache",
                    help="cache: the trainer's own training set (the mesh-array cache); npz: every field from the "
                    "shape files, as before the cache")
    tr.add_argument("--threads", type=positive_int, default=2, help="torch intra-op threads (default 2)")
    tr.add_argument("--seed", type=int_in(0, 2**31 - 1), default=0)
    tr.add_argument("--json", metavar="PATH", help="write the record as one JSON object")
    tr.add_argument("--quiet", action="store_true")
    tr.set_defaults(func=_cmd_bench_train)

    v = one_line_errors(bench.add_parser(
        "variants",
        help="mesh-predictor configurations at equal wall-clock time: test voxel IoU against training minutes",
        description="Trains each --variant (TrainConfig overrides on a shared mesh-mode base) for --minutes in "
        "--points chunks, scores the test split on ground-truth normal images after each chunk, and writes "
        "variants.json, variants.md and variants.png to --out. Resumes: finished chunks are kept.",
    ))
    v.add_argument("--data", required=True, metavar="DIR", help="dataset folder (train split to train, test split to score)")
    v.add_argument("--out", required=True, metavar="DIR", help="folder for runs/, variants.json/.md/.png; resumes")
    v.add_argument("--variant", action="append", required=True, metavar="NAME[:FIELD=VALUE,...]",
                   help="a variant: a name and its config overrides (repeat), e.g. k3:extra_views=3")
    v.add_argument("--set", type=_key_value, action="append", metavar="FIELD=VALUE",
                   help="override a config field for every variant (repeat)")
    v.add_argument("--minutes", type=float_in(0.01, 10_000.0), default=20.0, help="training wall time per variant")
    v.add_argument("--points", type=int_in(1, 100), default=4, help="scored points per variant (equal chunks)")
    v.add_argument("--max-samples", type=int_in(0, 10**9), default=156, help="test samples scored (0: all)")
    v.add_argument("--threads", type=positive_int, default=2, help="torch intra-op threads (default 2)")
    v.add_argument("--seed", type=int_in(0, 2**31 - 1), default=0)
    v.add_argument("--quiet", action="store_true")
    voxel_centres_flag(v)
    v.set_defaults(func=_cmd_bench_variants)

    w = one_line_errors(bench.add_parser(
        "variety", help="how varied the procedural shapes are: held-out shapes' nearest-train voxel IoU",
        description="For the first N procedural shapes of each category, the mean best voxel IoU of every "
        "val/test shape against the category's train shapes: the bound on nearest-neighbour retrieval "
        "(lower means a test split that measures generalisation).",
    ))
    w.add_argument("--shapes-per-category", type=int_in(2, 100_000), default=100)
    w.add_argument("--categories", nargs="+", metavar="NAME", help="default: all 13")
    w.add_argument("--voxel-resolution", type=int_in(4, 256), default=32)
    w.add_argument("--json", metavar="PATH", help="also write the table as JSON here")
    w.add_argument("--quiet", action="store_true")
    voxel_centres_flag(w)
    w.set_defaults(func=_cmd_bench_variety)

    p = one_line_errors(bench.add_parser(
        "refine", help="refinement to the sketch's outline: silhouette IoU, voxel IoU and latency for N steps",
        description="For clean and strongly augmented test-split sketches: the bundled (or --models) ONNX pipeline, "
        "then engine.refine with N steps for each --steps N; silhouette IoU against the target outline and the true "
        "one, voxel IoU, self-intersections and latency. Writes refine.md, refine.json and refine.png to --out.",
    ))
    p.add_argument("--data", required=True, metavar="DIR", help="dataset folder (its test split)")
    p.add_argument("--split", choices=("test", "val"), default="test",
                   help="the sketches' split (default test; val to choose a setting before the test split is seen)")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for refine.md, refine.json, refine.png")
    p.add_argument("--steps", type=int_in(0, 100), nargs="+", default=[0, 1, 2, 3, 4, 6], metavar="N",
                   help="refinement step counts (default 0 1 2 3 4 6; 0 = unrefined)")
    p.add_argument("--models", metavar="DIR", default=argparse.SUPPRESS,  # keeps `sketchmesh --models DIR bench refine`
                   help="model folder (default: the bundled models)")
    p.add_argument("--styles", nargs="+", choices=("clean", "strong"), default=["clean", "strong"],
                   help="sketch styles: clean, and strong augmentation (strength 1.0)")
    p.add_argument("--max-samples", type=int_in(0, 10**9), default=0, help="test sketches per style (0: all)")
    p.add_argument("--threads", type=int_in(1, 256), default=2, help="ONNX Runtime threads (default 2)")
    p.add_argument("--no-intersections", action="store_true", help="skip counting self-intersections (faster)")
    p.add_argument("--mirror-average", action="store_true",
                   help="the engine's mirror averaging on (each mesh averaged with the flipped drawing's), as in the app")
    p.add_argument("--repair-folds", action="store_true",
                   help="the fold repair on each final mesh (self-intersections smoothed away where they are), as on "
                   "the app's exports")
    p.add_argument("--true-camera", action="store_true",
                   help="also refine in each view's true framed camera and report its voxel IoU: a diagnostic of what "
                        "the engine's estimated camera costs (the engine cannot know the true one)")
    p.add_argument("--quiet", action="store_true")
    voxel_centres_flag(p)
    p.set_defaults(func=_cmd_bench_refine)

    t = one_line_errors(bench.add_parser(
        "tradeoff",
        help="voxel IoU against sketch-to-mesh latency of exported ONNX models (widths, int8, template levels)",
        description="Runs the app's engine on the clean test sketches of a dataset for every model folder, "
        "precision and template level; writes a table, JSON and a plot of IoU against latency.",
    ))
    t.add_argument("--data", required=True, metavar="DIR", help="dataset folder (its test split is used)")
    t.add_argument("--variant", action="append", required=True, metavar="LABEL=DIR",
                   help="a folder of exported models and its label (repeat)")
    t.add_argument("--precisions", nargs="+", default=["fp32"],
                   choices=MIRRORED_VARIANTS,
                   help="fp32, int8-predictor, int8, int8w (every network's large weights stored in int8, computed in "
                        "float32), each optionally with +mirror (the engine's mirror averaging on)")
    t.add_argument("--levels", type=int_in(0, 6), nargs="+", default=None, metavar="L",
                   help="template levels to report (default: the predictor's own)")
    t.add_argument("--max-samples", type=int_in(0, 10**9), default=0, help="at most this many test sketches (0: all)")
    t.add_argument("--threads", type=positive_int, default=2, help="ONNX Runtime threads (default 2)")
    t.add_argument("--bundled", metavar="LABEL[:PRECISION]", help="mark this variant as the bundled choice")
    t.add_argument("--out", required=True, metavar="DIR", help="folder for tradeoff.md/.json/.png")
    t.add_argument("--quiet", action="store_true")
    voxel_centres_flag(t)
    t.set_defaults(func=_cmd_bench_tradeoff)

    u = one_line_errors(bench.add_parser(
        "supports", help="where a drawing's legs are lost: supports seen in the true silhouette, the generator's image "
        "and the predictor's mesh",
        description="For every view of a shape standing on two or more separate supports: the supports seen in the "
        "drawing's own view (pieces along the rows of the lowest quarter of a silhouette) in the true silhouette, the "
        "generator's normal image of the clean drawing, the predictor's mesh of that image and (a diagnostic) its mesh "
        "of the true normal image, and the two meshes' supports in 3D. Writes supports.md, supports.json and "
        "supports.png to --out.",
    ))
    u.add_argument("--data", required=True, metavar="DIR", help="dataset folder")
    u.add_argument("--split", choices=("test", "val", "train"), default="test", help="the views' split (default test)")
    u.add_argument("--out", required=True, metavar="DIR", help="folder for supports.md, supports.json, supports.png")
    u.add_argument("--models", metavar="DIR", default=argparse.SUPPRESS,  # keeps `sketchmesh --models DIR bench ...`
                   help="model folder (default: the bundled models)")
    u.add_argument("--predictor", metavar="FILE", default=None,
                   help="the folder's predictor file to measure (default mesh_predictor.onnx; e.g. "
                        "mesh_predictor_legged.onnx)")
    u.add_argument("--categories", nargs="+", default=["bench", "chair", "table"], metavar="NAME",
                   help="categories whose views are measured (default bench chair table)")
    u.add_argument("--max-samples", type=int_in(0, 10**9), default=0,
                   help="at most this many views of standing shapes, spread evenly (0: all)")
    u.add_argument("--threads", type=int_in(1, 256), default=2, help="ONNX Runtime threads (default 2)")
    u.add_argument("--quiet", action="store_true")
    u.set_defaults(func=_cmd_bench_supports)

    if commands is None:
        return
    g = one_line_errors(commands.add_parser(
        "gallery",
        help="picture of sketch, generated normals and predicted mesh (two views) for test shapes",
    ))
    g.add_argument("--data", required=True, metavar="DIR", help="dataset folder (its test split is used)")
    g.add_argument("-o", "--output", required=True, metavar="PNG")
    g.add_argument("--models", metavar="DIR", default=argparse.SUPPRESS,
                   help="ONNX model folder (default: the bundled models)")
    g.add_argument("--per-category", type=positive_int, default=1, help="rows per category (default 1)")
    g.add_argument("--categories", nargs="+", metavar="NAME", help="only these categories")
    g.add_argument("--elevation", type=float_in(-90.0, 90.0), default=30.0, metavar="DEG",
                   help="the sketches' elevation: the dataset's nearest (default 30; 0 for side views)")
    g.add_argument("--azimuth", type=float_in(0.0, 360.0), default=45.0, metavar="DEG",
                   help="the sketches' azimuth: the dataset's nearest at that elevation (default 45)")
    g.add_argument("--turn", type=float_in(0.0, 360.0), default=90.0, metavar="DEG",
                   help="second view: about this many degrees of azimuth further (default 90)")
    g.add_argument("--size", type=int_in(32, 1024), default=160, help="render size of the mesh columns")
    g.add_argument("--mirror-average", action="store_true",
                   help="the engine's mirror averaging on (each mesh averaged with the flipped drawing's), as in the app")
    g.add_argument("--repair-folds", action="store_true",
                   help="the fold repair on each final mesh (self-intersections smoothed away where they are), as on "
                   "the app's exports")
    g.add_argument("--threads", type=positive_int, default=2)
    g.set_defaults(func=_cmd_gallery)
