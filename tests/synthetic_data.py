"""A tiny synthetic dataset for the training tests, in the real on-disk format (docs/DATA_FORMAT.md).

``sketchmesh data`` renders feature lines of procedural shapes at several seconds per shape;
the training tests only need the plumbing, so :func:`write_synthetic_dataset` writes a few
simple closed meshes (ellipsoids, boxes, cylinders with per-shape proportions) rendered by the
project's rasterizer (:func:`training.render.render_normals_numpy`) at 64x64 from a few
paper-style framed views (the 256x256 images are that render upsampled 4x, nearest), with the *same* files and manifest as ``sketchmesh data``
(:func:`training.data.dataset.write_shape_file` / :func:`training.data.dataset.write_manifest`),
so :class:`training.data.dataset.ShapeViewDataset` reads it unchanged. The sketch is the
thresholded Sobel magnitude of the normal image (silhouette and crease lines, 255 = ink) instead
of the feature-line drawing; no polylines are stored, so only ``augment_strength = 0`` loads.

Also runnable as a DDP driver for tests/test_training_ddp.py::

    torchrun --nproc_per_node 2 tests/synthetic_data.py ddp DATA_DIR OUT_DIR
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

CATEGORIES = ("blob", "box", "can", "table")
SKETCH_EDGE_THRESHOLD = 0.6
"""Sobel magnitude (of the [0, 1] normal image) above which a pixel is ink."""


def make_mesh(category: str, index: int):
    """A normalised closed mesh of a synthetic category; ``index`` varies the proportions."""
    import trimesh

    from engine.camera import normalize_vertices
    from engine.icosphere import icosphere
    from engine.mesh import Mesh

    s = 1.0 + 0.25 * index
    if category == "blob":
        m = icosphere(3)
        return Mesh(normalize_vertices(np.array(m.vertices) * np.array([1.0, 0.7 * s, 0.5])), m.faces)
    if category == "box":
        m = trimesh.creation.box(extents=(1.0, 0.6 * s, 0.4)).subdivide().subdivide()
    elif category == "can":
        m = trimesh.creation.cylinder(radius=0.3 * s, height=1.0, sections=24)
    elif category == "table":  # a top on four legs at its corners: a shape that stands on separate supports
        top = trimesh.creation.box(extents=(1.0, 0.08, 0.6 * s)).apply_translation((0.0, 0.3, 0.0))
        legs = [trimesh.creation.box(extents=(0.08, 0.6, 0.08)).apply_translation((x, 0.0, z))
                for x in (-0.44, 0.44) for z in (-0.26 * s, 0.26 * s)]
        m = trimesh.util.concatenate([top, *legs])
    else:
        raise ValueError(f"unknown synthetic category {category!r}; expected one of {CATEGORIES}")
    return Mesh(normalize_vertices(m.vertices), m.faces)


def render_shape_arrays(mesh, views: int, size: int = 256, small_size: int = 64) -> dict:
    """The arrays of one shape file (keys of training.data.dataset.SHAPE_KEYS except ``meta``)."""
    import torch

    from engine.camera import frame_camera, paper_views
    from training.model.networks import sobel_magnitude
    from training.render import render_normals_numpy

    out = {k: [] for k in ("sketch", "normals256", "silhouette256", "normals64", "silhouette64", "cameras")}
    cams = paper_views(views)
    for _, _, cam in cams:
        cam = frame_camera(cam, np.array(mesh.vertices))
        small = render_normals_numpy(mesh, cam, small_size)
        k = size // small_size  # the 256 images are the 64 render upsampled (a 256 render costs ~1 s)
        big = {key: np.repeat(np.repeat(small[key], k, axis=0), k, axis=1) for key in ("normals", "silhouette")}
        mag = sobel_magnitude(torch.from_numpy(big["normals"].transpose(2, 0, 1).copy())[None])[0].numpy()
        out["sketch"].append(np.where(mag > SKETCH_EDGE_THRESHOLD, 255, 0).astype(np.uint8))
        out["normals256"].append(np.round(np.clip(big["normals"], 0, 1) * 255).astype(np.uint8))
        out["silhouette256"].append(big["silhouette"].astype(bool))
        out["normals64"].append(small["normals"].astype(np.float32))
        out["silhouette64"].append(small["silhouette"].astype(bool))
        out["cameras"].append(cam.to_array())
    arrays = {k: np.stack(v) for k, v in out.items()}
    arrays["azimuths"] = np.array([a for a, _, _ in cams], np.float64)
    arrays["elevations"] = np.array([e for _, e, _ in cams], np.float64)
    arrays["poly_points"] = np.zeros((0, 2), np.float32)
    arrays["poly_offsets"] = np.zeros(1, np.int64)
    arrays["poly_kinds"] = np.zeros(0, np.int8)
    arrays["view_poly_offsets"] = np.zeros(views + 1, np.int64)
    arrays["vertices"] = np.asarray(mesh.vertices, np.float32)
    arrays["faces"] = np.asarray(mesh.faces, np.int64)
    return arrays


def write_synthetic_dataset(
    root: str | Path,
    categories=("blob", "box"),
    splits=("train", "train", "val", "test"),
    views: int = 4,
) -> Path:
    """Write ``len(categories) * len(splits)`` shapes (shape i of a category goes to ``splits[i]``).

    Returns:
        The dataset folder (``manifest.json`` + ``shapes/<category>/<id>.npz``).
    """
    from training.data.dataset import BuildSettings, shape_file, write_manifest, write_shape_file

    root = Path(root)
    settings = BuildSettings(num_azimuths=views)
    for cat in categories:
        for i, split in enumerate(splits):
            sid = f"{cat}_{i:05d}"
            arrays = render_shape_arrays(make_mesh(cat, i), views)
            meta = {"category": cat, "shape_id": sid, "split": split, "source": "synthetic", "path": "",
                    "index": i, "settings": json.loads(settings.to_json())}
            arrays["meta"] = np.array(json.dumps(meta, sort_keys=True))
            write_shape_file(shape_file(root, cat, sid), arrays)
    write_manifest(root, settings)
    return root


def train_tiny_joint_run(data_dir, out_dir, iters: int = 1, **overrides) -> Path:
    """A joint run of tiny networks (generator width 8, a level-2 template) trained ``iters`` iterations on the CPU
    into ``out_dir``: a run with both networks for tests that export, import or evaluate one."""
    from training.loop.config import TrainConfig
    from training.loop.trainer import Trainer

    cfg = TrainConfig(**{**dict(mode="joint", data_dir=str(data_dir), out_dir=str(out_dir), iters=iters, batch=2,
                                base_channels=8, predictor_channels=8, predictor_hidden=32, predictor_latent=16,
                                template_level=2, sobel_samples=64, augment_strength=0.0, log_every=1, val_every=0,
                                ckpt_every=0, plot_every=0, device="cpu", extra_views=1), **overrides})
    Trainer(cfg, progress=False).run()
    return Path(out_dir)


def _ddp_main(data_dir: str, out_dir: str) -> None:
    """Train a tiny mesh run under torchrun and dump this rank's parameter checksum and first batch."""
    import hashlib

    import torch

    torch.set_num_threads(1)
    from training.loop.config import TrainConfig
    from training.loop.trainer import ResumableBatchSampler, dist_info_from_env, train

    info = dist_info_from_env()
    cfg = TrainConfig(mode="joint", data_dir=data_dir, out_dir=str(Path(out_dir) / "run"), iters=3, batch=2,
                      base_channels=8, predictor_channels=8, predictor_hidden=32, predictor_latent=16,
                      template_level=2, sobel_samples=64, augment_strength=0.0, log_every=1, val_every=0,
                      ckpt_every=0, plot_every=0, device="cpu", extra_views=1)
    import training.loop.trainer as tr

    captured = {}
    original = tr.Trainer.run

    def run(self):
        result = original(self)
        captured["models"] = self.models
        captured["n"] = len(self.train_set)
        return result

    tr.Trainer.run = run
    train(cfg, progress=False)
    sampler = ResumableBatchSampler(captured["n"], cfg.batch, cfg.seed, 0, info)
    first = next(iter(sampler))
    digest = hashlib.sha256()
    total = 0.0
    for _, model in sorted(captured["models"].items()):
        for p in model.parameters():
            digest.update(p.detach().cpu().numpy().tobytes())
            total += float(p.detach().double().sum())
    Path(out_dir, f"rank{info.rank}.json").write_text(json.dumps(
        {"rank": info.rank, "world_size": info.world_size, "sha256": digest.hexdigest(), "sum": total,
         "first_batch": first}))


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "ddp":
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        _ddp_main(sys.argv[2], sys.argv[3])
    else:
        print(__doc__)
        sys.exit(2)
