"""``sketchmesh eval``: 3D and 2D accuracy of a trained run on the test split, with baselines.

For every test sample (a sketch of one view of one shape) the run predicts a mesh: sketch ->
generator -> normal image -> area-downsampled to 64x64 -> mesh predictor (or the predictor on the
ground-truth normal image with ``--gt-normals``). The prediction is in the input view's frame
(:mod:`engine.camera`), so it is rotated back to the world with ``R_in.T`` and compared with the
normalised ground-truth mesh:

* ``voxel_iou`` -- IoU of solid 32^3 voxelisations (the paper's Table 1 metric), higher is better;
* ``chamfer_l1`` -- Occupancy-Networks Chamfer-L1, lower is better;
* ``normal_consistency`` -- in [0, 1], higher is better;
* ``silhouette_iou`` -- IoU of the predicted mesh's silhouette rendered from the input view at 64x64
  against the ground-truth silhouette.

Metrics are averaged per category, and ``mean`` is the mean over categories (as in the paper).

Baselines in the same table:

* ``retrieval`` -- the nearest *training* sample by L1 distance between 64x64 normal images (the
  query's normal image: generated, or ground truth with ``--gt-normals``); its mesh is rotated into
  the query's view frame with the two views' rotations (``R_r`` then ``R_q.T`` back to the world:
  the retrieved shape is placed as it looked in its own view).
* any ``--baseline-run RUN`` (e.g. a silhouette-only run trained with ``lambda_n = 0``): evaluated
  the same way; a baseline without a generator borrows the main run's generator.
* with ``--mirror-average``, every run also as ``NAME +mirror``: each prediction averaged with the one
  made from the drawing flipped left to right, mirrored back (the engine's ``mirror_average``;
  :func:`engine.icosphere.mirror_average`), at twice the networks' cost.

``--sketch-path`` says how a test sketch reaches the generator:

* ``stored`` (the default, the measure of every earlier table): the dataset's raster as it is; an
  augmented one (``--augment-strength``) keeps grey, thinner or thicker strokes and an unframed
  shift and scale, which no input of the app reaches the generator with;
* ``image``: the engine's image-file path (:func:`engine.preprocess.preprocess_raster`: binarised at
  the ink threshold, reframed on its centre lines, thinned and redrawn at the standard width in full
  ink), as the app treats a scanned or photographed drawing;
* ``canvas``: the drawing's strokes (the hand-drawn ones with ``--augment-strength``) drawn by
  :func:`engine.preprocess.rasterize_strokes`, framed on their points at the standard width in full
  ink, as the app's canvas feeds the generator a drawing made with the pen.

``--mesh-scale S`` (a calibration probe, 1 by default) scales every run's predicted mesh about the centre of its
bounding box by S before it is scored (:func:`scale_about_box_centre`): does a systematic size error cost voxel IoU?

Outputs: a markdown table (printed and written to ``OUT/eval_<split>.md``), JSON (``--json PATH``
and ``OUT/eval_<split>.json``) and a bar chart ``OUT/eval_<split>.png``. Every method's row carries its
cost (milliseconds of network inference per sample on this machine).
"""

from __future__ import annotations

import argparse
import io
import json
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import torch

from engine.errors import SketchmeshError
from engine.fileio import atomic_write_bytes
from engine.icosphere import mirror_average
from engine.mesh import Mesh
from engine.preprocess import preprocess_raster
from training.data.mirror import mirror_normal_image
from training.evaluation.metrics import ELEVATION_TOL, category_mean_se, world_vertices
from training.evaluation.models_eval import SKETCH_PATHS, canvas_raster
from training.loop.config import TrainConfig
from training.model.networks import downsample_normals, view_frame_cameras

METRICS = ("voxel_iou", "chamfer_l1", "normal_consistency", "silhouette_iou")
HIGHER_IS_BETTER = {"voxel_iou": True, "chamfer_l1": False, "normal_consistency": True, "silhouette_iou": True}
SURFACE_POINTS = 2000
"""Surface samples per mesh for Chamfer-L1 and normal consistency (Occupancy Networks use 100k;
2k keeps evaluation at a few ms per sample with a standard error of about 1 % of the value)."""
EVAL_BATCH = 8
RETRIEVAL_CHUNK = 256


