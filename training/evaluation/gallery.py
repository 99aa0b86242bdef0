"""``sketchmesh gallery``: a picture of what the exported models do on test sketches.

One row per test shape (the first ``--per-category`` shapes of each category of the dataset's
test split), drawn from the view nearest ``--elevation`` and ``--azimuth`` (elevation first: a
dataset rendered at 0, 15, 30 and 45 degrees gives side views with ``--elevation 0``): the clean
sketch, the generated normal image, the predicted mesh rendered from the sketch's view, the same
mesh from a second view about ``--turn`` degrees of azimuth away at the same elevation (the
dataset's view nearest it; the column title gives the turn), and the ground-truth shape from
that second view. The models run through
:class:`engine.pipeline.SketchEngine` (the app's path); meshes are drawn with the project's
rasterizer and Lambert-shaded from their normals.

:func:`ceiling_sheet` draws another sheet: the models' mesh of a test drawing beside direct fits of the same shape
(``bench fit --procedural --meshes``, the predictor's ceiling) and the shape (``reproduce_models.sh ceiling-v57``).
"""

from __future__ import annotations

import argparse
import io
from pathlib import Path

import numpy as np

from engine.camera import Camera, decode_normals
from engine.errors import SketchmeshError
from engine.fileio import atomic_write_bytes

LIGHT = np.array([0.35, 0.5, 0.8]) / np.linalg.norm([0.35, 0.5, 0.8])
"""Direction towards the light in camera coordinates (up-right, towards the viewer)."""


class GalleryError(SketchmeshError):
    """The gallery cannot be made (empty split, no such category)."""


def shade(normals: np.ndarray, silhouette: np.ndarray) -> np.ndarray:
    """(S, S, 3) encoded normals -> (S, S) grey Lambert image in [0, 1], white background."""
    n = decode_normals(normals)
    lit = 0.25 + 0.75 * np.clip(n @ LIGHT, 0.0, 1.0)
    return np.where(silhouette > 0.5, lit, 1.0)


def _render(mesh, camera: Camera, size: int) -> np.ndarray:
    from training.render import render_normals_numpy

    out = render_normals_numpy(mesh, camera, size)
    return shade(out["normals"], out["silhouette"])


def _azimuth_gap(a, b):
    """Absolute circular difference of azimuths in degrees, in [0, 180]."""
    d = np.abs((np.asarray(a, np.float64) - np.asarray(b, np.float64)) % 360.0)
    return np.minimum(d, 360.0 - d)


def pick_views(azimuths, elevations, azimuth: float, elevation: float, turn: float) -> tuple[int, int]:
    """(sketch view, second view) of one shape: the view at the elevation nearest ``elevation`` whose
    azimuth is nearest ``azimuth``, and the view at that same elevation nearest ``azimuth + turn``
    (ties: the lower index). ``azimuths``/``elevations``: the shape's views, in degrees."""
    az, el = np.asarray(azimuths, np.float64), np.asarray(elevations, np.float64)
    level = el[np.argmin(np.abs(el - elevation))]
    same = np.flatnonzero(el == level)
    first = int(same[np.argmin(_azimuth_gap(az[same], azimuth))])
    second = int(same[np.argmin(_azimuth_gap(az[same], az[first] + turn))])
    return first, second


