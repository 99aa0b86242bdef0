"""``sketchmesh bench supports``: where a drawing's legs are lost, stage by stage.

Issue 16 asks for parts a person would name, and the legged furniture is where the bundle falls short: of the clean
drawings of standing test chairs, few give a mesh on the chair's own count of legs. The sphere can stand there (its
direct fit does: ``reproduce_models.sh ceiling-v57``), so the legs are lost in one of the two networks: in the
generator's normal image, which the predictor reads, or in the predictor's mesh. This benchmark follows them through.

For every view (of ``--split``, of the ``--categories``) of a shape that stands on two or more separate supports
(:func:`training.evaluation.metrics.support_count` of its voxels), it counts the supports seen in the drawing's own
view (:func:`training.evaluation.metrics.image_support_count`: separate pieces along the rows of the lowest quarter of
a silhouette) in

* ``true``: the shape's true silhouette (256 x 256), what the drawing shows;
* ``generator``: the generator's normal image of the clean drawing (its pixels off the background,
  :func:`engine.refine.generator_silhouette`), what the predictor reads (at 64 x 64, area-averaged);
* ``mesh``: the silhouette of the predictor's mesh made from that image (``--predictor``, one pass, no mirror
  averaging or routing, so each network is measured alone), rendered by the view's true framed camera, the camera the
  predictor's losses render it with in training (:mod:`engine.camera`);
* ``mesh_true_input``: the same for the mesh the predictor makes of the *true* normal image (the dataset's 64 x 64
  ``normals64``): what it would do with a perfect generator, a diagnostic the app cannot run;

and the supports the two meshes stand on in 3D (``support_count`` of their 32^3 voxels, in the world frame):
two or more, and as many as the shape. Per category it reports the share of views with two or more supports at each
stage, the share whose count equals the true silhouette's, and the 3D shares; ``supports.md``, ``supports.json``
(every view's counts too) and ``supports.png`` (the 2D shares as bars) in ``--out``.

Reading it: a stage that loses the legs its input shows is where the work is (a generator that paints a skirt under
legs the drawing shows, or a predictor that makes a skirt of legs its image shows).
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np

from engine.errors import SketchmeshError
from engine.fileio import atomic_write_bytes, atomic_write_text

STAGES = ("true", "generator", "mesh", "mesh_true_input")
"""The silhouettes counted, in the order the drawing goes through the networks (the last a diagnostic)."""

MESHES = ("mesh", "mesh_true_input")
"""The stages that are meshes, whose 3D supports are counted too."""

LEGGED = ("bench", "chair", "table")
"""The default categories: the legged furniture."""

VOXEL_RESOLUTION = 32


class SupportsBenchError(SketchmeshError):
    """The benchmark cannot run (no standing shape among the views asked for)."""


def run_supports_bench(
    data_dir: str | Path,
    *,
    models_dir: str | Path | None = None,
    predictor: str | None = None,
    categories: tuple[str, ...] = LEGGED,
    split: str = "test",
    max_samples: int = 0,
    threads: int = 2,
    progress: bool = True,
) -> dict:
    """Count the supports at every stage (module docstring) of the views of standing shapes.

    Args:
        data_dir: a dataset folder (``sketchmesh data``).
        models_dir: the model folder (default: the bundled models); its runtime generator
            (:func:`engine.models.load_runtime_generator`) draws the normal images.
        predictor: the predictor file of that folder (default ``mesh_predictor.onnx``), e.g. a specialist's.
        categories: the categories whose views are measured.
        split: the views' split.
        max_samples: at most this many views of standing shapes, spread evenly (0: all).
        threads: ONNX Runtime threads.

    Returns:
        ``{"rows": [one dict per view], "summary": {category: shares}, ...}``.
    """
    from tqdm import tqdm

    import engine.contract as C
    from engine.camera import Camera
    from engine.mesh import Mesh
    from engine.models import load_predictor, load_runtime_generator, resolve_models_dir
    from engine.pipeline import assemble_mesh, downsample_normals
    from engine.refine import generator_silhouette, pixel_coords, render_silhouette
    from training.data.dataset import ShapeViewDataset
    from training.evaluation.metrics import image_support_count, solid_voxels, support_count, world_vertices

    folder = resolve_models_dir(models_dir)
    name = predictor or C.PREDICTOR_FILE
    gen = load_runtime_generator(folder, threads)
    pred = load_predictor(folder / name, threads)
    data = ShapeViewDataset(Path(data_dir), split, extra_views=0, augment_strength=0.0)
    wanted = set(categories)
    candidates = [i for i in range(len(data)) if data.view_key(i)[0] in wanted]
    standing: dict[tuple[str, str], int] = {}  # each shape's supports in 3D, voxelised once
    for i in candidates:
        key = data.view_key(i)[:2]
        if key not in standing:
            standing[key] = support_count(solid_voxels(data.load_mesh(*key), VOXEL_RESOLUTION))
    views = [i for i in candidates if standing[data.view_key(i)[:2]] >= 2]
    if not views:
        raise SupportsBenchError(
            f"no view of the {split} split of {data_dir} in {', '.join(sorted(wanted))} shows a shape standing on two or "
            f"more separate supports ({len(candidates)} views of {len(standing)} shapes "
            "of those categories)")
    if max_samples and max_samples < len(views):
        views = [views[int(k)] for k in np.unique(np.linspace(0, len(views) - 1, max_samples).round().astype(int))]

    def mesh_of(small: np.ndarray) -> Mesh:
        local, glob = pred.session.run(pred.output_names, {pred.input_name: np.ascontiguousarray(small, np.float32)})
        return assemble_mesh(local, glob, pred.template_level, pred.template_radius)

    rows = []
    for i in tqdm(views, desc="supports", unit="view", disable=not progress):
        it = data[i]
        cat, sid = it["category"], it["shape_id"]
        cam16 = it["camera"].numpy().astype(np.float64)
        (normals,) = gen.session.run([C.GENERATOR_OUTPUT], {gen.input_name: it["sketch"].numpy()[None].astype(np.float32)})
        normals = np.clip(normals, 0.0, 1.0).astype(np.float32)
        true = it["silhouette"][0].numpy() > 0.5
        size = true.shape[0]
        camera = Camera(np.eye(3), cam16[9:12], float(cam16[12]), (float(cam16[13]), float(cam16[14])))
        row = {"category": cat, "shape_id": sid, "view": int(it["view"]), "shape_supports": standing[(cat, sid)],
               "true": image_support_count(true), "generator": image_support_count(generator_silhouette(normals))}
        for stage, small in (("mesh", downsample_normals(normals)), ("mesh_true_input", it["normals64"].numpy()[None])):
            mesh = mesh_of(small)
            px, _ = pixel_coords(mesh.vertices, camera, size)
            row[stage] = image_support_count(render_silhouette(px, mesh.faces, size)) if np.isfinite(px).all() else 0
            world = Mesh(world_vertices(np.asarray(mesh.vertices, np.float64), cam16), mesh.faces)
            row[f"{stage}_3d"] = support_count(solid_voxels(world, VOXEL_RESOLUTION))
        rows.append(row)
    return {"rows": rows, "summary": summarize(rows), "models": str(folder), "predictor": name, "split": split,
            "data": str(data_dir), "categories": sorted(wanted)}


def summarize(rows: list[dict]) -> dict:
    """Per category (and their mean, ``"mean"``): views; the share of views with two or more supports at each stage
    (``two_or_more``) and with the true silhouette's count (``as_true``); the meshes' 3D shares on two or more
    supports (``three_d_two_or_more``) and on as many as the shape (``three_d_own``)."""
    per: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        per[r["category"]].append(r)
    out = {}
    for cat, rs in sorted(per.items()):
        out[cat] = {
            "views": len(rs),
            "two_or_more": {s: float(np.mean([r[s] >= 2 for r in rs])) for s in STAGES},
            "as_true": {s: float(np.mean([r[s] == r["true"] for r in rs])) for s in STAGES[1:]},
            "three_d_two_or_more": {s: float(np.mean([r[f"{s}_3d"] >= 2 for r in rs])) for s in MESHES},
            "three_d_own": {s: float(np.mean([r[f"{s}_3d"] == r["shape_supports"] for r in rs])) for s in MESHES},
        }
    cats = list(out.values())
    if cats:
        out["mean"] = {"views": int(sum(c["views"] for c in cats)),
                       **{k: {s: float(np.mean([c[k][s] for c in cats])) for s in cats[0][k]}
                          for k in ("two_or_more", "as_true", "three_d_two_or_more", "three_d_own")}}
    return out


def markdown_table(summary: dict) -> str:
    """The shares per category: two or more supports seen at each stage, the count the drawing shows kept, and the
    meshes' 3D supports."""
    lines = ["| category | views | true silhouette: 2+ | generator's image: 2+ (as true) | mesh: 2+ (as true) | "
             "mesh of the true normal image (diagnostic): 2+ (as true) | mesh in 3D: 2+ / own count | "
             "mesh of the true normal image in 3D: 2+ / own count |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for cat, s in summary.items():
        two, same = s["two_or_more"], s["as_true"]
        lines.append(
            f"| {cat} | {s['views']} | {two['true']:.2f} | {two['generator']:.2f} ({same['generator']:.2f}) | "
            f"{two['mesh']:.2f} ({same['mesh']:.2f}) | {two['mesh_true_input']:.2f} ({same['mesh_true_input']:.2f}) | "
            f"{s['three_d_two_or_more']['mesh']:.2f} / {s['three_d_own']['mesh']:.2f} | "
            f"{s['three_d_two_or_more']['mesh_true_input']:.2f} / {s['three_d_own']['mesh_true_input']:.2f} |")
    return "\n".join(lines) + "\n"


def plot(summary: dict, path: str | Path) -> None:
    """Bars per category: the share of views showing two or more supports at each stage."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cats = list(summary)
    labels = {"true": "true silhouette", "generator": "generator's image", "mesh": "mesh",
              "mesh_true_input": "mesh of the true normal image (diagnostic)"}
    fig, ax = plt.subplots(figsize=(1.6 + 1.5 * len(cats), 3.6), dpi=110)
    width = 0.8 / len(STAGES)
    for k, stage in enumerate(STAGES):
        ax.bar(np.arange(len(cats)) + (k - (len(STAGES) - 1) / 2) * width,
               [summary[c]["two_or_more"][stage] for c in cats], width, label=labels[stage],
               hatch="//" if stage == "mesh_true_input" else None)
    ax.set_xticks(np.arange(len(cats)), [f"{c}\n({summary[c]['views']} views)" for c in cats])
    ax.set_ylabel("views showing 2+ supports")
    ax.set_ylim(0, 1)
    ax.set_title("Where the legs are lost: standing shapes, each drawing's own view", fontsize=10)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    atomic_write_bytes(Path(path), buf.getvalue())


def main_supports_bench(args: argparse.Namespace) -> int:
    result = run_supports_bench(args.data, models_dir=getattr(args, "models", None), predictor=args.predictor,
                                categories=tuple(args.categories), split=args.split, max_samples=args.max_samples,
                                threads=args.threads, progress=not args.quiet)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table = markdown_table(result["summary"])
    note = (f"{result['split']} split of {result['data']}, clean drawings; {result['predictor']} of {result['models']} "
            "(one pass, no routing or mirror averaging); 2D: separate pieces along the rows of the lowest quarter of each "
            "silhouette, the meshes seen by the view's true camera")
    atomic_write_text(out / "supports.md", table + f"\n{note}\n")
    atomic_write_text(out / "supports.json", json.dumps(result, indent=1))
    plot(result["summary"], out / "supports.png")
    print(table)
    print(note)
    print(f"wrote {out / 'supports.md'}, {out / 'supports.json'}, {out / 'supports.png'}")
    return 0


__all__ = ["LEGGED", "STAGES", "SupportsBenchError", "main_supports_bench", "markdown_table", "plot",
           "run_supports_bench", "summarize"]
