"""``sketchmesh router train | eval | export | set``: the category router that sends a drawing to a specialist predictor.

Cheap to import (argparse only; torch loads inside the commands). See :mod:`training.model.router`.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from engine.cliutil import check_output_dir, int_in, one_line_errors
from engine.errors import ModelError, SketchmeshError


class RouterArgsError(SketchmeshError):
    """A router flag has an invalid value."""


def _torch(threads: int):
    from training._torch import require_torch

    torch = require_torch()
    if threads:
        torch.set_num_threads(threads)
    return torch


def _check_data(paths: list[str], what: str) -> None:
    for p in paths:
        if not Path(p).is_dir():
            raise ModelError(f"{what} {p}: dataset folder does not exist")


def _print_table(table: list[dict], group: list[str]) -> None:
    print(f"routing to the {'/'.join(group)} specialist (its categories' summed probability above the threshold):")
    print(f"{'threshold':>9} {'recall':>7} {'false routes':>12}   ({table[0]['group']} drawings of the group, "
          f"{table[0]['others']} others)")
    for r in table:
        print(f"{r['threshold']:>9.2f} {r['recall']:>7.3f} {r['false_routes']:>12.4f}")


def _cmd_train(args: argparse.Namespace) -> int:
    _torch(args.threads)
    from training.loop.router import train_router
    from training.model.router import RouterConfig

    _check_data(args.data, "--data")
    if args.val_data:
        _check_data([args.val_data], "--val-data")
    check_output_dir(args.out, "--out")
    if args.group and not args.val_data:
        raise RouterArgsError("--group reports routing on --val-data: give --val-data DIR too")
    cfg = RouterConfig(data=list(args.data), inputs=list(args.inputs), val_data=args.val_data, epochs=args.epochs,
                       batch=args.batch, lr=args.lr, shift=args.shift, seed=args.seed, channels=list(args.channels),
                       weight_decay=args.weight_decay)
    try:
        last = train_router(args.out, cfg, resume=args.resume, progress=not args.quiet, group=args.group or None)
    except ValueError as exc:  # another router's checkpoint, --no-resume on a run, an unknown --group category
        raise RouterArgsError(str(exc)) from None
    if "val_routing" in last:
        _print_table(last["val_routing"], args.group)
    print(f"router run: {args.out} ({last.get('epoch', 0)} epochs in {last.get('seconds', 0.0) / 60:.1f} min; "
          f"validation accuracy {last.get('val_accuracy', float('nan')):.3f})")
    return 0


def _cmd_eval(args: argparse.Namespace) -> int:
    _torch(args.threads)
    from training.loop.router import load_router_run, predict_probabilities
    from training.model.router import labelled_rows, routing_table

    _check_data([args.data], "--data")
    net, cfg = load_router_run(args.run)
    unknown = [c for c in args.group if c not in cfg.categories]
    if unknown:
        raise RouterArgsError(f"--group {' '.join(unknown)}: not among the router's categories {cfg.categories}")
    sets = labelled_rows(args.data, args.inputs, args.split, cfg.categories)[0]
    probs, labels = predict_probabilities(net, sets)
    acc = float((probs.argmax(1) == labels).mean())
    print(f"{len(labels)} drawings of {args.data} ({args.split}): category right for {acc:.3f}")
    table = routing_table(probs, labels, cfg.categories, args.group)
    _print_table(table, args.group)
    if args.json:
        from engine.fileio import atomic_write_text

        atomic_write_text(args.json, json.dumps({"accuracy": acc, "routing": table, "drawings": len(labels)}, indent=1))
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    _torch(args.threads)
    from training.export.router import export_router, parse_routes
    from training.loop.router import load_router_run

    if not Path(args.models).is_dir():
        raise ModelError(f"--models {args.models}: model folder does not exist")
    _, cfg = load_router_run(args.run)
    try:
        routes = parse_routes(args.route, cfg.categories)
        report = export_router(args.run, args.models, routes, args.threshold, mirror=args.mirror)
    except ValueError as exc:
        raise RouterArgsError(str(exc)) from None
    print(f"wrote {report['path']} ({report['bytes'] / 1e3:.0f} kB; torch vs ONNX Runtime within "
          f"{report['parity_max_abs']:.1e}); routes {json.dumps(routes)} above {args.threshold}")
    return 0


def _cmd_set(args: argparse.Namespace) -> int:
    from training.export.router_options import set_router_options

    if not Path(args.models).is_dir():
        raise ModelError(f"{args.models}: model folder does not exist")
    try:
        report = set_router_options(args.models, threshold=args.threshold, mirror=args.mirror)
    except ValueError as exc:
        raise RouterArgsError(str(exc)) from None
    b, a = report["before"], report["after"]
    was = {None: "off", "false": "off", "true": "on"}.get(b["route_mirror"], repr(b["route_mirror"]))
    print(f"{report['path']}: threshold {b['route_threshold']} -> {a['route_threshold']}, mirror routing "
          f"{was} -> {'on' if a['route_mirror'] else 'off'} (the network unchanged)")
    return 0


def _open_unit(text: str) -> float:
    """A number strictly between 0 and 1 (a threshold, a learning rate)."""
    try:
        t = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 < t < 1.0:
        raise argparse.ArgumentTypeError(f"must lie strictly between 0 and 1, got {text}")
    return t


def _non_negative(text: str) -> float:
    """A finite number >= 0 (a weight decay)."""
    try:
        t = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 <= t < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return t


MIRROR_HELP = ("route on the mean probabilities of the drawing and its left-right flip when the engine's mirror "
               "averaging is on (route_mirror)")


def register(commands, bench) -> None:
    """Add ``router`` (train, eval, export, set) to the top-level sub-parsers."""
    p = commands.add_parser(
        "router", help="train, evaluate and export the category router that picks a specialist mesh predictor",
        description="A small classifier over the categories reads the predictor's input (the generator's normal image "
        "at 64 x 64); the engine sends a drawing to a specialist predictor when the summed probability of that "
        "specialist's categories passes a threshold (engine.contract, router.onnx).",
    )
    sub = p.add_subparsers(dest="router_command", metavar="ACTION", required=True)
    one_line_errors(p)

    t = sub.add_parser("train", help="train (or resume) a router on datasets' generated normal images")
    t.add_argument("--data", required=True, action="append", metavar="DIR",
                   help="dataset whose train split (and generated sets --inputs) it learns from; repeatable")
    t.add_argument("--inputs", nargs="+", default=["normals16", "normals16_mirror"], metavar="NAME",
                   help="generated sets of each dataset (default: normals16 normals16_mirror)")
    t.add_argument("--val-data", metavar="DIR", help="dataset (train split, same generated sets) scored after each epoch")
    t.add_argument("--out", required=True, metavar="RUN")
    t.add_argument("--epochs", type=int_in(1, 10_000), default=30)
    t.add_argument("--batch", type=int_in(1, 65_536), default=128)
    t.add_argument("--lr", type=_open_unit, default=2e-3)
    t.add_argument("--shift", type=int_in(0, 16), default=3, help="random shift in pixels (default 3)")
    t.add_argument("--channels", type=int_in(1, 1024), nargs="+", default=[16, 32, 48, 64], metavar="C",
                   help="the stride-2 convolutions' widths (default 16 32 48 64: about 50,000 parameters)")
    t.add_argument("--weight-decay", type=_non_negative, default=1e-4, help="AdamW weight decay (default 1e-4)")
    t.add_argument("--seed", type=int_in(0, 2**31 - 1), default=0)
    t.add_argument("--group", nargs="+", metavar="CATEGORY", help="report routing to these categories on --val-data")
    t.add_argument("--resume", action=argparse.BooleanOptionalAction, default=True)
    t.add_argument("--threads", type=int_in(0, 256), default=0)
    t.add_argument("--quiet", action="store_true")
    t.set_defaults(func=_cmd_train)
    one_line_errors(t)

    e = sub.add_parser("eval", help="a router run's accuracy and routing table on a dataset's generated images")
    e.add_argument("run", metavar="RUN")
    e.add_argument("--data", required=True, metavar="DIR")
    e.add_argument("--split", default="train", choices=("train", "val", "test"))
    e.add_argument("--inputs", nargs="+", default=["normals16", "normals16_mirror"], metavar="NAME")
    e.add_argument("--group", nargs="+", required=True, metavar="CATEGORY")
    e.add_argument("--json", metavar="PATH")
    e.add_argument("--threads", type=int_in(0, 256), default=0)
    e.set_defaults(func=_cmd_eval)
    one_line_errors(e)

    x = sub.add_parser("export", help="write router.onnx into a model folder that holds the specialists")
    x.add_argument("run", metavar="RUN")
    x.add_argument("--models", required=True, metavar="DIR", help="model folder (with the specialist files in it)")
    x.add_argument("--route", required=True, action="append", metavar="FILE=CAT[,CAT...]",
                   help="a specialist file in DIR and the categories it serves; repeatable")
    x.add_argument("--threshold", type=_open_unit, default=0.8,
                   help="summed probability above which a drawing goes to the specialist (default 0.8)")
    x.add_argument("--mirror", action="store_true", help=MIRROR_HELP)
    x.add_argument("--threads", type=int_in(0, 256), default=0)
    x.set_defaults(func=_cmd_export)
    one_line_errors(x)

    s = sub.add_parser("set", help="change a model folder's routing threshold or mirror routing (no retraining)",
                       description="Rewrite router.onnx's route_threshold and route_mirror metadata in place (atomic); "
                       "the network is kept as it is.")
    s.add_argument("models", metavar="DIR", help="model folder with a router.onnx")
    s.add_argument("--threshold", type=_open_unit,
                   help="summed probability above which a drawing goes to the specialist")
    s.add_argument("--mirror", action=argparse.BooleanOptionalAction, default=None, help=MIRROR_HELP)
    s.set_defaults(func=_cmd_set)
    one_line_errors(s)
