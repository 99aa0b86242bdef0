"""``sketchmesh gallery``: a picture of what the exported models do on test sketches.

One row per test shape (the first ``--per-category`` shapes of each category of the dataset's
test split, view ``--view``): the clean sketch, the generated normal image, the predicted mesh
rendered from the sketch's view, the same mesh from a second view ``--turn`` degrees of azimuth
away, and the ground-truth shape from that second view. The models run through
:class:`engine.pipeline.SketchEngine` (the app's path); meshes are drawn with the project's
rasterizer and Lambert-shaded from their normals.
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


def make_gallery(models_dir: str | Path, data_dir: str | Path, out: str | Path, *, per_category: int = 1,
                 categories: tuple[str, ...] = (), view: int = 3, turn: int = 6, size: int = 160,
                 threads: int = 2) -> Path:
    """Write the gallery PNG (see the module docstring); ``turn`` counts views of the dataset."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from engine.mesh import Mesh
    from engine.pipeline import SketchEngine
    from training.data.dataset import ShapeViewDataset
    from training.evaluation.evaluate import world_vertices

    test = ShapeViewDataset(Path(data_dir), "test", extra_views=0, augment_strength=0.0)
    chosen: dict[str, list[int]] = {}
    for i, (si, v) in enumerate(test._items):
        rec = test._shapes[si]
        if categories and rec["category"] not in categories:
            continue
        n_views = int(rec["num_views"])
        if v != view % n_views:
            continue
        if len(chosen.setdefault(rec["category"], [])) < per_category:
            chosen[rec["category"]].append(i)
    rows = [i for cat in sorted(chosen) for i in chosen[cat]]
    if not rows:
        raise GalleryError(f"no test shapes in {data_dir}" + (f" for categories {', '.join(categories)}" if categories else ""))
    engine = SketchEngine(models_dir, threads=threads, cache_size=0)
    cols = ("sketch", "generated normals", "mesh, sketch view", f"mesh, +{15 * turn} deg", f"ground truth, +{15 * turn} deg")
    fig, axes = plt.subplots(len(rows), len(cols), figsize=(2.0 * len(cols), 2.0 * len(rows)), dpi=100, squeeze=False)
    for r, i in enumerate(rows):
        item = test[i]
        si, v = test._items[i]
        rec = test._shapes[si]
        cams = test._cache.get(test._path(rec), "cameras")
        cam_in = Camera.from_array(cams[v])
        cam_2 = Camera.from_array(cams[(v + turn) % int(rec["num_views"])])
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
        for c, img in enumerate(images):
            ax = axes[r, c]
            ax.imshow(img, cmap="gray" if img.ndim == 2 else None, vmin=0, vmax=1, interpolation="antialiased")
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(cols[c], fontsize=9)
            if c == 0:
                ax.set_ylabel(rec["category"], fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    atomic_write_bytes(out, buf.getvalue())
    return Path(out)


def main_gallery(args: argparse.Namespace) -> int:
    from engine.models import resolve_models_dir

    models = resolve_models_dir(getattr(args, "models", None))
    path = make_gallery(models, args.data, args.output, per_category=args.per_category,
                        categories=tuple(args.categories or ()), view=args.view, turn=args.turn, size=args.size,
                        threads=args.threads)
    print(f"wrote {path}")
    return 0


__all__ = ["GalleryError", "main_gallery", "make_gallery", "shade"]
