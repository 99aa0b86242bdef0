"""``sketchmesh data`` and ``sketchmesh bench data``: cheap to import (argparse only; torch loads inside commands).

Usage::

    sketchmesh data --source procedural --shapes-per-category N --out DIR [--views 24]
                    [--elevations 30 ...] [--size 256] [--workers K] [--shard K/N] [--seed S]
                    [--augment-strength A] [--categories chair table ...]
    sketchmesh data --source shapenet:PATH --out DIR ...
    sketchmesh data --source meshes:PATH --out DIR ...
    sketchmesh data merge OUT SHARD_DIR [SHARD_DIR ...]
    sketchmesh data preview DIR -o sheet.png [--rows 8] [--views-per-shape 2] [--augment-strength A]
    sketchmesh bench data [--views 4] [--json PATH]

(``sketchmesh data build --source ...`` is the same as ``sketchmesh data --source ...``.)
The format is described in docs/DATA_FORMAT.md.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
import warnings

from engine.cliutil import check_output_dir, check_output_file, int_in, one_line_errors, positive_int, unit_float
from engine.errors import SketchmeshError


class DataCommandError(SketchmeshError):
    """A `sketchmesh data` flag or input is unusable."""


def _elevation(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an angle in degrees, got {text!r}") from None
    if not -90.0 < v < 90.0:
        raise argparse.ArgumentTypeError(f"elevation must be in (-90, 90) degrees, got {v}")
    return v


def _add_build_flags(p: argparse.ArgumentParser, required_out: bool) -> None:
    p.add_argument("--source", default="procedural",
                   help="procedural | shapenet:PATH | meshes:PATH (default: procedural)")
    p.add_argument("--out", required=required_out, default=None, help="dataset folder to write")
    p.add_argument("--shapes-per-category", type=positive_int, default=None,
                   help="shapes per category (procedural default 10; other sources: at most this many)")
    p.add_argument("--first-shape", type=int_in(0, 10**7), default=0, metavar="I",
                   help="procedural source: each category's shapes start at index I (default 0), so a build from "
                        "I = N holds only shapes that a build of N per category does not")
    p.add_argument("--categories", nargs="+", default=None, metavar="NAME", help="only these categories")
    p.add_argument("--views", type=positive_int, default=24, help="azimuths per elevation (default 24)")
    p.add_argument("--elevations", type=_elevation, nargs="+", default=[30.0], metavar="DEG",
                   help="elevations in degrees (default 30)")
    p.add_argument("--views-per-shape", type=positive_int, default=None, metavar="K",
                   help="render K of the grid's views per shape, drawn per shape (as many at each elevation when K "
                        "is a multiple of them): more shapes for the same rendering (default: every view)")
    p.add_argument("--size", type=positive_int, default=256, help="sketch / normal image size (default 256)")
    p.add_argument("--small-size", type=positive_int, default=64, help="predictor target size (default 64)")
    p.add_argument("--workers", type=int_in(1, 256), default=1, help="processes rendering shapes in parallel")
    p.add_argument("--shard", default=None, metavar="K/N", help="render only shard K of N (0 <= K < N)")
    p.add_argument("--splits", nargs="+", choices=("train", "val", "test"), default=None, metavar="SPLIT",
                   help="render only the shapes of these splits (train, val, test; default all): e.g. `--splits val test` "
                        "builds what evaluation reads in a fifth of the time, and a later build without it into the same "
                        "folder renders the rest")
    p.add_argument("--seed", type=int, default=0, help="seed of the stored augmented sketches (default 0)")
    p.add_argument("--augment-strength", type=unit_float, default=0.0,
                   help="also store an augmented sketch per view at this strength (the trainer re-augments at load)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def register(commands, bench) -> None:
    """Add ``data`` (build / merge / preview) and ``bench data``."""
    data = one_line_errors(commands.add_parser(
        "data", help="build, merge and preview the training dataset",
        description="Render training data (sketch, normal image, silhouette per view). "
                    "`sketchmesh data --source ... --out DIR` builds; `data merge`, `data preview` and `data samples` are sub-actions."))
    _add_build_flags(data, required_out=False)
    data.set_defaults(func=cmd_build)
    actions = data.add_subparsers(dest="data_command", metavar="ACTION")
    build = one_line_errors(actions.add_parser("build", help="same as `sketchmesh data --source ... --out DIR`"))
    _add_build_flags(build, required_out=True)
    build.set_defaults(func=cmd_build)
    merge = one_line_errors(actions.add_parser("merge", help="merge shard outputs into one dataset"))
    merge.add_argument("out", help="merged dataset folder")
    merge.add_argument("shards", nargs="+", help="shard dataset folders")
    merge.set_defaults(func=cmd_merge)
    preview = one_line_errors(actions.add_parser("preview", help="contact sheet: sketch | normals | silhouette rows"))
    preview.add_argument("dir", help="dataset folder")
    preview.add_argument("-o", "--output", required=True, help="PNG to write")
    preview.add_argument("--rows", type=positive_int, default=8, help="shapes (rows) on the sheet (default 8)")
    preview.add_argument("--views-per-shape", type=positive_int, default=2, help="views per row (default 2)")
    preview.add_argument("--augment-strength", type=unit_float, default=0.0, help="show load-time augmentation")
    preview.add_argument("--seed", type=int, default=0)
    preview.set_defaults(func=cmd_preview)
    samples = one_line_errors(actions.add_parser("samples", help="export sketches of a split as PNG files to open in the app"))
    samples.add_argument("dir", help="dataset folder")
    samples.add_argument("-o", "--output", required=True, help="folder to write the PNG files into")
    samples.add_argument("--split", default="test", choices=("train", "val", "test"))
    samples.add_argument("--per-category", type=positive_int, default=1, help="shapes per category (default 1)")
    samples.add_argument("--view", type=int, default=3, help="view index of each shape (default 3: 45 degrees azimuth)")
    samples.add_argument("--augment-strength", type=unit_float, default=0.0, help="hand-drawn augmentation (default clean)")
    samples.add_argument("--seed", type=int, default=0)
    samples.set_defaults(func=cmd_samples)
    gen = one_line_errors(actions.add_parser(
        "generated", help="the generator's normal images of a split's sketches, as a mesh-mode training input",
        description="Run a model folder's generator over the hand-drawn-augmented sketch of every view of a split "
                    "(the app's engine code) and keep the 64 x 64 results in DIR/.cache/generated/NAME, for "
                    "`sketchmesh train mesh --input-normals NAME`. Resumes where a stopped call left off."))
    gen.add_argument("dir", help="dataset folder")
    gen.add_argument("--models", required=True, metavar="DIR", help="ONNX model folder whose generator.onnx to run")
    gen.add_argument("--name", required=True, help="name of the result under DIR/.cache/generated")
    gen.add_argument("--split", default="train", choices=("train", "val", "test", "all"))
    gen.add_argument("--augment-strength", type=unit_float, default=0.5, help="hand-drawn augmentation (default 0.5)")
    gen.add_argument("--seed", type=int, default=0)
    gen.add_argument("--workers", type=int_in(1, 256), default=1, help="processes, one thread each (1: one, two threads)")
    gen.add_argument("--max-shapes", type=positive_int, default=None, help="stop after this many shapes (resume later)")
    gen.add_argument("--mirror", action="store_true",
                     help="run the generator on every drawing flipped left to right: the exact inputs of mirrored "
                          "training items (train mesh --mirror P --mirror-inputs NAME)")
    gen.add_argument("--torch-device", metavar="DEVICE", default=None,
                     help="run the generator in torch on DEVICE (cuda, cpu) instead of ONNX Runtime: the same network "
                          "rebuilt from the file, for a GPU machine; the workers only draw the sketches")
    gen.add_argument("--reuse", metavar="DATASET", default=None,
                     help="another dataset folder (the one this one grew from) whose set of the same --name was built "
                          "with the same generator and settings: the rows of the shapes both hold in the same file are "
                          "copied from it instead of generated again")
    gen.add_argument("--no-progress", action="store_true", help="no progress bar")
    gen.set_defaults(func=cmd_generated)

    b = one_line_errors(bench.add_parser(
        "data", help="data generation speed: views/s per core, growth with mesh size, line-drawing share"))
    b.add_argument("--views", type=positive_int, default=3, help="views timed per mesh (default 3)")
    b.add_argument("--size", type=positive_int, default=256)
    b.add_argument("--faces", type=positive_int, nargs="+", default=[1000, 10000, 100000],
                   help="target face counts (default 1000 10000 100000)")
    b.add_argument("--augment-strength", type=unit_float, default=0.5)
    b.add_argument("--json", default=None, metavar="PATH", help="write the records as JSON")
    b.set_defaults(func=cmd_bench_data)


@contextlib.contextmanager
def _plain_warnings():
    """Show warnings (skipped shapes) as one line each: 'sketchmesh: warning: ...'."""
    old = warnings.formatwarning
    warnings.formatwarning = lambda message, *args, **kwargs: f"sketchmesh: warning: {message}\n"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", UserWarning)
            yield
    finally:
        warnings.formatwarning = old


def _require_torch():
    from training._torch import require_torch

    return require_torch()


def cmd_build(args: argparse.Namespace) -> int:
    _require_torch()
    if not args.out:
        raise DataCommandError("missing --out DIR (the dataset folder to write)")
    from training.data.dataset import (
        BuildSettings,
        build_dataset,
        check_build_request,
        make_jobs,
        parse_shard,
        parse_source,
    )

    # everything that can be checked is checked before any shape is rendered or any folder made
    check_output_dir(args.out, "--out")
    shard = parse_shard(args.shard)
    try:
        settings = BuildSettings(size=args.size, small_size=args.small_size, num_azimuths=args.views,
                                 elevations=tuple(args.elevations), augment_strength=args.augment_strength, seed=args.seed,
                                 views_per_shape=args.views_per_shape or 0)
        settings.check()
    except ValueError as exc:
        raise DataCommandError(str(exc)) from None
    if parse_source(args.source)[0] == "procedural":  # the job list itself can be too big to build
        from training.data.shapes import CATEGORIES

        n_categories = len(set(args.categories)) if args.categories else len(CATEGORIES)
        n_shapes = (10 if args.shapes_per_category is None else args.shapes_per_category) * n_categories
        check_build_request(args.out, -(-n_shapes // shard[1]), settings, args.workers)
    jobs = make_jobs(args.source, args.shapes_per_category, args.categories, first_shape=args.first_shape)
    if not jobs:
        raise DataCommandError(f"--source {args.source} has no shapes to render")
    if args.splits:
        jobs = [j for j in jobs if j.split in args.splits]
        if not jobs:
            raise DataCommandError(f"--source {args.source} has no shapes in the split(s) {' '.join(args.splits)}")
    if shard[0] >= len(jobs):
        raise DataCommandError(f"--shard {args.shard}: --source {args.source} has only {len(jobs)} shapes, "
                               f"so shard {shard[0]} of {shard[1]} would render none")
    check_build_request(args.out, -(-len(jobs) // shard[1]), settings, args.workers)
    t0 = time.perf_counter()
    with _plain_warnings():
        summary = build_dataset(args.out, jobs, settings, workers=args.workers, shard=shard, progress=not args.no_progress)
    dt = time.perf_counter() - t0
    if summary["shapes"] == 0:
        failed = summary["failed"] or [("?", "no complete shape file")]
        first = f"{failed[0][0]}: {failed[0][1]}"
        what = first if len(failed) == 1 else f"all {len(failed)} failed, the first with {first}"
        raise DataCommandError(f"no shape could be rendered from --source {args.source}; nothing written ({what})")
    print(f"{summary['rendered']} shapes rendered, {summary['skipped']} already complete, "
          f"{len(summary['failed'])} failed; {args.out} now holds {summary['shapes']} shapes / {summary['views']} views "
          f"({dt:.1f} s)")
    return 1 if summary["failed"] and summary["rendered"] == 0 else 0


def cmd_generated(args: argparse.Namespace) -> int:
    _require_torch()  # the dataset's mesh-array cache is built by the training package
    from training.data.generated import build_generated

    net = None
    if args.torch_device is not None:  # the generator rebuilt from its file, in torch on that device
        import torch

        from engine.models import model_paths, resolve_models_dir
        from training.export.from_onnx import generator_from_onnx

        try:
            device = torch.device(args.torch_device)
        except (RuntimeError, ValueError) as exc:
            raise SketchmeshError(f"--torch-device {args.torch_device!r} is not a torch device ({exc})") from None
        if device.type == "cuda" and not torch.cuda.is_available():
            raise SketchmeshError(f"--torch-device {args.torch_device}: this torch has no CUDA device")
        net = generator_from_onnx(model_paths(resolve_models_dir(args.models))[0]).to(device)
    r = build_generated(args.dir, args.models, args.name, split=args.split, augment_strength=args.augment_strength,
                        seed=args.seed, workers=args.workers, progress=not args.no_progress, max_shapes=args.max_shapes,
                        mirror=args.mirror, torch_generator=net, reuse_from=args.reuse)
    if args.reuse:
        print(f"{r['reused']} views copied from {args.reuse}")
    print(f"{r['written']} views generated in {r['seconds']:.1f} s; {r['done']} of the {r['views']} views of the "
          f"{args.split} split are done")
    return 0


def cmd_merge(args: argparse.Namespace) -> int:
    from training.data.dataset import merge_datasets

    check_output_dir(args.out, "OUT")
    s = merge_datasets(args.out, args.shards)
    print(f"merged {len(args.shards)} shards into {args.out}: {s['shapes']} shapes, {s['views']} views ({s['copied']} files linked/copied)")
    return 0


def cmd_preview(args: argparse.Namespace) -> int:
    from training.data.preview import write_contact_sheet

    if not str(args.output).lower().endswith(".png"):
        raise DataCommandError(f"-o must name a .png file, got {args.output}")
    check_output_file(args.output, "-o")
    h, w = write_contact_sheet(args.dir, args.output, rows=args.rows, views_per_shape=args.views_per_shape,
                               augment_strength=args.augment_strength, seed=args.seed)
    print(f"wrote {args.output} ({w}x{h})")
    return 0


def cmd_samples(args: argparse.Namespace) -> int:
    from training.data.preview import write_samples

    check_output_dir(args.output, "-o")
    written = write_samples(args.dir, args.output, split=args.split, per_category=args.per_category, view=args.view,
                            augment_strength=args.augment_strength, seed=args.seed)
    print(f"wrote {len(written)} sketches to {args.output}")
    return 0


# --------------------------------------------------------------------------- benchmark
def _refined(mesh, target_faces: int):
    """Re-tessellate a closed mesh (geometry unchanged) to about ``target_faces`` faces with manifold3d."""
    import manifold3d
    import numpy as np

    from engine.mesh import Mesh

    m = manifold3d.Manifold(manifold3d.Mesh(np.array(mesh.vertices, np.float32, order="C"), np.array(mesh.faces, np.uint32, order="C")))
    n = int(round((target_faces / max(mesh.num_faces, 1)) ** 0.5))
    if n >= 2:
        m = m.refine(n)
    out = m.to_mesh()
    return Mesh(np.asarray(out.vert_properties)[:, :3], np.asarray(out.tri_verts, np.int64))


def _with_hidden_interior(mesh, faces: int):
    """The mesh plus a dense sphere hidden inside a closed box around its middle (extra hidden faces only)."""
    import numpy as np

    from engine.icosphere import icosphere
    from engine.mesh import Mesh

    level = int(np.clip(np.ceil(np.log(max(faces, 20) / 20) / np.log(4)), 0, 6))
    s = icosphere(level, 0.1)
    v = np.concatenate([mesh.vertices, s.vertices])
    f = np.concatenate([mesh.faces, s.faces + mesh.num_vertices])
    return Mesh(v, f)


def bench_data_records(views: int = 3, size: int = 256, faces=(1000, 10000, 100000), augment_strength: float = 0.5,
                       progress: bool = True) -> list[dict]:
    """Time the full per-view pipeline (render 256 + 64, lines, raster, augmentation) on one core."""
    import torch
    from tqdm import tqdm

    from engine.camera import frame_camera, look_at
    from training.data.augment import render_sketch
    from training.data.lines import extract_lines, prepare_mesh, rasterize_polylines
    from training.data.shapes import make_shape
    from training.render import render_normals_numpy

    torch.set_num_threads(1)
    base = make_shape("loudspeaker", 0)  # closed box-like body: the interior sphere is fully hidden
    cases = []
    for target in faces:
        m = _refined(base, target)
        cases.append((f"loudspeaker (target {target})", m, m.num_faces))
    big = cases[-1][1] if cases else base
    hidden = _with_hidden_interior(cases[0][1], big.num_faces) if cases else base
    cases.append((f"{cases[0][0]} + hidden sphere", hidden, hidden.num_faces))
    # warm-up (imports, first-call allocations) outside the timings
    warm_cam = frame_camera(look_at(10.0, 30.0), base.vertices)
    warm = render_normals_numpy(base, warm_cam, size)
    render_normals_numpy(base, warm_cam, 64)
    warm_lines = extract_lines(prepare_mesh(base), warm_cam, size, warm["depth"], warm["face_index"])
    render_sketch(warm_lines.polylines, size, augment_strength, 0)
    records = []
    for name, mesh, nf in tqdm(cases, desc="bench data", disable=not progress):
        t_prep = time.perf_counter()
        prep = prepare_mesh(mesh)
        t_prep = time.perf_counter() - t_prep
        acc = {"render256": 0.0, "render64": 0.0, "lines": 0.0, "raster": 0.0, "augment": 0.0}
        stats = {}
        for k in range(views):
            cam = frame_camera(look_at(360.0 * k / views + 20.0, 30.0), mesh.vertices)
            t0 = time.perf_counter()
            r = render_normals_numpy(mesh, cam, size)
            t1 = time.perf_counter()
            render_normals_numpy(mesh, cam, 64)
            t2 = time.perf_counter()
            d = extract_lines(prep, cam, size, r["depth"], r["face_index"])
            t3 = time.perf_counter()
            rasterize_polylines(d.polylines, size)
            t4 = time.perf_counter()
            render_sketch(d.polylines, size, augment_strength, k)
            t5 = time.perf_counter()
            for key, dt in zip(("render256", "render64", "lines", "raster", "augment"), (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4)):
                acc[key] += dt
            stats = d.stats
        per_view = {k: v / views for k, v in acc.items()}
        total = sum(per_view.values()) + t_prep / 24.0  # prep is once per shape, amortised over 24 views
        records.append({
            "bench": "data", "mesh": name, "faces": int(nf), "size": size, "views": views,
            "views_per_s_per_core": 1.0 / total, "ms_per_view": 1000 * total,
            **{f"ms_{k}": 1000 * v for k, v in per_view.items()},
            "ms_prepare_per_shape": 1000 * t_prep,
            "line_share": (per_view["lines"] + per_view["raster"] + t_prep / 24.0) / total,
            "visible_faces": stats.get("visible_faces"), "line_segments": stats.get("segments"),
            "polylines": len(d.polylines),
        })
    return records


def format_bench_table(records: list[dict]) -> str:
    head = ("mesh", "faces", "views/s/core", "ms/view", "render256", "render64", "lines", "raster", "augment",
            "prep/shape", "line share", "vis faces")
    rows = [head]
    for r in records:
        rows.append((r["mesh"], str(r["faces"]), f"{r['views_per_s_per_core']:.2f}", f"{r['ms_per_view']:.0f}",
                     f"{r['ms_render256']:.0f}", f"{r['ms_render64']:.0f}", f"{r['ms_lines']:.1f}",
                     f"{r['ms_raster']:.1f}", f"{r['ms_augment']:.1f}", f"{r['ms_prepare_per_shape']:.0f}",
                     f"{100 * r['line_share']:.1f}%", str(r["visible_faces"])))
    widths = [max(len(row[i]) for row in rows) for i in range(len(head))]
    lines = ["  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(row, widths))) for row in rows]
    lines.insert(1, "-" * len(lines[0]))
    return "\n".join(lines)


def cmd_bench_data(args: argparse.Namespace) -> int:
    _require_torch()
    if args.json:
        check_output_file(args.json, "--json")
    records = bench_data_records(args.views, args.size, tuple(args.faces), args.augment_strength)
    print(format_bench_table(records))
    print("ms columns are per view on one core (torch threads = 1); 'lines' = contour/crease/suggestive extraction "
          "with hidden-line removal, 'raster' = stroke drawing, prep = per-shape topology + curvature (once per 24 views).")
    if args.json:
        from engine.fileio import atomic_write_text

        atomic_write_text(args.json, json.dumps(records, indent=1))
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    from sketchmesh.cli import main

    sys.exit(main(["data", *sys.argv[1:]]))
