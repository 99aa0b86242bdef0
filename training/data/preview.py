"""Contact sheet of a dataset: rows of sketch | normal image | silhouette with category labels."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from engine.fileio import atomic_write_bytes
from training.data.dataset import DatasetError, ShapeFileCache, load_manifest

LABEL_HEIGHT = 18
TILE = 160


def contact_sheet(root: str | os.PathLike, rows: int = 8, views_per_shape: int = 2, augment_strength: float = 0.0,
                  seed: int = 0, tile: int = TILE) -> np.ndarray:
    """Compose the sheet: (H, W, 3) uint8 BGR image.

    Shapes are picked evenly over the categories (round-robin, first shapes first); each shape
    shows ``views_per_shape`` evenly spaced views, each as a triplet sketch | normals |
    silhouette (dark strokes on white, normals as RGB, silhouette white on black), with a
    label "category/shape_id view k (split)". With ``augment_strength > 0`` the sketch is the
    load-time augmentation the trainer would see.
    """
    import cv2

    manifest = load_manifest(root)
    shapes = manifest["shapes"]
    if not shapes:
        raise DatasetError(f"{root}: the dataset has no shapes")
    by_cat: dict[str, list] = {}
    for s in shapes:
        by_cat.setdefault(s["category"], []).append(s)
    picked = []
    depth = 0
    while len(picked) < rows and any(depth < len(v) for v in by_cat.values()):
        for cat in sorted(by_cat):
            if depth < len(by_cat[cat]) and len(picked) < rows:
                picked.append(by_cat[cat][depth])
        depth += 1
    cache = ShapeFileCache(capacity=2)
    row_imgs = []
    for rec in picked:
        path = str(Path(root) / rec["file"])
        n = int(rec["num_views"])
        views = np.linspace(0, n, views_per_shape, endpoint=False).astype(int)
        cells = []
        for v in views:
            if augment_strength > 0:
                from training.data.augment import render_sketch
                from training.data.render import view_polylines

                arrays = {k: cache.get(path, k) for k in ("view_poly_offsets", "poly_offsets", "poly_points")}
                size = cache.get(path, "sketch").shape[-1]
                sk = np.round(render_sketch(view_polylines(arrays, v), size, augment_strength, [seed, v]) * 255).astype(np.uint8)
            else:
                sk = cache.get(path, "sketch")[v]
            sketch = cv2.cvtColor(255 - sk, cv2.COLOR_GRAY2BGR)
            normals = cache.get(path, "normals256")[v][..., ::-1]
            sil = cv2.cvtColor(cache.get(path, "silhouette256")[v].astype(np.uint8) * 255, cv2.COLOR_GRAY2BGR)
            trip = [cv2.resize(np.ascontiguousarray(x), (tile, tile), interpolation=cv2.INTER_AREA) for x in (sketch, normals, sil)]
            cell = np.concatenate(trip, axis=1)
            label = np.full((LABEL_HEIGHT, cell.shape[1], 3), 235, np.uint8)
            cv2.putText(label, f"{rec['category']}/{rec['shape_id']} view {v} ({rec['split']})", (4, LABEL_HEIGHT - 5),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
            cell = np.concatenate([label, cell], axis=0)
            cells.append(np.pad(cell, ((2, 2), (2, 2), (0, 0)), constant_values=128))
        row_imgs.append(np.concatenate(cells, axis=1))
    width = max(r.shape[1] for r in row_imgs)
    row_imgs = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)), constant_values=128) for r in row_imgs]
    return np.concatenate(row_imgs, axis=0)


def write_contact_sheet(root: str | os.PathLike, out: str | os.PathLike, **kwargs) -> tuple[int, int]:
    """Write :func:`contact_sheet` as a PNG (atomically); returns (height, width)."""
    import cv2

    img = contact_sheet(root, **kwargs)
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise DatasetError(f"cannot encode the contact sheet for {out}")
    atomic_write_bytes(out, buf.tobytes())
    return img.shape[0], img.shape[1]


def write_samples(root: str | os.PathLike, out: str | os.PathLike, *, split: str = "test", per_category: int = 1,
                  view: int = 3, augment_strength: float = 0.0, seed: int = 0) -> list[Path]:
    """Export sketches of a dataset split as PNG files a user can open (dark strokes on white).

    Files are named ``<category>_<shape_id>_v<view>.png``; the first ``per_category`` shapes of
    each category in ``split`` are taken, view ``view`` of each (modulo its view count).
    """
    import cv2

    from training.data.lines import sketch_to_file_image

    manifest = load_manifest(root)
    chosen: dict[str, list] = {}
    for s in manifest["shapes"]:
        if s["split"] == split and len(chosen.setdefault(s["category"], [])) < per_category:
            chosen[s["category"]].append(s)
    if not any(chosen.values()):
        raise DatasetError(f"{root}: no shapes in the {split!r} split")
    cache = ShapeFileCache(capacity=2)
    written = []
    for cat in sorted(chosen):
        for rec in chosen[cat]:
            path = str(Path(root) / rec["file"])
            v = view % int(rec["num_views"])
            if augment_strength > 0:
                from training.data.augment import render_sketch
                from training.data.render import view_polylines

                arrays = {k: cache.get(path, k) for k in ("view_poly_offsets", "poly_offsets", "poly_points")}
                size = cache.get(path, "sketch").shape[-1]
                ink = render_sketch(view_polylines(arrays, v), size, augment_strength, [seed, v])
            else:
                ink = cache.get(path, "sketch")[v].astype(np.float64) / 255.0
            ok, buf = cv2.imencode(".png", sketch_to_file_image(ink))
            if not ok:
                raise DatasetError(f"could not encode the sketch of {rec['shape_id']}")
            target = Path(out) / f"{rec['category']}_{rec['shape_id']}_v{v}.png"
            atomic_write_bytes(target, buf.tobytes())
            written.append(target)
    return written