class EvaluationError(SketchmeshError):
    """Evaluation cannot run (empty split, run without the needed networks)."""


class _Method:
    """A way of predicting view-frame meshes from a batch (the run, a baseline run, retrieval)."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.seconds = 0.0
        self.count = 0


class _RunMethod(_Method):
    """A run's networks; with ``mirror`` each prediction is averaged with the one from the mirrored input
    (:func:`engine.icosphere.mirror_average`, the engine's ``mirror_average``)."""

    def __init__(self, name: str, generator, predictor, cfg: TrainConfig, gt_normals: bool, mirror: bool = False,
                 plain: _RunMethod | None = None) -> None:
        super().__init__(name)
        self.generator, self.predictor, self.cfg, self.gt_normals = generator, predictor, cfg, gt_normals
        self.mirror = mirror
        self.plain = plain  # with mirror: the same run's plain method, whose pass on the same batch is reused
        self._last: tuple[int, np.ndarray, float] | None = None  # (id of the batch, its vertices, seconds)

    @torch.no_grad()
    def normals64(self, batch: dict, flip: bool = False) -> torch.Tensor:
        if self.gt_normals:
            n = batch["normals64"].float()
            # a true normal image mirrored exactly, its silhouette as coverage (training.data.mirror)
            return mirror_normal_image(n, batch["silhouette64"].float()) if flip else n
        sketch = batch["sketch"].float()
        return downsample_normals(self.generator(sketch.flip(-1) if flip else sketch), self.predictor.input_size)

    @torch.no_grad()
    def _vertices(self, batch: dict, flip: bool) -> np.ndarray:
        local, glob = self.predictor(self.normals64(batch, flip))
        return self.predictor.vertices(local, glob).numpy().astype(np.float64)

    @torch.no_grad()
    def predict(self, batch: dict) -> tuple[np.ndarray, np.ndarray | None]:
        t0 = time.perf_counter()
        last = self.plain._last if self.plain is not None else None
        reused = 0.0
        if last is not None and last[0] == id(batch):
            verts, reused = last[1], last[2]  # counted in this method's cost too: it is what the app runs twice
        else:
            verts = self._vertices(batch, False)
        if self.mirror:
            verts = mirror_average(verts, self._vertices(batch, True))
        seconds = time.perf_counter() - t0
        self._last = (id(batch), verts, seconds)
        self.seconds += seconds + reused
        self.count += verts.shape[0]
        return verts, None


class _RetrievalMethod(_Method):
    """Nearest training sample by 64x64 normal-image L1 distance."""

    def __init__(self, train_set, query: _RunMethod | None, progress: bool) -> None:
        super().__init__("retrieval")
        from tqdm import tqdm

        self.train_set = train_set
        self.query = query
        n = len(train_set)
        if n == 0:
            raise EvaluationError("the retrieval baseline needs a non-empty train split")
        images, cams, keys = [], [], []
        # in batches: a mesh-fields dataset gathers each batch from its array cache at once
        get = getattr(train_set, "__getitems__", None) or (lambda idx: [train_set[i] for i in idx])
        with tqdm(total=n, desc="retrieval index", disable=not progress, unit="img") as bar:
            for s in range(0, n, RETRIEVAL_CHUNK):
                for item in get(list(range(s, min(s + RETRIEVAL_CHUNK, n)))):
                    images.append(torch.as_tensor(np.asarray(item["normals64"]), dtype=torch.float16))
                    cams.append(np.asarray(item["camera"], dtype=np.float64))
                    keys.append((item["category"], item["shape_id"]))
                bar.update(min(RETRIEVAL_CHUNK, n - s))
        self.images = torch.stack(images).reshape(n, -1)  # (N, 3 * 64 * 64) float16
        self.cameras = np.stack(cams)
        self.keys = keys

    @torch.no_grad()
    def predict(self, batch: dict) -> tuple[np.ndarray, list]:
        t0 = time.perf_counter()
        q = (self.query.normals64(batch) if self.query is not None else batch["normals64"].float()).reshape(
            batch["normals64"].shape[0], -1)
        best_d = torch.full((q.shape[0],), float("inf"))
        best_i = torch.zeros(q.shape[0], dtype=torch.int64)
        for s in range(0, self.images.shape[0], RETRIEVAL_CHUNK):
            chunk = self.images[s:s + RETRIEVAL_CHUNK].float()
            d = torch.cdist(q, chunk, p=1.0)  # (B, chunk)
            dmin, imin = d.min(dim=1)
            better = dmin < best_d
            best_d = torch.where(better, dmin, best_d)
            best_i = torch.where(better, imin + s, best_i)
        self.seconds += time.perf_counter() - t0
        self.count += q.shape[0]
        return None, [(self.keys[i], self.cameras[i]) for i in best_i.tolist()]


def _load_models(run: str | Path, need_generator: bool, fallback_generator=None):
    from training.loop.trainer import load_run

    cfg, models, _ = load_run(run)
    if "predictor" not in models:
        raise EvaluationError(f"run {run} has no mesh predictor (train 'mesh' or 'joint' first)")
    gen = models.get("generator", fallback_generator)
    if need_generator and gen is None:
        raise EvaluationError(f"run {run} has no generator: pass --generator-run RUN, or --gt-normals")
    return cfg, gen, models["predictor"]


def _silhouettes(view_vertices: np.ndarray, faces: np.ndarray, cameras: np.ndarray, size: int) -> np.ndarray:
    """(B, size, size) bool silhouettes of view-frame meshes from their input views."""
    from training.render import rasterize

    v = torch.from_numpy(np.ascontiguousarray(view_vertices, dtype=np.float64))
    cams = view_frame_cameras(torch.from_numpy(np.asarray(cameras, dtype=np.float64)))[:, 0]
    with torch.no_grad():
        out = rasterize(v, torch.from_numpy(np.array(faces, dtype=np.int64)), cams, size)
    return out.silhouette.numpy() > 0.5


def scale_about_box_centre(vertices: np.ndarray, scale: float) -> np.ndarray:
    """(..., V, 3) vertices scaled by ``scale`` about the centre of each mesh's axis-aligned bounding box."""
    v = np.asarray(vertices, np.float64)
    centre = (v.min(axis=-2, keepdims=True) + v.max(axis=-2, keepdims=True)) / 2
    return centre + float(scale) * (v - centre)


def app_path_sketches(sketch_path: str, sketches: torch.Tensor | None, drawings: list | None = None,
                      names: list | None = None) -> torch.Tensor:
    """A batch of test sketches as one of the app's input paths feeds them to the generator (module doc).

    Args:
        sketch_path: "image" (each stored raster through :func:`engine.preprocess.preprocess_raster`)
            or "canvas" (each drawing's polylines through :func:`engine.preprocess.rasterize_strokes`).
        sketches: "image": (N, 1, 256, 256) the stored rasters ("canvas" does not read them; may be None).
        drawings: "canvas": N lists of (K, 2) pixel polylines (:meth:`ShapeViewDataset.view_strokes`).
        names: N (category, shape id, view) naming the sketches in errors.

    Raises:
        EvaluationError: a sketch the engine refuses (no ink above its threshold, no strokes), named.
    """
    from engine.contract import SKETCH_SIZE
    from engine.errors import EmptySketchError, SketchInputError

    if sketch_path not in ("image", "canvas"):
        raise ValueError(f"app_path_sketches takes the image or canvas path, got {sketch_path!r}")
    if sketch_path == "canvas":
        if drawings is None:
            raise ValueError("the canvas path needs one drawing (its polylines) per sketch")
        a = None
        n = len(drawings)
    else:
        a = sketches.detach().cpu().float().numpy()
        if a.ndim != 4 or a.shape[1] != 1:
            raise ValueError(f"app_path_sketches takes (N, 1, H, W) sketches, got {tuple(a.shape)}")
        n = len(a)
    out = np.empty((n, 1, SKETCH_SIZE, SKETCH_SIZE), np.float32)
    for i in range(n):
        try:
            out[i, 0] = preprocess_raster(a[i, 0]) if sketch_path == "image" else canvas_raster(drawings[i])
        except (EmptySketchError, SketchInputError) as e:
            who = f" {names[i]}" if names is not None else ""
            raise EvaluationError(f"sketch{who}: the engine refuses it ({e})") from e
    return torch.from_numpy(out)


def _pair_metrics(pred: Mesh, gt: Mesh, gt_voxels: np.ndarray, resolution: int, surface: bool = True) -> dict[str, float]:
    from training.evaluation.metrics import solid_voxels, surface_metrics

    pv = solid_voxels(pred, resolution, surface)
    union = int(np.count_nonzero(pv | gt_voxels))
    iou = 1.0 if union == 0 else int(np.count_nonzero(pv & gt_voxels)) / union
    try:
        surf = surface_metrics(pred, gt, SURFACE_POINTS)
        cd, nc = surf["chamfer_l1"], surf["normal_consistency"]
    except ValueError:  # a collapsed prediction with zero area: worst scores, not a crash
        cd, nc = float("nan"), 0.0
    return {"voxel_iou": iou, "chamfer_l1": cd, "normal_consistency": nc}


def _summarise(records: list[dict]) -> dict:
    per_cat: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for r in records:
        for m in METRICS:
            per_cat[r["category"]][m].append(r[m])
    per_category = {c: {m: float(np.nanmean(v[m])) if np.isfinite(v[m]).any() else float("nan") for m in METRICS}
                    | {"samples": len(v[METRICS[0]])} for c, v in sorted(per_cat.items())}
    mean = {m: float(np.nanmean([per_category[c][m] for c in per_category])) for m in METRICS}
    mean["samples"] = len(records)
    if records:
        mean["voxel_iou_se"] = category_mean_se([r["voxel_iou"] for r in records], [r["category"] for r in records],
                                                [r["shape_id"] for r in records])[1]
    return {"mean": mean, "per_category": per_category}


def _paired_difference(records: list[dict], first: list[dict]) -> dict[str, float]:
    """Voxel IoU of ``records`` minus ``first``'s on the same sketches: the difference of the category means and
    its paired standard error (:func:`category_mean_se` of the per-sample differences, the shapes as clusters)."""
    if [(r["category"], r["shape_id"], r["view"]) for r in records] != [
            (r["category"], r["shape_id"], r["view"]) for r in first]:
        raise AssertionError("the methods were not scored on the same sketches in the same order")
    diff, se = category_mean_se([a["voxel_iou"] - b["voxel_iou"] for a, b in zip(records, first)],
                                [r["category"] for r in records], [r["shape_id"] for r in records])
    return {"voxel_iou": diff, "voxel_iou_se": se}


def evaluate(
    run: str | Path,
    data_dir: str | Path,
    split: str = "test",
    *,
    gt_normals: bool = False,
    generator_run: str | Path | None = None,
    baseline_runs: tuple = (),
    retrieval: bool = True,
    max_samples: int = 0,
    augment_strength: float = 0.0,
    voxel_resolution: int = 32,
    voxel_surface: bool = True,
    progress: bool = True,
    test_set=None,
    train_set=None,
    elevation: float | None = None,
    mirror: bool = False,
    retrieval_data: str | Path | None = None,
    sketch_path: str = "stored",
    mesh_scale: float = 1.0,
) -> dict:
    """Evaluate a run (and baselines) on a split; see the module docstring.

    Args:
        run: run folder with a mesh predictor (and a generator unless ``gt_normals`` or
            ``generator_run``).
        data_dir: dataset folder.
        split: "test" (default), "val" or "train".
        gt_normals: feed the predictor ground-truth normal images.
        generator_run: take the generator from this run.
        baseline_runs: extra runs evaluated alongside.
        retrieval: include the retrieval baseline (reads the whole train split's 64x64 normals).
        max_samples: evaluate at most this many samples, evenly spaced (0: all).
        augment_strength: sketch augmentation of the evaluated sketches.
        voxel_resolution: voxel grid side for the IoU.
        voxel_surface: count the cells the surface passes through as solid (the default); False:
            cell centres inside only (``--voxel-centres``, the earlier tables' measure).
        test_set, train_set: datasets to use instead of reading ``data_dir`` (tests).
        elevation: only the samples rendered at this elevation in degrees (None: all).
        mirror: also score every run as ``NAME +mirror`` (module doc).
        retrieval_data: dataset whose train split the retrieval baseline searches (default
            ``data_dir``): a run trained on a larger dataset is set against retrieval from the shapes it saw.
        sketch_path: "stored", "image" or "canvas": how a test sketch reaches the generator
            (:data:`training.evaluation.models_eval.SKETCH_PATHS`, module doc).
        mesh_scale: scale every run's prediction about its bounding-box centre by this before scoring it
            (a calibration probe; retrieval's meshes are left as they are).

    Returns:
        ``{"mean": {...}, "per_category": {...}}`` of the run, plus ``"methods"`` (every method's
        summary and ``ms_per_sample``), ``"split"``, ``"samples"``, ``"seconds"``.
    """
    from tqdm import tqdm

    from training.loop.trainer import load_run, make_dataset

    t_start = time.perf_counter()
    if sketch_path not in SKETCH_PATHS:
        raise EvaluationError(f"sketch path must be one of {', '.join(SKETCH_PATHS)}, got {sketch_path!r}")
    if sketch_path != "stored" and gt_normals:
        raise EvaluationError("a sketch path applies to sketches; with ground-truth normals no sketch is used")
    if voxel_resolution < 4:
        raise EvaluationError(f"voxel resolution must be >= 4, got {voxel_resolution}")
    if not (np.isfinite(mesh_scale) and 0.0 < mesh_scale <= 10.0):
        raise EvaluationError(f"mesh scale must be in (0, 10], got {mesh_scale}")
    gen_fallback = None
    if generator_run:
        _, gmodels, _ = load_run(generator_run)
        if "generator" not in gmodels:
            raise EvaluationError(f"--generator-run {generator_run} has no generator")
        gen_fallback = gmodels["generator"]
    cfg, gen, pred = _load_models(run, not gt_normals, gen_fallback)
    if generator_run:
        gen = gen_fallback
    data_cfg = cfg.replace(data_dir=str(data_dir), extra_views=0, augment_strength=augment_strength, categories=())
    if test_set is None:
        test_set = make_dataset(data_cfg, split)
        if augment_strength > 0 and split != "train":  # make_dataset only augments the train split
            from training.data.dataset import ShapeViewDataset

            test_set = ShapeViewDataset(Path(data_dir), split, extra_views=0, augment_strength=augment_strength,
                                        seed=cfg.seed)
    if len(test_set) == 0:
        raise EvaluationError(f"the {split} split of {data_dir} is empty")
    methods: list[_Method] = [_RunMethod(Path(run).name or str(run), gen, pred, cfg, gt_normals)]
    for b in baseline_runs:
        bcfg, bgen, bpred = _load_models(b, not gt_normals, gen)
        name = Path(b).name or str(b)
        if any(m.name == name for m in methods):
            name = str(b)
        methods.append(_RunMethod(name, bgen, bpred, bcfg, gt_normals))
    if mirror:
        methods += [_RunMethod(f"{m.name} +mirror", m.generator, m.predictor, m.cfg, gt_normals, mirror=True, plain=m)
                    for m in list(methods)]
    if retrieval:
        if train_set is None:
            # only the 64x64 normal images and cameras, from the dataset's array cache (not every shape file)
            train_set = make_dataset(data_cfg.replace(data_dir=str(retrieval_data or data_dir), augment_strength=0.0,
                                                     extra_views=0, mirror=0.0, mirror_consistency=0.0, mirror_inputs=""),
                                     "train", fields="mesh")
        methods.append(_RetrievalMethod(train_set, methods[0], progress))

    indices = np.arange(len(test_set))
    if elevation is not None:
        indices = indices[np.abs(test_set.elevations() - float(elevation)) < ELEVATION_TOL]
        if indices.size == 0:
            have = sorted({round(float(e), 3) for e in test_set.elevations()})
            raise EvaluationError(f"the {split} split has no view at elevation {elevation:g}; it has {have}")
    if max_samples and max_samples < len(indices):
        indices = indices[np.unique(np.linspace(0, len(indices) - 1, max_samples).round().astype(int))]
    faces = pred.template_faces.cpu().numpy().copy()
    gt_cache: dict[tuple[str, str], tuple[Mesh, np.ndarray]] = {}
    train_mesh_cache: dict[tuple[str, str], Mesh] = {}
    records: dict[str, list[dict]] = {m.name: [] for m in methods}

    def gt_mesh(cat: str, sid: str) -> tuple[Mesh, np.ndarray]:
        from training.evaluation.metrics import solid_voxels

        if (cat, sid) not in gt_cache:
            mesh = test_set.load_mesh(cat, sid)
            gt_cache[(cat, sid)] = (mesh, solid_voxels(mesh, voxel_resolution, voxel_surface))
        return gt_cache[(cat, sid)]

    from training.data.dataset import ShapeViewDataset

    if isinstance(test_set, ShapeViewDataset):  # only what is read: no 256 px images, no raster the canvas redraws
        fields = "mesh" if sketch_path == "canvas" else "sketch"
        fetch = lambda i: test_set.item(i, fields)  # noqa: E731
    else:  # a caller's own test set, as it serves its items
        fetch = test_set.__getitem__
    bar = tqdm(total=len(indices), desc=f"eval {split}", unit="sample", disable=not progress)
    for s in range(0, len(indices), EVAL_BATCH):
        items = [fetch(int(i)) for i in indices[s:s + EVAL_BATCH]]
        batch = {k: torch.as_tensor(np.stack([np.asarray(it[k]) for it in items]))
                 for k in ("sketch", "normals64", "silhouette64", "camera") if k in items[0]}
        if sketch_path != "stored":
            drawings = ([test_set.view_strokes(int(i)) for i in indices[s:s + EVAL_BATCH]]
                        if sketch_path == "canvas" else None)
            batch["sketch"] = app_path_sketches(sketch_path, batch.get("sketch"), drawings,
                                                [(it["category"], it["shape_id"], int(it["view"])) for it in items])
        cams = batch["camera"].numpy().astype(np.float64)
        for method in methods:
            verts, retrieved = method.predict(batch)
            if retrieved is not None:  # retrieval: the train mesh, as it looked in its own view
                verts_world = []
                for (key, cam_r), cam_q in zip(retrieved, cams):
                    if key not in train_mesh_cache:
                        train_mesh_cache[key] = method.train_set.load_mesh(*key)
                    m = train_mesh_cache[key]
                    r_r = cam_r[:9].reshape(3, 3)
                    view = np.asarray(m.vertices, np.float64) @ r_r.T  # p_view = R_r p_world
                    verts_world.append((world_vertices(view, cam_q), m.faces, view))
                sil = [_silhouettes(v[None], f, c[None], 64)[0] for (_, f, v), c in zip(verts_world, cams)]
                meshes = [Mesh(w, f) for w, f, _ in verts_world]
            else:
                if mesh_scale != 1.0:
                    verts = scale_about_box_centre(verts, mesh_scale)
                sil = list(_silhouettes(verts, faces, cams, 64))
                meshes = [Mesh(world_vertices(v, c), faces) for v, c in zip(verts, cams)]
            for it, mesh, sl in zip(items, meshes, sil):
                gmesh, gvox = gt_mesh(it["category"], it["shape_id"])
                rec = _pair_metrics(mesh, gmesh, gvox, voxel_resolution, voxel_surface)
                from training.evaluation.metrics import silhouette_iou

                rec["silhouette_iou"] = silhouette_iou(sl, np.asarray(it["silhouette64"]) > 0.5)
                rec.update(category=it["category"], shape_id=it["shape_id"], view=int(it["view"]))
                records[method.name].append(rec)
        bar.update(len(items))
    bar.close()

    summaries = {}
    for m in methods:
        summ = _summarise(records[m.name])
        summ["ms_per_sample"] = 1000.0 * m.seconds / max(m.count, 1)
        if m is not methods[0] and records[m.name]:
            summ["vs_first"] = {"method": methods[0].name} | _paired_difference(records[m.name], records[methods[0].name])
        summaries[m.name] = summ
    main = summaries[methods[0].name]
    return {
        "mean": main["mean"],
        "per_category": main["per_category"],
        "methods": summaries,
        "method_order": [m.name for m in methods],
        "split": split,
        "samples": int(len(indices)),
        "gt_normals": bool(gt_normals),
        "elevation": None if elevation is None else float(elevation),
        "augment_strength": float(augment_strength),
        "mirror_average": bool(mirror),
        "voxel_resolution": int(voxel_resolution),
        "voxel_surface": bool(voxel_surface),
        "retrieval_data": str(retrieval_data or data_dir) if retrieval else None,
        "sketch_path": sketch_path,
        "mesh_scale": float(mesh_scale),
        "seconds": time.perf_counter() - t_start,
    }


def markdown_table(result: dict) -> str:
    """Voxel IoU / Chamfer-L1 per category (rows) and method (columns), then every metric's mean and the cost."""
    names = result["method_order"]
    cats = sorted({c for n in names for c in result["methods"][n]["per_category"]})
    what = [f"{result['samples']} samples"]
    if result.get("elevation") is not None:
        what.append(f"views at {result['elevation']:g} degrees elevation")
    if result["gt_normals"]:
        what.append("ground-truth normals")
    elif result.get("augment_strength"):
        what.append(f"sketches augmented at strength {result['augment_strength']:g}")
    if result.get("sketch_path", "stored") != "stored":
        what.append(SKETCH_PATHS[result["sketch_path"]])
    if result.get("mesh_scale", 1.0) != 1.0:
        what.append(f"the runs' meshes scaled by {result['mesh_scale']:g} about their box centres")
    if not result.get("voxel_surface", True):
        what.append("voxels by cell centres only")
    if result.get("retrieval_data") and "retrieval" in names:
        what.append(f"retrieval from the train split of {result['retrieval_data']}")
    lines = [f"Voxel IoU ({result['voxel_resolution']}^3) / Chamfer-L1 on the {result['split']} split, "
             + ", ".join(what), "",
             "| category | " + " | ".join(names) + " |", "|---|" + "---:|" * len(names)]
    for c in cats:
        cells = []
        for n in names:
            per = result["methods"][n]["per_category"].get(c, {})
            cells.append(f"{per.get('voxel_iou', float('nan')):.3f} / {per.get('chamfer_l1', float('nan')):.3f}")
        lines.append(f"| {c} | " + " | ".join(cells) + " |")
    lines += ["", "| method | " + " | ".join(METRICS) + " | ms / sample |", "|---|" + "---:|" * (len(METRICS) + 1)]
    for n in names:
        mean = result["methods"][n]["mean"]
        cells = [f"{mean[m]:.4f}" for m in METRICS]
        se = mean.get("voxel_iou_se")
        if se is not None and np.isfinite(se):
            cells[METRICS.index("voxel_iou")] += f" +- {se:.4f}"
        lines.append(f"| {n} | " + " | ".join(cells) + f" | {result['methods'][n]['ms_per_sample']:.1f} |")
    paired = [(n, result["methods"][n]["vs_first"]) for n in names if "vs_first" in result["methods"][n]]
    if paired:
        def cell(d: dict) -> str:  # the SE is NaN (None once through JSON) when a category has one shape
            se = d.get("voxel_iou_se")
            return f"{d['voxel_iou']:+.4f}" + (f" +- {se:.4f}" if se is not None and np.isfinite(se) else "")

        lines += ["", f"Voxel IoU minus {paired[0][1]['method']}'s on the same sketches (paired): "
                  + "; ".join(f"{n} {cell(d)}" for n, d in paired) + "."]
    lines.append("")
    lines.append("voxel_iou, normal_consistency, silhouette_iou: higher is better; chamfer_l1: lower is better. "
                 "Means are over categories; +- one standard error of that mean, the shapes as the draws (a shape's "
                 "views are not independent). ms / sample: network inference only (this machine).")
    return "\n".join(lines) + "\n"


def bar_chart(result: dict, path: str | Path) -> None:
    """Grouped bars of voxel IoU per category and method (PNG, atomic)."""
    atomic_write_bytes(path, bar_chart_png(result))


def bar_chart_png(result: dict) -> bytes:
    """The PNG bytes of :func:`bar_chart`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = result["method_order"]
    cats = sorted({c for n in names for c in result["methods"][n]["per_category"]}) + ["mean"]
    x = np.arange(len(cats))
    width = 0.8 / max(len(names), 1)
    fig, ax = plt.subplots(figsize=(max(6, 0.9 * len(cats) + 2), 3.5))
    for k, n in enumerate(names):
        pc = result["methods"][n]["per_category"]
        vals = [pc.get(c, {}).get("voxel_iou", np.nan) for c in cats[:-1]] + [result["methods"][n]["mean"]["voxel_iou"]]
        ax.bar(x + (k - (len(names) - 1) / 2) * width, vals, width, label=n)
    ax.set_xticks(x, cats, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("voxel IoU")
    ax.set_ylim(0, 1)
    ax.legend(fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()


def _json_safe(x):
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x


def evaluate_cli(args: argparse.Namespace) -> int:
    """The ``sketchmesh eval`` command (see :mod:`training.cli.train`).

    Every input and output location is checked before the evaluation runs; the table, the JSON
    files and the chart are then written all or nothing.
    """
    from engine.cliutil import check_output_dir, check_output_file
    from engine.fileio import StagedWrites
    from training.data.dataset import check_dataset
    from training.loop.checkpoint import check_run_folder

    if args.max_samples < 0:
        raise EvaluationError(f"--max-samples must be >= 0, got {args.max_samples}")
    check_run_folder(args.run)
    for flag, runs in (("--generator-run", [args.generator_run] if args.generator_run else []),
                       ("--baseline-run", args.baseline_run)):
        for run in runs:
            check_run_folder(run, flag)
    check_dataset(args.data, args.split, what="--data")
    if args.retrieval_data and not args.no_retrieval:
        check_dataset(args.retrieval_data, "train", what="--retrieval-data")
    out = Path(args.out) if args.out else Path(args.run) / "eval"
    check_output_dir(out, "--out")
    if args.json:
        check_output_file(args.json, "--json")
    result = evaluate(
        args.run, args.data, args.split, gt_normals=args.gt_normals, generator_run=args.generator_run,
        baseline_runs=tuple(args.baseline_run), retrieval=not args.no_retrieval, max_samples=args.max_samples,
        augment_strength=args.augment_strength, voxel_resolution=args.voxel_resolution, progress=not args.quiet,
        elevation=args.elevation, voxel_surface=not args.voxel_centres, mirror=args.mirror_average,
        retrieval_data=args.retrieval_data, sketch_path=args.sketch_path,
        mesh_scale=1.0 if args.mesh_scale is None else args.mesh_scale,
    )
    table = markdown_table(result)
    print(table)
    stem = f"eval_{args.split}"
    text = json.dumps(_json_safe(result), indent=2, sort_keys=True)
    with StagedWrites() as staged:
        staged.add(out / f"{stem}.md", table)
        staged.add(out / f"{stem}.json", text)
        staged.add(out / f"{stem}.png", bar_chart_png(result))
        if args.json:
            staged.add(args.json, text)
    print(f"wrote {out / (stem + '.md')}, {out / (stem + '.json')}, {out / (stem + '.png')}"
          + (f" and {args.json}" if args.json else "") + f" in {result['seconds']:.1f} s")
    return 0
