"""``sketchmesh train | eval | export | import-models``: cheap to import (argparse only; torch loads inside commands).

Every :class:`training.loop.config.TrainConfig` field has a flag (``--lambda-n 0`` etc.); the config is
built once here and passed down. Also runnable as ``python -m training.cli.train ...`` (handy
under ``torchrun --nproc_per_node 2 -m training.cli.train train mesh ...``).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from pathlib import Path

from engine.cliutil import check_output_dir, float_in, int_in, one_line_errors, run_guarded, unit_float
from engine.errors import ModelError, SketchmeshError
from training.cli.bench import voxel_centres_flag
from training.export.static_int8 import CALIBRATION_DRAWINGS

# flags handled explicitly (positional mode, short names) rather than generated from the dataclass
_EXPLICIT = {"mode", "data_dir", "out_dir"}


class ConfigError(SketchmeshError):
    """A training flag has an invalid value."""


MAX_NUM_WORKERS = 256
"""Most DataLoader worker processes a run may ask for."""

TRAIN_MEMORY_SHARE = 0.8
"""Largest share of the available memory the weights, gradients, optimizer state and one batch may take."""


def _add_config_flags(parser: argparse.ArgumentParser) -> None:
    from training.loop.config import DEFAULT_BATCH, TrainConfig

    for f in dataclasses.fields(TrainConfig):
        if f.name in _EXPLICIT:
            continue
        flag = "--" + f.name.replace("_", "-")
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        help_text = f"(default: {default!r})"
        if f.name == "batch":
            help_text = "per-process batch size (default: " + ", ".join(f"{k} {v}" for k, v in DEFAULT_BATCH.items()) + ")"
        if f.name == "betas":
            parser.add_argument(flag, type=float, nargs=2, default=None, metavar=("B1", "B2"), help=help_text)
        elif f.name == "categories":
            parser.add_argument(flag, nargs="+", default=None, metavar="NAME", help="train on these categories only")
        elif f.name == "debug_nan_iters":
            parser.add_argument(flag, type=int, nargs="+", default=None, metavar="IT", help=argparse.SUPPRESS)
        elif f.name == "debug_sleep":
            parser.add_argument(flag, type=float, default=None, help=argparse.SUPPRESS)
        elif isinstance(default, bool):
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, default=None, help=help_text)
        else:
            parser.add_argument(flag, type=type(default), default=None, help=help_text)


def config_from_args(args: argparse.Namespace):
    """Build the one TrainConfig from parsed flags (unset flags keep the dataclass defaults)."""
    from training.loop.config import TrainConfig

    values = {"mode": args.mode, "data_dir": args.data, "out_dir": args.out}
    for f in dataclasses.fields(TrainConfig):
        if f.name in _EXPLICIT:
            continue
        v = getattr(args, f.name, None)
        if v is not None:
            values[f.name] = tuple(v) if isinstance(v, list) else v
    try:
        return TrainConfig(**values)
    except (ValueError, TypeError) as exc:
        raise ConfigError(str(exc)) from None


def _is_main_rank() -> bool:
    return os.environ.get("RANK", "0") == "0"


INIT_FIELDS = {
    "generator": ("base_channels", "generator_arch"),
    "predictor": ("predictor_arch", "template_level", "predictor_channels", "predictor_hidden", "predictor_latent",
                  "predictor_modes", "predictor_blocks", "predictor_aligned"),
}
"""Config fields that fix the parameter shapes of the networks an --init-* run hands over."""
WIDENABLE = ("predictor_hidden", "predictor_latent", "predictor_blocks")
"""Of those, the ones a compact predictor may grow (``CompactMeshPredictor.load_grown``; its aligned branch it may add
where the run has none, see ``fits``)."""


def _check_init_run(run: str, flag: str, role: str, cfg) -> None:
    """The run an --init-* flag names has a checkpoint whose ``role`` network fits this configuration."""
    from training.loop.checkpoint import require_checkpoint
    from training.loop.config import TrainConfig

    state = require_checkpoint(run)
    try:
        saved = TrainConfig.from_json(state["config"])
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"{flag} {run}: its checkpoint carries an unusable config ({exc})") from None
    if role not in state["models"]:
        raise ConfigError(f"{flag} {run}: a {saved.mode} run, it has no {role} to initialise from")
    def fits(k: str) -> bool:  # a compact predictor is widened to larger fully connected layers (load_widened)
        if k == "predictor_aligned" and cfg.predictor_arch == "compact":  # added where absent, never resized
            return getattr(saved, k) in (0, getattr(cfg, k))
        if k in WIDENABLE and cfg.predictor_arch == "compact":
            return getattr(saved, k) <= getattr(cfg, k)
        return getattr(saved, k) == getattr(cfg, k)

    diffs = [f"{k} {getattr(saved, k)} there, {getattr(cfg, k)} here" for k in INIT_FIELDS[role] if not fits(k)]
    if diffs:
        raise ConfigError(f"{flag} {run}: its {role} was trained with another configuration ({'; '.join(diffs)})")


def _parameter_count(cfg) -> int:
    """Parameters of the networks ``cfg`` trains, counted on the meta device (nothing allocated).

    ``nn.init.normal_`` is skipped there: on meta tensors it goes through torch's Python
    reference ops, whose first use imports torch._dynamo (6 s); the values are never used.
    Returns 0 when the networks cannot be built on the meta device (the memory check then only
    counts the batch).
    """
    from unittest import mock

    import torch

    from training.loop.trainer import build_models

    try:
        with torch.device("meta"), mock.patch.object(torch.nn.init, "normal_", lambda t, *a, **k: t):
            models = build_models(cfg)
    except Exception:  # noqa: BLE001 - a guard against absurd sizes must not stop a sane run
        return 0
    return sum(p.numel() for m in models.values() for p in m.parameters())


def preflight_train(cfg) -> None:
    """Check a training request before anything is built or written (torch is imported).

    The dataset (folder, manifest, every shape file of the train split, image sizes against the
    config), the run folder and the runs to initialise from, and the memory the weights,
    gradients, optimizer state and one batch will take against the available memory.

    Raises:
        SketchmeshError: naming the flag and the problem.
    """
    from training.data.dataset import available_memory_bytes, check_dataset
    from training.loop.checkpoint import check_run_folder

    if cfg.num_workers > MAX_NUM_WORKERS:
        raise ConfigError(f"--num-workers must be at most {MAX_NUM_WORKERS}, got {cfg.num_workers}")
    check_output_dir(cfg.out_dir, "--out")
    for flag, run, role, used in (("--init-normals", cfg.init_normals, "generator", cfg.uses_generator),
                                  ("--init-mesh", cfg.init_mesh, "predictor", cfg.uses_predictor)):
        if run:
            check_run_folder(run, flag)
            if used:
                _check_init_run(run, flag, role, cfg)
    manifest = check_dataset(cfg.data_dir, "train", cfg.categories or None, "--data")
    settings = manifest.get("settings") or {}
    size, small = int(settings.get("size", 256)), int(settings.get("small_size", 64))
    if cfg.uses_generator and size != cfg.sketch_size:
        raise ConfigError(f"--data {cfg.data_dir} holds {size}x{size} sketches, but the {cfg.mode} run's generator "
                          f"takes {cfg.sketch_size}x{cfg.sketch_size} (--sketch-size); build the data with --size "
                          f"{cfg.sketch_size}")
    if cfg.uses_predictor and small != cfg.render_size:
        raise ConfigError(f"--data {cfg.data_dir} holds {small}x{small} predictor targets, but the {cfg.mode} run "
                          f"renders at {cfg.render_size}x{cfg.render_size} (--render-size); use --render-size {small} "
                          f"or build the data with --small-size {cfg.render_size}")
    views = min((int(r.get("num_views", 1)) for r in manifest["shapes"]), default=1)
    if cfg.extra_views > max(views - 1, 1):
        raise ConfigError(f"--extra-views {cfg.extra_views}: the shapes of {cfg.data_dir} have only {views} views")
    params = _parameter_count(cfg)
    k = 1 + cfg.extra_views
    item = 4 * (cfg.sketch_size**2 * 5 + cfg.render_size**2 * 4 * k) + 8 * 16 * k
    need = 16 * params + 2 * cfg.batch * item  # weights, gradients, two optimizer moments (float32); a batch and its copy
    memory = available_memory_bytes()
    if memory is not None and need > TRAIN_MEMORY_SHARE * memory:
        gb = 1024**3
        raise ConfigError(f"this configuration needs at least {need / gb:,.1f} GB of memory ({params:,} parameters, "
                          f"batches of {cfg.batch}), more than the {memory / gb:,.1f} GB available; use smaller widths "
                          "or --batch")


def _cmd_train(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    from training._torch import require_torch

    torch = require_torch()
    if args.threads:
        torch.set_num_threads(args.threads)
    from engine.fileio import nearest_existing
    from training.loop.checkpoint import checkpoint_paths, remove_stale_checkpoint_files
    from training.loop.trainer import train

    preflight_train(cfg)
    run = Path(os.path.abspath(cfg.out_dir))
    base = nearest_existing(run)
    created = None if base == run else base / run.relative_to(base).parts[0]  # the top folder this run will make
    if _is_main_rank():  # a write killed midway (a SIGKILL, a full disk) may have left its temporary file
        remove_stale_checkpoint_files(run)
    try:
        last = train(cfg, resume=args.resume, progress=not args.quiet)
    except Exception:
        # a run that failed before its first checkpoint is no run: leave no folder with a header-only log
        if created is not None and _is_main_rank() and created.is_dir() and not checkpoint_paths(run):
            import shutil

            shutil.rmtree(created, ignore_errors=True)
        raise
    if not _is_main_rank():  # under torchrun only rank 0 reports
        return 0
    if last:
        print("final: " + "  ".join(f"{k}={v:.4g}" for k, v in last.items()))
    print(f"run folder: {cfg.out_dir}")
    return 0


_RUN_ONLY_EVAL_FLAGS = (("gt_normals", "--gt-normals"), ("generator_run", "--generator-run"),
                        ("baseline_run", "--baseline-run"), ("mesh_scale", "--mesh-scale"))
_MODELS_ONLY_EVAL_FLAGS = (("views", "--views"), ("mirror_only", "--mirror-only"))


def _eval_models_specs(args: argparse.Namespace) -> list[str]:
    """The model folders ``eval`` scores (``--models`` after ``eval``, or the top-level one); [] for RUN mode.

    Exactly one of RUN and ``--models`` is required, and each mode's own flags are refused in the other.
    """
    specs = list(getattr(args, "eval_models", None) or [])
    if not specs and getattr(args, "models", None):  # `sketchmesh --models DIR eval ...`
        specs = [args.models]
    if args.run and specs:
        raise ConfigError("give a RUN folder or --models DIR, not both")
    if not args.run and not specs:
        raise ConfigError("give a RUN folder (a training run) or --models DIR (exported ONNX models; "
                          "'bundled' for the app's) to evaluate")
    if specs:
        used = [flag for key, flag in _RUN_ONLY_EVAL_FLAGS if getattr(args, key, None)]
        if used:
            raise ConfigError(f"{used[0]} applies to a RUN, not to --models")
    else:
        used = [flag for key, flag in _MODELS_ONLY_EVAL_FLAGS if getattr(args, key, None) is not None]
        if used:
            raise ConfigError(f"{used[0]} applies to --models, not to a RUN")
        if args.split == "all":
            raise ConfigError("--split all applies to --models; a RUN is scored on train, val or test")
    return specs


def _cmd_eval(args: argparse.Namespace) -> int:
    specs = _eval_models_specs(args)
    if specs:
        from training.evaluation.models_eval import evaluate_models_cli

        return evaluate_models_cli(args, specs)
    from training._torch import require_torch

    torch = require_torch()
    if args.threads:
        torch.set_num_threads(args.threads)
    from training.evaluation.evaluate import evaluate_cli

    return evaluate_cli(args)


def _cmd_export(args: argparse.Namespace) -> int:
    from training._torch import require_torch

    torch = require_torch()
    if args.threads:
        torch.set_num_threads(args.threads)
    from training.export.to_onnx import export_run
    from training.loop.checkpoint import check_run_folder

    check_run_folder(args.run)
    for flag, run in (("--generator-run", args.generator_run), ("--predictor-run", args.predictor_run)):
        if run:
            check_run_folder(run, flag)
    check_output_dir(args.output, "-o")
    reports = export_run(args.run, args.output, generator_run=args.generator_run,
                         predictor_run=args.predictor_run, quantize=args.quantize)
    for r in reports:
        print(r.line())
    if reports and reports[0].parity_inputs:
        print(f"parity inputs: {reports[0].parity_inputs}")
    print(f"exported {len(reports)} model(s) to {args.output}: torch vs ONNX Runtime parity within tolerance")
    return 0


def _cmd_import(args: argparse.Namespace) -> int:
    from training._torch import require_torch

    torch = require_torch()
    if args.threads:
        torch.set_num_threads(args.threads)
    from training.evaluation.models_eval import models_folder
    from training.export.from_onnx import import_models

    check_output_dir(args.out, "--out")
    roles = (args.only,) if args.only else ("generator", "predictor")
    reports = import_models(models_folder(args.models), args.out, data_dir=args.data, roles=roles, calibration=args.calibration)
    for r in reports:
        print(r.line())
    print(f"parity inputs: {reports[0].parity_inputs}")
    print(f"imported {len(reports)} model(s) into {args.out}: continue with "
          + " ".join(f"--init-{'normals' if r.role == 'generator' else 'mesh'} {r.run_dir}" for r in reports))
    return 0


def _cmd_quantize_generator(args: argparse.Namespace) -> int:
    from training.evaluation.models_eval import models_folder
    from training.export.static_int8 import quantize_generator

    if not Path(args.data).is_dir():
        raise ModelError(f"--data {args.data}: dataset folder does not exist")
    r = quantize_generator(models_folder(args.models), args.data, count=args.drawings, split=args.split,
                           keep_float=args.keep_float, min_pixels=args.min_pixels)
    print(f"wrote {r['path']} ({r['bytes']:,} bytes): {r['quantized']} convolutions in int8 ({r['macs_int8'] / 1e6:.0f} "
          f"of the {r['macs'] / 1e6:.0f} million multiply-adds of a drawing), "
          f"{len(r['kept_float'])} left as stored (float32 arithmetic); on the {r['calibration']} calibration drawings "
          f"the output moves by {r['mean_abs']:.4f} on average (largest {r['max_abs']:.3f}, in [0, 1] colour units)")
    return 0


def _cmd_average(args: argparse.Namespace) -> int:
    from training._torch import require_torch

    torch = require_torch()
    if args.threads:
        torch.set_num_threads(args.threads)
    from training.export.average import average_runs

    if args.data and not Path(args.data).is_dir():
        raise ModelError(f"--data {args.data}: dataset folder does not exist")
    check_output_dir(args.out, "--out")
    try:
        report = average_runs(args.runs, args.out, weights=args.weights, bn_samples=args.bn_samples,
                              data_dir=args.data)
    except ValueError as exc:  # the run count or --weights
        raise ModelError(str(exc)) from None
    print(report.line())
    return 0


_threads = int_in(0, 256)

MAX_VOXEL_RESOLUTION = 256
"""Largest --voxel-resolution of eval (256^3 voxels per mesh is already slow)."""


def register(commands, bench) -> None:
    """Add ``train``, ``eval``, ``export``, ``import-models`` and ``average`` to the top-level sub-parsers (see
    :mod:`sketchmesh.cli`)."""
    p = commands.add_parser(
        "train", help="train the normal generator, the mesh predictor, or both jointly",
        description="Train (or resume) a run: normals = pix2pix cGAN sketch -> normal image; mesh = mesh "
        "predictor on ground-truth normals through the differentiable renderer; joint = both end to end.",
    )
    p.add_argument("mode", choices=("normals", "mesh", "joint"))
    p.add_argument("--data", required=True, metavar="DIR", help="dataset folder (sketchmesh data --out DIR)")
    p.add_argument("--out", required=True, metavar="RUN", help="run folder (checkpoints, logs, images)")
    p.add_argument("--resume", action=argparse.BooleanOptionalAction, default=True,
                   help="continue from RUN's last checkpoint (default); --no-resume refuses to touch an existing run")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--threads", type=_threads, default=0, help="torch CPU threads (0: torch's default)")
    _add_config_flags(p)
    p.set_defaults(func=_cmd_train)
    one_line_errors(p)

    p = commands.add_parser(
        "eval", help="evaluate a run on the test split (voxel IoU, Chamfer-L1, normal consistency, silhouette IoU), "
        "or exported ONNX models (--models) on any dataset, e.g. your own meshes",
        description="`sketchmesh eval RUN --data DIR` scores a training run's torch networks. "
        "`sketchmesh eval --models DIR --data DIR [--split all]` scores folders of exported ONNX models through the "
        "app's engine on any dataset (e.g. built with `sketchmesh data --source meshes:PATH`): per-mesh voxel IoU "
        "from each mesh's line drawings, beside retrieval and the template sphere as floors.",
    )
    p.add_argument("run", metavar="RUN", nargs="?", help="training run folder (or give --models instead)")
    p.add_argument("--models", dest="eval_models", metavar="DIR", action="append", default=None,
                   help="instead of RUN: a folder of exported ONNX models ('bundled': the app's); repeat to compare")
    p.add_argument("--data", required=True, metavar="DIR")
    p.add_argument("--split", default="test", choices=("train", "val", "test", "all"),
                   help="default test; all (--models only): every shape, e.g. of a folder of your own meshes")
    p.add_argument("--views", type=int_in(0, 10**6), default=None, metavar="N",
                   help="--models: line drawings per mesh, evenly spaced over its views (default 4; 0: all)")
    p.add_argument("--retrieval-data", metavar="DIR",
                   help="dataset whose train split the retrieval floor searches (default --data; e.g. the "
                        "larger dataset a run was trained on)")
    p.add_argument("--json", metavar="PATH", help="write the results as JSON here")
    p.add_argument("--out", metavar="DIR",
                   help="folder for the markdown table, JSON and figure (default RUN/eval, or DATA/eval with --models)")
    p.add_argument("--augment-strength", type=unit_float, default=0.0, help="sketch augmentation of the test sketches")
    p.add_argument("--sketch-path", choices=("stored", "image", "canvas"), default="stored",
                   help="how a test sketch reaches the generator: stored (default) the dataset's raster as it is; "
                   "image: through the engine's image-file preprocessing (binarise, reframe, thin, redraw at the "
                   "standard width in full ink), as the app treats a scanned drawing; canvas: its strokes drawn as the "
                   "app's canvas draws a pen drawing (framed on the points, standard width, full ink)")
    p.add_argument("--mesh-scale", type=float_in(1e-3, 10.0), default=None, metavar="S",
                   help="RUN: scale every predicted mesh about its bounding-box centre by S before scoring it "
                   "(a calibration probe; default 1)")
    p.add_argument("--gt-normals", action="store_true",
                   help="feed the predictor the ground-truth normal images instead of the generator's")
    p.add_argument("--generator-run", metavar="RUN", help="take the generator from this run (default: RUN)")
    p.add_argument("--baseline-run", metavar="RUN", action="append", default=[],
                   help="also evaluate this run (e.g. the silhouette-only lambda_n = 0 run); repeatable")
    p.add_argument("--no-retrieval", action="store_true", help="skip the nearest-training-sample retrieval baseline")
    p.add_argument("--mirror-average", action="store_true",
                   help="also score every run (or model folder) as 'NAME +mirror': each mesh averaged with the one "
                   "predicted from the drawing flipped left to right (the app's Mirror average), at twice the cost")
    p.add_argument("--mirror-only", action="store_true", default=None,
                   help="--models: score every folder only mirror averaged (the app's default), not also plain")
    p.add_argument("--max-samples", type=int_in(0, 10**9), default=0,
                   help="evaluate at most this many test samples (with --models: meshes), evenly spaced (0: all)")
    p.add_argument("--voxel-resolution", type=int_in(4, MAX_VOXEL_RESOLUTION), default=32)
    voxel_centres_flag(p)
    p.add_argument("--elevation", type=float_in(-90.0, 90.0), default=None, metavar="DEG",
                   help="only the views rendered at this elevation (e.g. 0 for side and front views)")
    p.add_argument("--threads", type=_threads, default=0,
                   help="torch threads (with --models: ONNX Runtime threads) (0: the default)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_cmd_eval)
    one_line_errors(p)

    p = commands.add_parser("export", help="export a run to the engine's ONNX models (with a parity check)")
    p.add_argument("run", metavar="RUN")
    p.add_argument("-o", "--output", required=True, metavar="DIR")
    p.add_argument("--quantize", choices=("none", "int8", "int8-all", "fp16", "int8w"), default="none",
                   help="int8: dynamic int8 quantisation of the mesh predictor; int8-all: of both networks; fp16: the "
                   "mesh predictor's weights stored in float16 and computed in float32 (half the file, float32 speed); "
                   "int8w: both networks' large weights stored in int8, computed in float32 (the bundled models' form)")
    p.add_argument("--generator-run", metavar="RUN", help="take the generator from this run (default: RUN)")
    p.add_argument("--predictor-run", metavar="RUN", help="take the mesh predictor from this run (default: RUN)")
    p.add_argument("--threads", type=_threads, default=0)
    p.set_defaults(func=_cmd_export)
    one_line_errors(p)

    p = commands.add_parser(
        "import-models", help="rebuild exported ONNX models (e.g. the bundled ones) as training runs to train on",
        description="The reverse of export: MODELS (a folder of generator.onnx / mesh_predictor.onnx; 'bundled' for "
        "the app's) becomes the run folders OUT/generator and OUT/predictor, checked against ONNX Runtime, so a "
        "fresh machine can continue training them (--init-normals / --init-mesh) or score them as runs. The "
        "predictor's batch norms, folded into its convolutions by the export, are set from the batch statistics "
        "of --calibration training inputs of --data.",
    )
    p.add_argument("models", metavar="MODELS")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for the run folders (OUT/generator, OUT/predictor)")
    p.add_argument("--data", metavar="DIR", help="dataset for calibration and parity (default: the one in the models' config)")
    p.add_argument("--only", choices=("generator", "predictor"), help="import one network")
    p.add_argument("--calibration", type=int_in(1, 100_000), default=256, metavar="N",
                   help="training inputs whose statistics set the predictor's batch norms (default 256)")
    p.add_argument("--threads", type=_threads, default=0)
    p.set_defaults(func=_cmd_import)
    one_line_errors(p)

    p = commands.add_parser(
        "quantize-generator", help="write a models folder's generator with its convolutions in int8 "
        "(generator_int8.onnx), calibrated on training sketches; the engine then runs it",
        description="Static int8 quantisation of MODELS/generator.onnx: weights int8 per channel, each convolution's "
        "input quantised with a range calibrated on --drawings sketches of --data's --split (half as drawn, half "
        "with strong hand-drawn augmentation); the first and last convolutions and those on images under 16 x 16 "
        "stay float32. Written as "
        "MODELS/generator_int8.onnx, which the engine runs in place of generator.onnx (kept for training).",
    )
    p.add_argument("models", metavar="MODELS", help="models folder holding generator.onnx")
    p.add_argument("--data", required=True, metavar="DIR", help="dataset whose sketches calibrate the ranges")
    p.add_argument("--split", choices=("train", "val"), default="train")
    p.add_argument("--drawings", type=int_in(2, 10_000), default=CALIBRATION_DRAWINGS, metavar="N",
                   help=f"calibration drawings (default {CALIBRATION_DRAWINGS})")
    p.add_argument("--keep-float", type=int_in(0, 8), default=1, metavar="K",
                   help="convolutions at each end kept float32 (default 1)")
    p.add_argument("--min-pixels", type=int_in(0, 65536), default=None, metavar="N",
                   help="convolutions with fewer output pixels stay as stored (default: engine.bench.STATIC_MIN_PIXELS, "
                   "16 x 16)")
    p.set_defaults(func=_cmd_quantize_generator)
    one_line_errors(p)

    p = commands.add_parser(
        "average", help="average the weights of runs of one network (e.g. two learning-rate cycles' ends) into a new run",
        description="Stochastic weight averaging of RUN folders of the same network: the weighted mean of their "
        "newest checkpoints' parameters, the batch norms set again from the averaged network's statistics on "
        "--bn-samples training inputs; fixed buffers must agree. The result (OUT) is a run like any other for "
        "eval, export and train --init-mesh.",
    )
    p.add_argument("runs", metavar="RUN", nargs="+", help="two or more run folders")
    p.add_argument("--out", required=True, metavar="RUN", help="new run folder for the average")
    p.add_argument("--weights", type=float, nargs="+", metavar="W", help="one weight per run (default equal)")
    p.add_argument("--bn-samples", type=int_in(0, 100_000), default=1024, metavar="N",
                   help="training inputs that set the batch norms (default 1024; 0: average the runs' statistics)")
    p.add_argument("--data", metavar="DIR", help="dataset for the batch norms (default: the first run's)")
    p.add_argument("--threads", type=_threads, default=0)
    p.set_defaults(func=_cmd_average)
    one_line_errors(p)


def main(argv: list[str] | None = None) -> int:
    """Standalone entry point with only these commands (same error handling as sketchmesh)."""
    parser = one_line_errors(argparse.ArgumentParser(prog="python -m training.cli.train"))
    parser.add_argument("--debug", action="store_true")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    register(commands, None)
    args = parser.parse_args(argv)
    return run_guarded(args.func, args)


if __name__ == "__main__":
    sys.exit(main())
