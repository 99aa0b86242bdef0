"""``sketchmesh infer`` and ``sketchmesh bench engine`` (registered into :mod:`sketchmesh.cli`).

Cheap to import: argparse only; the engine's heavier modules load inside the command functions.
Every user-facing failure is an :class:`engine.errors.SketchmeshError` (one line on stderr,
non-zero exit); bad flags give one ``sketchmesh infer: error: ...`` line and exit 2.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from engine.cliutil import int_in, one_line_errors

MAX_SUBDIVIDE_LEVELS = 4
"""--subdivide limit: 1280 faces * 4**4 = 327,680 faces."""

MAX_SMOOTH_ITERATIONS = 1000

MAX_REFINE_STEPS = 100  # mirrors engine.refine.MAX_STEPS (checked by a test)


FORMATS = ("obj", "glb", "gltf", "ply", "stl")  # mirrors engine.export.WRITERS (checked by a test)


def register(commands, bench) -> None:
    """Add ``infer`` to the top-level commands and ``engine`` to the bench commands."""
    p = commands.add_parser(
        "infer",
        help="sketch image(s) -> mesh file(s), headless",
        description="Predict a 3D mesh from each sketch image and export it. "
        "Formats: .obj (vertex normals), .glb, .gltf (self-contained), .ply, .stl.",
    )
    p.add_argument("sketches", nargs="+", metavar="SKETCH", help="sketch image(s): PNG, JPEG, BMP, TIFF or WebP")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file for one sketch (format from its suffix), or a folder for several")
    p.add_argument("--format", choices=FORMATS, help="export format (default: OUT's suffix, or obj into a folder)")
    p.add_argument("--normals", metavar="PATH", help="also save the generated normal image as PNG (a folder for several sketches)")
    p.add_argument("--report", metavar="PATH", help="write a JSON report (timings, counts, watertight, self-intersections); "
                   "a folder for several sketches")
    p.add_argument("--models", metavar="DIR", default=argparse.SUPPRESS,  # keeps `sketchmesh --models DIR infer`
                   help="model folder replacing the bundled models")
    p.add_argument("--smooth", type=int_in(0, MAX_SMOOTH_ITERATIONS), default=0, metavar="N", help="Taubin smoothing iterations")
    p.add_argument("--subdivide", type=int_in(0, MAX_SUBDIVIDE_LEVELS), default=0, metavar="N",
                   help=f"Loop subdivision levels (0..{MAX_SUBDIVIDE_LEVELS})")
    p.add_argument("--refine", type=int_in(0, MAX_REFINE_STEPS), default=0, metavar="N",
                   help="refine the mesh with N steps so its silhouette from the sketch's view matches the drawing's "
                   "outline (0 = off; see engine/refine.py)")
    p.add_argument("--mirror-average", action="store_true",
                   help="also predict from the drawing flipped left to right and average the two meshes (about twice "
                   "the networks' time; see engine/pipeline.py)")
    p.add_argument("--repair-folds", action="store_true",
                   help="where the predicted surface crosses itself, smooth just there until it does not (one "
                   "self-intersection check when nothing crosses; see engine/postprocess.py)")
    p.add_argument("--threads", type=int_in(1, 256), default=None, metavar="N", help="inference threads (default: physical cores)")
    p.set_defaults(func=cmd_infer)
    one_line_errors(p)

    b = bench.add_parser(
        "engine",
        help="per-stage inference latency (p50/p95) for float32 and int8 models, with their error",
        description="Time every inference stage over many runs for the float32 models and dynamic-int8 "
        "variants, and report each variant's error against float32.",
    )
    b.add_argument("--models", metavar="DIR", default=argparse.SUPPRESS,
                   help="model folder (default: the bundled models)")
    b.add_argument("--runs", type=int_in(1, 100_000), default=50, metavar="N", help="timed runs per variant (default 50)")
    b.add_argument("--warmup", type=int_in(0, 1000), default=3, metavar="N", help="untimed runs first (default 3)")
    b.add_argument("--threads", type=int_in(1, 256), default=None, metavar="N", help="inference threads")
    b.add_argument("--sketch", action="append", metavar="IMAGE", help="sketch image(s) to use (default: bundled samples "
                   "or synthetic sketches)")
    b.add_argument("--variants", default="fp32,int8-predictor,int8,int8w",
                   help="comma list of fp32, int8-predictor, int8, int8w (weights stored in int8, computed in float32), "
                        "each optionally with +mirror (mirror averaging on)")
    b.add_argument("--json", metavar="PATH", help="write the records as JSON")
    b.set_defaults(func=cmd_bench_engine)
    one_line_errors(b)


def _normals_png_bytes(normals, path: Path) -> bytes:
    import cv2
    import numpy as np

    from engine.errors import ExportError

    if path.suffix.lower() != ".png":
        raise ExportError(f"--normals must name a .png file, got {path.name}")
    rgb8 = np.clip(np.rint(normals * 255.0), 0, 255).astype(np.uint8)
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb8[..., ::-1]))
    if not ok:
        raise ExportError(f"cannot encode the normal image for {path}")
    return buf.tobytes()


def infer_one(engine, sketch: Path, out: Path, fmt: str, *, smooth: int = 0, subdivide: int = 0, refine: int = 0,
              normals_path: Path | None = None, report_path: Path | None = None) -> dict:
    """Run one sketch through the engine, post-process, write its files; return the report record.

    The mesh, the normal image and the JSON report are written all or nothing
    (:class:`engine.fileio.StagedWrites`): if one cannot be written, none of them is.

    Returns:
        dict with sketch, output, timings_ms (preprocess, generator, downsample, predictor,
        assemble, refine, repair, postprocess, export, stats, total), vertices, faces, watertight,
        winding_consistent, self_intersections, area, volume, cached, normals, refine_steps, mirror_average,
        repair_folds, warnings.
    """
    from engine.pipeline import to_raster

    t_start = time.perf_counter()
    raster = to_raster(sketch)  # bad input fails here, before the exporters are even imported
    t_pre = time.perf_counter()
    _warm_imports()
    from engine.errors import ExportError
    from engine.export import mesh_to_bytes
    from engine.fileio import StagedWrites
    from engine.postprocess import mesh_stats
    from engine.postprocess import smooth as smooth_mesh
    from engine.postprocess import subdivide as subdivide_mesh

    pred = engine.predict(raster, want_normals=normals_path is not None, refine=refine)
    t0 = time.perf_counter()
    mesh = pred.mesh
    if smooth:
        mesh = smooth_mesh(mesh, "taubin", smooth)
    if subdivide:
        mesh = subdivide_mesh(mesh, subdivide, "loop")
    t1 = time.perf_counter()
    staged = StagedWrites()
    try:
        try:
            staged.add(out, mesh_to_bytes(mesh, "." + fmt))
            if normals_path is not None:
                staged.add(normals_path, _normals_png_bytes(pred.normals, normals_path))
            t2 = time.perf_counter()
            stats = mesh_stats(mesh)
            t3 = time.perf_counter()
            timings = dict(pred.timings_ms)
            timings["preprocess"] += (t_pre - t_start) * 1e3  # the image decode and framing happened above
            timings.update(postprocess=(t1 - t0) * 1e3, export=(t2 - t1) * 1e3, stats=(t3 - t2) * 1e3)
            timings["total"] = sum(timings.values())  # excludes the one-off import of the exporters
            record = {
                "sketch": str(sketch),
                "output": str(out),
                "format": fmt,
                "models_dir": str(engine.models_dir),
                "timings_ms": {k: round(v, 3) for k, v in timings.items()},
                **stats,
                "smooth_iterations": smooth,
                "subdivide_levels": subdivide,
                "refine_steps": refine,
                "mirror_average": pred.mirror_average,
                "repair_folds": pred.repair_folds,
                "category": pred.category,  # the model folder's router: what it read the drawing as (None without one)
                "route": pred.route,  # the specialist predictor it chose (None: mesh_predictor.onnx)
                "warnings": list(pred.warnings),
                "cached": pred.cached,
                "normals": str(normals_path) if normals_path is not None else None,
            }
            if report_path is not None:
                staged.add(report_path, json.dumps(record, indent=2) + "\n")
            staged.commit()
        except OSError as exc:
            raise ExportError(f"cannot write {exc.filename or out}: {exc.strerror or exc}; nothing was written") from None
    finally:
        staged.discard()
    return record


def _warm_imports() -> None:
    """Import the exporters' dependencies (trimesh takes ~1.5 s) outside the timed stages."""
    import importlib

    for name in ("trimesh", "trimesh.exchange.gltf", "engine.export", "engine.postprocess"):
        importlib.import_module(name)