def make_gallery(models_dir: str | Path, data_dir: str | Path, out: str | Path, *, per_category: int = 1,
                 categories: tuple[str, ...] = (), azimuth: float = 45.0, elevation: float = 30.0,
                 turn: float = 90.0, size: int = 160, threads: int = 2, mirror_average: bool = False,
                 repair_folds: bool = False) -> Path:
    """Write the gallery PNG (see the module docstring); angles in degrees."""
    from engine.mesh import Mesh
    from engine.pipeline import SketchEngine
    from training.data.dataset import ShapeViewDataset
    from training.evaluation.evaluate import world_vertices

    test = ShapeViewDataset(Path(data_dir), "test", extra_views=0, augment_strength=0.0)
    angles: dict[tuple[str, str], dict[int, tuple[float, float]]] = {}
    for r in test.manifest["views"]:
        angles.setdefault((r["category"], r["shape_id"]), {})[int(r["view"])] = (float(r["azimuth"]), float(r["elevation"]))
    index = {item: i for i, item in enumerate(test._items)}
    chosen: dict[str, list[tuple[int, int]]] = {}
    for si, rec in enumerate(test._shapes):
        if categories and rec["category"] not in categories:
            continue
        if len(chosen.setdefault(rec["category"], [])) >= per_category:
            continue
        by_view = angles[(rec["category"], rec["shape_id"])]
        n = int(rec["num_views"])
        first, second = pick_views([by_view[v][0] for v in range(n)], [by_view[v][1] for v in range(n)],
                                   azimuth, elevation, turn)
        chosen[rec["category"]].append((index[(si, first)], second))
    rows = [row for cat in sorted(chosen) for row in chosen[cat]]
    if not rows:
        raise GalleryError(f"no test shapes in {data_dir}" + (f" for categories {', '.join(categories)}" if categories else ""))
    engine = SketchEngine(models_dir, threads=threads, cache_size=0, mirror_average=mirror_average,
                          repair_folds=repair_folds)
    grid, titles, labels = [], (), []
    for i, second in rows:
        item = test[i]
        si, v = test._items[i]
        rec = test._shapes[si]
        by_view = angles[(rec["category"], rec["shape_id"])]
        (az_1, el_1), (az_2, _) = by_view[v], by_view[second]
        gap = (az_2 - az_1) % 360.0
        cols = ("sketch", "generated normals", "mesh, sketch view", f"mesh, +{gap:g} deg", f"ground truth, +{gap:g} deg")
        cams = test._cache.get(test._path(rec), "cameras")
        cam_in = Camera.from_array(cams[v])
        cam_2 = Camera.from_array(cams[second])
        sketch = item["sketch"][0].numpy()
        pred = engine.predict(sketch, want_normals=True)
        gt = test.load_mesh(rec["category"], rec["shape_id"])
        world = Mesh(world_vertices(np.asarray(pred.mesh.vertices, np.float64), cams[v]), pred.mesh.faces)
        images = (
            1.0 - sketch,
            pred.normals,
            _render(world, cam_in, size),
            _render(world, cam_2, size),
            _render(gt, cam_2, size),
        )
        grid.append(images)
        titles = titles or cols
        labels.append(f"{rec['category']}\naz {az_1:g}, el {el_1:g}")
    return _write_grid(out, grid, list(titles), labels, inches=2.0, fontsize=9)


def _write_grid(out: str | Path, grid: list, titles: list[str], labels: list[str], *, inches: float,
                fontsize: int) -> Path:
    """A PNG of images in rows (grey when 2-D), ``titles`` over the first row's columns, ``labels`` beside each row,
    ``inches`` a cell at 100 dpi; written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(grid), len(titles), figsize=(inches * len(titles), inches * len(grid)), dpi=100,
                             squeeze=False)
    for r, images in enumerate(grid):
        for c, img in enumerate(images):
            ax = axes[r, c]
            ax.imshow(img, cmap="gray" if img.ndim == 2 else None, vmin=0, vmax=1, interpolation="antialiased")
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(titles[c], fontsize=fontsize)
            if c == 0:
                ax.set_ylabel(labels[r], fontsize=fontsize)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    atomic_write_bytes(out, buf.getvalue())
    return Path(out)


def _framed_render(mesh, azimuth: float, elevation: float, size: int) -> np.ndarray:
    """``mesh`` seen from (azimuth, elevation), framed on itself as the data's views are framed on their shape."""
    from engine.camera import frame_camera, look_at

    return _render(mesh, frame_camera(look_at(azimuth, elevation), np.asarray(mesh.vertices)), size)


