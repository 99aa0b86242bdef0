"""``sketchmesh train | eval | export``: cheap to import (argparse only; torch loads inside commands).

Every :class:`training.loop.config.TrainConfig` field has a flag (``--lambda-n 0`` etc.); the config is
built once here and passed down. Also runnable as ``python -m training.cli.train ...`` (handy
under ``torchrun --nproc_per_node 2 -m training.cli.train train mesh ...``).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys

from engine.cliutil import run_guarded
from engine.errors import SketchmeshError

# flags handled explicitly (positional mode, short names) rather than generated from the dataclass
_EXPLICIT = {"mode", "data_dir", "out_dir"}


class ConfigError(SketchmeshError):
    """A training flag has an invalid value."""


def _add_config_flags(parser: argparse.ArgumentParser) -> None:
    from training.loop.config import TrainConfig

    for f in dataclasses.fields(TrainConfig):
        if f.name in _EXPLICIT:
            continue
        flag = "--" + f.name.replace("_", "-")
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        help_text = f"(default: {default!r})"
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


def _cmd_train(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    from training._torch import require_torch

    torch = require_torch()
    if args.threads:
        torch.set_num_threads(args.threads)
    from training.loop.trainer import train

    last = train(cfg, resume=args.resume, progress=not args.quiet)
    if os.environ.get("RANK", "0") != "0":  # under torchrun only rank 0 reports
        return 0
    if last:
        print("final: " + "  ".join(f"{k}={v:.4g}" for k, v in last.items()))
    print(f"run folder: {cfg.out_dir}")
    return 0


def _cmd_eval(args: argparse.Namespace) -> int:
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

    reports = export_run(args.run, args.output, generator_run=args.generator_run,
                         predictor_run=args.predictor_run, quantize=args.quantize)
    for r in reports:
        print(r.line())
    if reports and reports[0].parity_inputs:
        print(f"parity inputs: {reports[0].parity_inputs}")
    print(f"exported {len(reports)} model(s) to {args.output}: torch vs ONNX Runtime parity within tolerance")
    return 0


def register(commands, bench) -> None:
    """Add ``train``, ``eval`` and ``export`` to the top-level sub-parsers (see :mod:`sketchmesh.cli`)."""
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
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: torch's default)")
    _add_config_flags(p)
    p.set_defaults(func=_cmd_train)

    p = commands.add_parser(
        "eval", help="evaluate a run on the test split (voxel IoU, Chamfer-L1, normal consistency, silhouette IoU)",
    )
    p.add_argument("run", metavar="RUN")
    p.add_argument("--data", required=True, metavar="DIR")
    p.add_argument("--split", default="test", choices=("train", "val", "test"))
    p.add_argument("--json", metavar="PATH", help="write the results as JSON here")
    p.add_argument("--out", metavar="DIR", help="folder for the markdown table and figure (default RUN/eval)")
    p.add_argument("--augment-strength", type=float, default=0.0, help="sketch augmentation of the test sketches")
    p.add_argument("--gt-normals", action="store_true",
                   help="feed the predictor the ground-truth normal images instead of the generator's")
    p.add_argument("--generator-run", metavar="RUN", help="take the generator from this run (default: RUN)")
    p.add_argument("--baseline-run", metavar="RUN", action="append", default=[],
                   help="also evaluate this run (e.g. the silhouette-only lambda_n = 0 run); repeatable")
    p.add_argument("--no-retrieval", action="store_true", help="skip the nearest-training-sample retrieval baseline")
    p.add_argument("--max-samples", type=int, default=0, help="evaluate at most this many test samples (0: all)")
    p.add_argument("--voxel-resolution", type=int, default=32)
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_cmd_eval)

    p = commands.add_parser("export", help="export a run to the engine's ONNX models (with a parity check)")
    p.add_argument("run", metavar="RUN")
    p.add_argument("-o", "--output", required=True, metavar="DIR")
    p.add_argument("--quantize", choices=("none", "int8", "int8-all"), default="none",
                   help="int8: dynamic int8 quantisation of the mesh predictor; int8-all: of both networks")
    p.add_argument("--generator-run", metavar="RUN", help="take the generator from this run (default: RUN)")
    p.add_argument("--predictor-run", metavar="RUN", help="take the mesh predictor from this run (default: RUN)")
    p.add_argument("--threads", type=int, default=0)
    p.set_defaults(func=_cmd_export)


def main(argv: list[str] | None = None) -> int:
    """Standalone entry point with only these three commands (same error handling as sketchmesh)."""
    parser = argparse.ArgumentParser(prog="python -m training.cli.train")
    parser.add_argument("--debug", action="store_true")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    register(commands, None)
    args = parser.parse_args(argv)
    return run_guarded(args.func, args)


if __name__ == "__main__":
    sys.exit(main())