def cmd_infer(args: argparse.Namespace) -> int:
    from engine.cliutil import check_output_dir, check_output_file
    from engine.errors import ExportError, SketchInputError, SketchmeshError
    from engine.export import check_export_path, supported_suffixes
    from engine.pipeline import SketchEngine

    sketches = [Path(s) for s in args.sketches]
    out = Path(args.output)
    many = len(sketches) > 1
    folder_mode = many or out.is_dir() or str(args.output).endswith(("/", os.sep))
    if folder_mode:
        if out.exists() and not out.is_dir():
            raise ExportError(f"-o {out}: exists and is not a folder (several sketches need an output folder)")
        if many and out.suffix.lower() in supported_suffixes() and not out.is_dir():
            raise ExportError(f"-o {out}: with {len(sketches)} sketches, -o must be a folder, not a {out.suffix} file")
        fmt = args.format or "obj"
        stems = [s.stem for s in sketches]
        dupes = sorted({s for s in stems if stems.count(s) > 1})
        if dupes:
            raise SketchInputError(f"several sketches are named {dupes[0]!r}; their outputs would overwrite each other")
        targets = [out / f"{s.stem}.{fmt}" for s in sketches]
    else:
        if args.format and out.suffix and out.suffix.lower() in supported_suffixes() and out.suffix.lower() != "." + args.format:
            raise ExportError(f"-o {out.name} does not match --format {args.format}")
        fmt = check_export_path(out, args.format).lstrip(".")
        targets = [out]
    if many:
        for flag, value, suffix in (("--normals", args.normals, ".png"), ("--report", args.report, ".json")):
            if value and (Path(value).suffix.lower() == suffix or Path(value).is_file()):
                raise ExportError(f"{flag} {value}: with {len(sketches)} sketches, {flag} must be a folder")

    def side_path(option: str | None, stem: str, suffix: str) -> Path | None:
        if option is None:
            return None
        p = Path(option)
        return p / f"{stem}{suffix}" if many else p

    if args.normals and not many and Path(args.normals).suffix.lower() != ".png":
        raise ExportError(f"--normals must name a .png file, got {args.normals}")
    # every output location is checked before the models load or any sketch is read
    if folder_mode:
        check_output_dir(out, "-o")
    else:
        check_output_file(out, "-o")
    for flag, value in (("--normals", args.normals), ("--report", args.report)):
        if value:
            (check_output_dir if many else check_output_file)(value, flag)

    sketch_engine = SketchEngine(args.models, threads=args.threads, mirror_average=args.mirror_average,
                                 repair_folds=args.repair_folds)
    sketch_engine.load()  # model problems stop everything before any sketch is read

    progress = None
    if many and sys.stderr.isatty():
        try:
            from tqdm import tqdm

            progress = tqdm(total=len(sketches), unit="sketch", file=sys.stderr)
        except ImportError:
            progress = None
    failures: list[SketchmeshError] = []
    for sketch, target in zip(sketches, targets):
        try:
            record = infer_one(
                sketch_engine, sketch, target, fmt, smooth=args.smooth, subdivide=args.subdivide, refine=args.refine,
                normals_path=side_path(args.normals, sketch.stem, "_normals.png"),
                report_path=side_path(args.report, sketch.stem, ".json"),
            )
            t = record["timings_ms"]
            msg = (f"{sketch} -> {target} ({record['vertices']} vertices, {record['faces']} faces, "
                   f"watertight={record['watertight']}, {t['total']:.0f} ms)")
            (progress.write(msg) if progress else print(msg))
            for warning in record["warnings"]:
                print(f"sketchmesh: warning: {sketch}: {warning}", file=sys.stderr)
        except SketchmeshError as exc:
            failures.append(exc)
            if not many:
                raise
            print(f"sketchmesh: error: {exc}", file=sys.stderr)
        if progress:
            progress.update(1)
    if progress:
        progress.close()
    if failures:
        raise SketchmeshError(f"{len(failures)} of {len(sketches)} sketches failed")
    return 0


def cmd_bench_engine(args: argparse.Namespace) -> int:
    from engine.bench import run_engine_bench

    return run_engine_bench(
        models_dir=args.models, runs=args.runs, warmup=args.warmup, threads=args.threads,
        sketches=args.sketch, variants=[v.strip() for v in args.variants.split(",") if v.strip()],
        json_path=args.json,
    )