def ceiling_images(models_dir: str | Path, data_dir: str | Path, fit_dirs: dict[str, str | Path],
                   shape_ids: list[str], *, azimuth: float = 45.0, elevation: float = 30.0, turn: float = 90.0,
                   size: int = 128, threads: int = 2, mirror_average: bool = True) -> list[dict]:
    """The rows of :func:`ceiling_sheet`: for each shape ``shape_id``, ``azimuth`` / ``elevation`` of its drawing and
    ``images`` {column title: (S, S) image in [0, 1]}."""
    import trimesh

    from engine.mesh import Mesh
    from engine.pipeline import SketchEngine
    from training.data.dataset import ShapeViewDataset
    from training.evaluation.evaluate import world_vertices

    test = ShapeViewDataset(Path(data_dir), "test", extra_views=0, augment_strength=0.0)
    angles: dict[str, dict[int, tuple[float, float]]] = {}
    for r in test.manifest["views"]:
        angles.setdefault(r["shape_id"], {})[int(r["view"])] = (float(r["azimuth"]), float(r["elevation"]))
    index = {item: i for i, item in enumerate(test._items)}
    shapes = {rec["shape_id"]: (si, rec) for si, rec in enumerate(test._shapes)}
    missing = [s for s in shape_ids if s not in shapes]
    if missing or not shape_ids:
        raise GalleryError(f"no test shapes {', '.join(missing) or '(none given)'} in {data_dir}")
    clash = [label for label in fit_dirs if label in ("drawing", "models' mesh", "true shape")]
    if clash:
        raise GalleryError(f"a fit's label cannot be a column of its own: {', '.join(clash)}")
    for label, folder in fit_dirs.items():
        absent = [s for s in shape_ids if not (Path(folder) / f"{s}.obj").is_file()]
        if absent:
            raise GalleryError(f"{label}: no fitted mesh {', '.join(absent)} in {folder}")
    engine = SketchEngine(models_dir, threads=threads, cache_size=0, mirror_average=mirror_average)
    rows = []
    for sid in shape_ids:
        si, rec = shapes[sid]
        by_view = angles[sid]
        n = int(rec["num_views"])
        v, _ = pick_views([by_view[k][0] for k in range(n)], [by_view[k][1] for k in range(n)], azimuth, elevation, turn)
        az, el = by_view[v]
        cams = test._cache.get(test._path(rec), "cameras")
        sketch = test[index[(si, v)]]["sketch"][0].numpy()
        pred = engine.predict(sketch)
        world = Mesh(world_vertices(np.asarray(pred.mesh.vertices, np.float64), cams[v]), pred.mesh.faces)
        images = {"drawing": 1.0 - sketch, "models' mesh": _framed_render(world, az + turn, el, size)}
        for label, folder in fit_dirs.items():
            tm = trimesh.load(Path(folder) / f"{sid}.obj", force="mesh", process=False)
            images[label] = _framed_render(Mesh(tm.vertices, tm.faces), az + turn, el, size)
        images["true shape"] = _framed_render(test.load_mesh(rec["category"], sid), az + turn, el, size)
        rows.append({"shape_id": sid, "azimuth": az, "elevation": el, "images": images})
    return rows


def ceiling_sheet(models_dir: str | Path, data_dir: str | Path, fit_dirs: dict[str, str | Path],
                  shape_ids: list[str], out: str | Path, **kw) -> Path:
    """The models' mesh of a drawing beside the direct fits of the same shape (the ceiling) and the shape.

    One row a test shape of ``data_dir`` named in ``shape_ids``: its drawing from the view nearest (``azimuth``,
    ``elevation``), the mesh ``models_dir`` makes of it (the app's engine, mirror averaged unless
    ``mirror_average=False``), each fit of ``fit_dirs`` (label -> folder of ``bench fit --procedural --meshes``
    OBJs, ``SHAPE_ID.obj``) and the true shape, all from ``turn`` degrees of azimuth further round at the drawing's
    elevation, each framed on itself (keywords: :func:`ceiling_images`). Writes the PNG atomically.
    """
    rows = ceiling_images(models_dir, data_dir, fit_dirs, shape_ids, **kw)
    titles = list(rows[0]["images"])
    return _write_grid(out, [[row["images"][t] for t in titles] for row in rows], titles,
                       [f"{row['shape_id']}\naz {row['azimuth']:g}, el {row['elevation']:g}" for row in rows],
                       inches=1.8, fontsize=8)


def main_gallery(args: argparse.Namespace) -> int:
    from engine.models import resolve_models_dir

    models = resolve_models_dir(getattr(args, "models", None))
    path = make_gallery(models, args.data, args.output, per_category=args.per_category,
                        categories=tuple(args.categories or ()), azimuth=args.azimuth, elevation=args.elevation,
                        turn=args.turn, size=args.size, threads=args.threads, mirror_average=args.mirror_average,
                        repair_folds=args.repair_folds)
    print(f"wrote {path}")
    return 0


__all__ = ["GalleryError", "ceiling_images", "ceiling_sheet", "main_gallery", "make_gallery", "pick_views", "shade"]
