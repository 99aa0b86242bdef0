"""``sketchmesh eval --models DIR --data DATA``: voxel IoU of exported ONNX models on any dataset.

Where ``sketchmesh eval RUN`` scores the torch networks of a training run, this scores what the
app runs: folders of ONNX models (``sketchmesh export``, or ``bundled`` for the app's own) driven
by :class:`engine.pipeline.SketchEngine`, on any dataset built by ``sketchmesh data`` -- in
particular ``--source meshes:DIR``, a user's own meshes. It answers "are my retrained models
better than the bundled ones on my meshes?".

For every shape of the chosen split (``--split all`` for a mesh folder, whose few shapes may all
have landed in one split) and ``--views N`` of its stored views (evenly spaced over the shape's
views, each at the middle of its share: 4 of 24 azimuths are 45, 135, 225 and 315 degrees):

1. the stored line drawing (``sketch``, 255 = ink, ``/ 255`` is the generator's input, the raster
   ``sketchmesh gallery`` and ``bench tradeoff`` feed the engine; ``--augment-strength A`` redraws
   it hand-drawn from the stored polylines instead; ``--sketch-path image`` puts it through the
   engine's image-file preprocessing first, ``canvas`` draws its strokes as the app's canvas does)
   goes through ``SketchEngine.predict`` (cache off, no refinement);
2. the predicted mesh, in the view's frame, is rotated back to the world with the view's camera
   (:func:`training.evaluation.metrics.world_vertices`);
3. its solid voxelisation at ``--voxel-resolution`` (32^3) is compared with the shape's own
   normalised mesh (the ``vertices`` / ``faces`` of its shape file): voxel IoU.

A shape's IoU is the mean over its views; the table's mean is the mean over shapes (not over
categories, as ``eval RUN`` does: a mesh folder often has one category).

Floors, in the same table:

* ``template`` -- the template sphere of the (first) model folder's predictor (level and radius
  from its metadata: 642 vertices, radius 0.5 for the bundled one) at the origin of the world
  frame: what the predictor deforms, i.e. a model that learned nothing. One IoU per shape.
* ``retrieval`` -- per view, the nearest training view by L1 distance between line drawings
  (area-averaged to 64x64, then blurred with a Gaussian of :data:`RETRIEVAL_BLUR_SIGMA` pixels),
  among the train split of ``--retrieval-data`` (default: ``--data`` itself). Its shape is placed
  as it looked in its own view (``R_q.T @ R_r``, as in ``eval RUN``). The query shape itself (same
  category and id) is never retrieved (leave-one-out), so ``--split all`` on one folder is fair.
  Unlike ``eval RUN``'s retrieval (by generated normal images) it uses only the drawing, so it
  is one floor for every model folder. With no training shapes it is skipped with a note.

How the meshes stand, beside the IoU: every voxelisation's :func:`training.evaluation.metrics.support_count` (the
separate pieces, legs, end panels or wheels, that the lowest quarter of its height is split into; the retrieved shape
counted upright, as it was modelled), and per category, over the drawings of the shapes that stand on two or more, the
share of each column's meshes that stand on two or more too and that stand on as many (:func:`supports_summary`): issue
16's "parts a person would name" counted on every drawing instead of looked for in a gallery row.

Outputs: a markdown table (printed, and written to ``OUT/eval_models_<split>.md``), JSON
(``OUT/eval_models_<split>.json`` and ``--json PATH``): every shape's row (mean IoUs and each
view's, the supports), the means, per-category means, the supports table and the settings. ``OUT`` defaults to
``DATA/eval``.
"""

from __future__ import annotations

import argparse
import json
import time
import zlib
from collections import defaultdict
from pathlib import Path

import numpy as np

from engine.errors import EmptySketchError, SketchmeshError
from engine.mesh import Mesh
from engine.preprocess import preprocess_raster, rasterize_strokes
from engine.strokes import Stroke

BUNDLED = "bundled"
"""``--models bundled``: the app's bundled models (unless a folder of that name exists here)."""

DEFAULT_VIEWS = 4
RETRIEVAL_SIZE = 64
RETRIEVAL_BLUR_SIGMA = 1.0
"""Gaussian blur (pixels at 64x64) of the retrieval features: a stroke a pixel away still matches."""
RETRIEVAL_CHUNK = 512
SKETCH_PATHS = {
    "stored": "the stored drawings",
    "image": "through the engine's image-file preprocessing",
    "canvas": "the strokes drawn as the app's canvas draws them",
}
"""``sketchmesh eval --sketch-path`` values (for a RUN and for --models) and how a table's caption says them."""
TEMPLATE = "template"
RETRIEVAL = "retrieval"


def models_folder(spec: str) -> Path:
    """The model folder a ``--models``-style argument names: ``bundled`` is the app's (unless a folder of that name
    exists here), anything else a path."""
    from engine.models import resolve_models_dir

    return resolve_models_dir(None if spec == BUNDLED and not Path(spec).exists() else spec)


class ModelsEvalError(SketchmeshError):
    """The model-folder evaluation cannot run (bad flags, empty split, unusable dataset)."""


# --------------------------------------------------------------------------- inputs
def resolve_model_folders(specs) -> list[tuple[str, Path]]:
    """``--models`` values -> (label, folder) pairs; ``bundled`` is the app's bundled models.

    Labels are the folder names, or the paths where two names clash. Existence and validity are
    checked when the engines load (:func:`open_engines`).
    """
    out: list[tuple[str, Path]] = []
    for spec in specs:
        spec = str(spec)
        path = models_folder(spec)
        label = BUNDLED if spec == BUNDLED and not Path(spec).exists() else path.name or str(path)
        if any(p.resolve() == path.resolve() for _, p in out):
            raise ModelsEvalError(f"--models {spec}: the same model folder is given twice")
        if any(lab == label for lab, _ in out) or label in (TEMPLATE, RETRIEVAL):
            label = str(path)
        out.append((label, path))
    if not out:
        raise ModelsEvalError("give at least one --models DIR")
    return out


def open_engines(folders: list[tuple[str, Path]], threads: int | None = None) -> list:
    """One loaded :class:`engine.pipeline.SketchEngine` per folder (cache off); ModelError if unusable."""
    from engine.pipeline import SketchEngine

    engines = []
    for _, path in folders:
        engine = SketchEngine(path, threads=threads, cache_size=0)
        engine.load()
        engines.append(engine)
    return engines


class MirrorAveraged:
    """An opened engine seen with its ``mirror_average`` on for each prediction (the same sessions, no second load)."""

    def __init__(self, engine) -> None:
        self._engine = engine

    def predict(self, *args, **kwargs):
        previous = self._engine.mirror_average
        self._engine.mirror_average = True
        try:
            return self._engine.predict(*args, **kwargs)
        finally:
            self._engine.mirror_average = previous

    def __getattr__(self, name: str):
        return getattr(self._engine, name)


def pick_views(num_views: int, n: int) -> list[int]:
    """``n`` view indices evenly spaced over ``num_views``, each in the middle of its share (0 or n >= num_views: all)."""
    if n <= 0 or n >= num_views:
        return list(range(num_views))
    return sorted({int((k + 0.5) * num_views / n) for k in range(n)})


def split_counts(manifest: dict) -> dict[str, int]:
    """Shapes per split of a dataset manifest."""
    counts: dict[str, int] = defaultdict(int)
    for rec in manifest.get("shapes", []):
        counts[str(rec.get("split"))] += 1
    return dict(counts)


def check_data(data_dir, split: str, what: str = "--data", model_input: bool = True) -> dict:
    """The dataset is usable and ``split`` has shapes (naming the splits it has); returns its manifest.

    ``model_input``: its line drawings must also be the models' 256x256 input (the retrieval
    data's need not: retrieval compares drawings at 64x64).
    """
    from training.data.dataset import DatasetError, check_dataset

    try:
        manifest = check_dataset(data_dir, "all", what=what)
    except DatasetError as exc:  # some of its messages (no manifest) do not name the flag
        if str(exc).startswith(what):
            raise
        raise DatasetError(f"{what} {exc}") from None
    if split != "all":
        counts = split_counts(manifest)
        if not counts.get(split):
            have = ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
            raise ModelsEvalError(f"{what} {data_dir}: the {split} split has no shapes (it has {have}); "
                                  "use --split all to score every shape")
    size = int((manifest.get("settings") or {}).get("size", 256))
    from engine.contract import SKETCH_SIZE

    if model_input and size != SKETCH_SIZE:
        raise ModelsEvalError(f"{what} {data_dir} holds {size}x{size} line drawings; the models take "
                              f"{SKETCH_SIZE}x{SKETCH_SIZE}: rebuild it with --size {SKETCH_SIZE}")
    return manifest


# --------------------------------------------------------------------------- retrieval
def sketch_feature(sketch: np.ndarray) -> np.ndarray:
    """(H, W) sketch in [0, 1] -> (64 * 64,) float32 retrieval feature (area-averaged, blurred)."""
    import cv2

    a = np.asarray(sketch, dtype=np.float32)
    small = cv2.resize(a, (RETRIEVAL_SIZE, RETRIEVAL_SIZE), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), RETRIEVAL_BLUR_SIGMA)
    return small.reshape(-1)


class SketchRetrieval:
    """Nearest training view by L1 distance of :func:`sketch_feature` (leave-one-out by shape)."""

    def __init__(self, dataset, progress: bool = False) -> None:
        from tqdm import tqdm

        self.dataset = dataset
        feats, cams, keys, views = [], [], [], []
        shapes = dataset.shapes()
        for cat, sid, _ in tqdm(shapes, desc="retrieval index", unit="shape", disable=not progress):
            sk = dataset.shape_array(cat, sid, "sketch")
            cam = dataset.shape_array(cat, sid, "cameras")
            for v in range(len(sk)):
                feats.append(sketch_feature(sk[v].astype(np.float32) / 255.0).astype(np.float16))
                cams.append(np.asarray(cam[v], np.float64))
                keys.append((cat, sid))
                views.append(v)
        self.features = np.stack(feats) if feats else np.zeros((0, RETRIEVAL_SIZE**2), np.float16)
        self.cameras = np.stack(cams) if cams else np.zeros((0, 16))
        self.keys = keys
        self.views = views
        self._key_ids = {k: i for i, k in enumerate(sorted(set(keys)))}
        self._row_key = np.array([self._key_ids[k] for k in keys], np.int64)
        self._meshes: dict[tuple[str, str], Mesh] = {}
        self._supports: dict[tuple, int] = {}

    def __len__(self) -> int:
        return len(self.keys)

    def nearest(self, sketch: np.ndarray, exclude: tuple[str, str] | None = None) -> int | None:
        """Row of the nearest training view to ``sketch`` (not of shape ``exclude``), or None if there is none."""
        q = sketch_feature(sketch)
        skip = self._key_ids.get(exclude, -1) if exclude is not None else -1
        best_d, best_i = np.inf, None
        for s in range(0, len(self.keys), RETRIEVAL_CHUNK):
            d = np.abs(self.features[s:s + RETRIEVAL_CHUNK].astype(np.float32) - q[None]).sum(1)
            d[self._row_key[s:s + RETRIEVAL_CHUNK] == skip] = np.inf
            i = int(np.argmin(d))
            if d[i] < best_d:
                best_d, best_i = float(d[i]), s + i
        return best_i

    def mesh(self, row: int) -> Mesh:
        key = self.keys[row]
        if key not in self._meshes:
            self._meshes[key] = self.dataset.load_mesh(*key)
        return self._meshes[key]

    def supports(self, row: int, resolution: int, surface: bool) -> int:
        """The retrieved shape's :func:`~training.evaluation.metrics.support_count`, upright as it was modelled (not
        tilted into the query's view as :meth:`world_mesh` places it for the IoU: a view from another elevation would
        tilt its legs into one another)."""
        from training.evaluation.metrics import solid_voxels, support_count

        key = (self.keys[row], int(resolution), bool(surface))
        if key not in self._supports:
            self._supports[key] = support_count(solid_voxels(self.mesh(row), resolution, surface))
        return self._supports[key]

    def world_mesh(self, row: int, query_camera: np.ndarray) -> Mesh:
        """The retrieved shape as it looked in its own view, shown in the query's view, in the world frame."""
        from training.evaluation.metrics import world_vertices

        m = self.mesh(row)
        r_r = self.cameras[row][:9].reshape(3, 3)
        view = np.asarray(m.vertices, np.float64) @ r_r.T  # p_view = R_r p_world
        return Mesh(world_vertices(view, query_camera), m.faces)


# --------------------------------------------------------------------------- evaluation
def _iou(voxels: np.ndarray, gt_voxels: np.ndarray) -> float:
    union = int(np.count_nonzero(voxels | gt_voxels))
    return 1.0 if union == 0 else int(np.count_nonzero(voxels & gt_voxels)) / union


def _mean(values) -> float | None:
    vals = [v for v in values if v is not None]
    return float(np.mean(vals)) if vals else None


def _se(values) -> float | None:
    """Standard error of the mean over meshes (each mesh one draw, one stratum); None with fewer than two meshes."""
    from training.evaluation.metrics import category_mean_se

    vals = [v for v in values if v is not None]
    se = category_mean_se(vals, np.zeros(len(vals)))[1] if vals else float("nan")
    return se if np.isfinite(se) else None


def _paired(rows: list[dict], column: str, first: str) -> dict | None:
    """``column`` minus ``first`` over the meshes both scored: the mean difference and its standard error."""
    diffs = [r["iou"][column] - r["iou"][first] for r in rows
             if r["iou"][column] is not None and r["iou"][first] is not None]
    if not diffs:
        return None
    return {"mean": float(np.mean(diffs)), "se": _se(diffs), "meshes": len(diffs)}


def canvas_raster(polylines: list) -> np.ndarray:
    """A drawing's (K, 2) pixel polylines as the app's canvas feeds them to the generator: each one an
    :class:`engine.strokes.Stroke` through :func:`engine.preprocess.rasterize_strokes` (framed on the points,
    the standard width, full ink). Raises EmptySketchError when there are none."""
    return rasterize_strokes([Stroke(np.asarray(p, np.float64)) for p in polylines])


def _view_sketch(dataset, cat: str, sid: str, view: int, augment_strength: float, seed: int,
                 sketch_path: str = "stored") -> np.ndarray:
    """One view's drawing as ``sketch_path`` feeds it to the engine (:data:`SKETCH_PATHS`).

    Raises:
        EmptySketchError: the engine's preprocessing finds no ink (image) or no strokes (canvas).
    """
    from training.data.augment import augment_strokes, render_sketch
    from training.data.render import view_polylines

    rng_seed = [int(seed), zlib.crc32(f"{cat}/{sid}".encode()), int(view)]
    if sketch_path == "canvas" or augment_strength > 0:
        arrays = {k: dataset.shape_array(cat, sid, k) for k in ("view_poly_offsets", "poly_offsets", "poly_points")}
        polylines = view_polylines(arrays, view)
    if sketch_path == "canvas":
        return canvas_raster(augment_strokes(polylines, augment_strength, rng_seed, dataset.size).polylines)
    if augment_strength > 0:
        sketch = np.asarray(render_sketch(polylines, dataset.size, augment_strength, rng_seed), np.float32)
    else:
        sketch = dataset.shape_array(cat, sid, "sketch")[view].astype(np.float32) / 255.0
    return preprocess_raster(sketch) if sketch_path == "image" else sketch


def evaluate_models(
    models: list[tuple[str, Path]],
    data_dir: str | Path,
    split: str = "test",
    *,
    views: int = DEFAULT_VIEWS,
    retrieval: bool = True,
    retrieval_data: str | Path | None = None,
    max_samples: int = 0,
    augment_strength: float = 0.0,
    seed: int = 0,
    sketch_path: str = "stored",
    voxel_resolution: int = 32,
    voxel_surface: bool = True,
    threads: int | None = None,
    progress: bool = True,
    engines: list | None = None,
    elevation: float | None = None,
) -> dict:
    """Score model folders on a dataset's split with the template and retrieval floors (module docstring).

    Args:
        models: (label, folder) pairs (:func:`resolve_model_folders`).
        data_dir: dataset folder (``sketchmesh data --out``).
        split: "train", "val", "test" or "all".
        views: views per shape, evenly spaced (0: all).
        retrieval: include the retrieval floor.
        retrieval_data: dataset whose train split is searched (default ``data_dir``).
        max_samples: at most this many shapes, evenly spaced (0: all).
        augment_strength: redraw the line drawings hand-drawn at this strength (0: the stored ones).
        seed: seed of that augmentation.
        sketch_path: "stored", "image" or "canvas": how a drawing reaches the engine
            (:data:`SKETCH_PATHS`); a view the engine's preprocessing refuses
            (no ink above its threshold) is skipped like an empty one.
        voxel_resolution: voxel grid side.
        voxel_surface: count the cells the surface passes through (default); False: centres only.
        threads: ONNX Runtime threads per engine (None: the engine's default).
        engines: loaded engines to use instead of opening ``models`` (tests).
        elevation: only views at this elevation in degrees (None: all); shapes without one are left out.

    Returns:
        JSON-ready dict: ``columns`` (model labels, then "retrieval" if it ran, then "template"),
        ``rows`` (per shape: category, shape_id, split, views, ``iou`` {column: mean over the views},
        ``per_view`` [{view, azimuth, elevation, iou, ``supports`` {column: count; None for a retrieval miss; no
        template entry, its count is the summary's}, retrieved, and for folders with a router ``routes``
        {label: {route, category}}}], ``true_supports`` the shape's own count),
        ``mean`` (per column, over the rows that have a value), ``counted`` (those rows),
        ``per_category``, ``supports`` (:func:`supports_summary`), ``notes`` and the settings.

    Raises:
        ModelsEvalError, DatasetError, ModelError: unusable inputs, each on one line.
    """
    from tqdm import tqdm

    from engine.icosphere import icosphere
    from training.data.dataset import ShapeViewDataset
    from training.evaluation.metrics import ELEVATION_TOL, solid_voxels, support_count, world_vertices

    t_start = time.perf_counter()
    if not 1 <= voxel_resolution <= 512:
        raise ModelsEvalError(f"voxel resolution must be in [1, 512], got {voxel_resolution}")
    if split not in ("train", "val", "test", "all"):
        raise ModelsEvalError(f"--split must be train, val, test or all, got {split!r}")
    if sketch_path not in SKETCH_PATHS:
        raise ModelsEvalError(f"--sketch-path must be one of {', '.join(SKETCH_PATHS)}, got {sketch_path!r}")
    check_data(data_dir, split)
    dataset = ShapeViewDataset(Path(data_dir), split, extra_views=0, augment_strength=0.0)
    shapes = dataset.shapes()
    if not shapes:  # pragma: no cover - check_data refuses it first
        raise ModelsEvalError(f"--data {data_dir}: the {split} split has no shapes")
    if max_samples and max_samples < len(shapes):
        shapes = [shapes[i] for i in np.unique(np.linspace(0, len(shapes) - 1, max_samples).round().astype(int))]
    if engines is None:
        engines = open_engines(models, threads)
    labels = [label for label, _ in models]
    info = engines[0].model_info()
    template = icosphere(int(info["template_level"]), float(info["template_radius"]))
    template_vox = solid_voxels(template, voxel_resolution, voxel_surface)

    notes: list[str] = []
    searcher = None
    if retrieval:
        rdir = Path(retrieval_data) if retrieval_data is not None else Path(data_dir)
        if retrieval_data is not None:
            check_data(rdir, "train", what="--retrieval-data", model_input=False)
        else:
            from training.data.dataset import load_manifest

            if not split_counts(load_manifest(rdir)).get("train"):
                notes.append(f"retrieval skipped: {rdir} has no train split shapes to retrieve from "
                             "(pass --retrieval-data DIR)")
                rdir = None
        if rdir is not None:
            searcher = SketchRetrieval(ShapeViewDataset(rdir, "train", extra_views=0, augment_strength=0.0), progress)
    columns = labels + ([RETRIEVAL] if searcher is not None else []) + [TEMPLATE]

    rows = []
    skipped_views = 0
    bar = tqdm(shapes, desc=f"eval models ({split})", unit="mesh", disable=not progress)
    for cat, sid, shape_split in bar:
        gt = dataset.load_mesh(cat, sid)
        gt_vox = solid_voxels(gt, voxel_resolution, voxel_surface)
        gt_supports = support_count(gt_vox)
        cams = dataset.shape_array(cat, sid, "cameras")
        azimuths = dataset.shape_array(cat, sid, "azimuths")
        elevations = dataset.shape_array(cat, sid, "elevations")
        per_view = []
        candidates = list(range(len(cams)))
        if elevation is not None:
            candidates = [v for v in candidates if abs(float(elevations[v]) - float(elevation)) < ELEVATION_TOL]
            if not candidates:
                continue
        for v in [candidates[k] for k in pick_views(len(candidates), views)]:
            try:
                sketch = _view_sketch(dataset, cat, sid, v, augment_strength, seed, sketch_path)
            except EmptySketchError:
                skipped_views += 1
                continue
            iou: dict = {}
            supports: dict = {}
            rec: dict = {"view": int(v), "azimuth": float(azimuths[v]), "elevation": float(elevations[v]), "iou": iou,
                         "supports": supports}
            try:
                for label, engine in zip(labels, engines):
                    pred = engine.predict(sketch)
                    if getattr(pred, "category", None) is not None:  # a folder with a router: where it sent the drawing
                        rec.setdefault("routes", {})[label] = {"route": pred.route, "category": pred.category}
                    world = Mesh(world_vertices(np.asarray(pred.mesh.vertices, np.float64), cams[v]), pred.mesh.faces)
                    vox = solid_voxels(world, voxel_resolution, voxel_surface)
                    iou[label], supports[label] = _iou(vox, gt_vox), support_count(vox)
            except EmptySketchError:  # a view with no ink (a degenerate mesh seen edge-on): nothing to score
                skipped_views += 1
                continue
            if searcher is not None:
                hit = searcher.nearest(sketch, exclude=(cat, sid))
                iou[RETRIEVAL], supports[RETRIEVAL], rec["retrieved"] = None, None, None
                if hit is not None:
                    rmesh = searcher.world_mesh(hit, cams[v])
                    iou[RETRIEVAL] = _iou(solid_voxels(rmesh, voxel_resolution, voxel_surface), gt_vox)
                    supports[RETRIEVAL] = searcher.supports(hit, voxel_resolution, voxel_surface)
                    rcat, rsid = searcher.keys[hit]
                    rec["retrieved"] = f"{rcat}/{rsid} view {searcher.views[hit]}"
            per_view.append(rec)
        template_iou = _iou(template_vox, gt_vox)
        rows.append({
            "category": cat, "shape_id": sid, "split": shape_split, "views": [r["view"] for r in per_view],
            "iou": {c: template_iou if c == TEMPLATE else _mean(r["iou"].get(c) for r in per_view) for c in columns},
            "per_view": per_view, "true_supports": gt_supports,
        })
    bar.close()
    if elevation is not None and not rows:
        raise SketchmeshError(f"no view of the {split} split of {data_dir} is at elevation {elevation:g} degrees")
    if skipped_views:
        notes.append(f"{skipped_views} view(s) with a blank line drawing were skipped")
    if searcher is not None and any(r["iou"][RETRIEVAL] is None for r in rows):
        notes.append("retrieval: no other training shape for some meshes (leave-one-out); their retrieval is blank")

    mean = {c: _mean(r["iou"][c] for r in rows) for c in columns}
    se = {c: _se(r["iou"][c] for r in rows) for c in columns}
    paired = {c: _paired(rows, c, columns[0]) for c in columns[1:]}
    counted = {c: sum(r["iou"][c] is not None for r in rows) for c in columns}
    per_cat: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        per_cat[r["category"]].append(r)
    per_category = {cat: {c: _mean(r["iou"][c] for r in rs) for c in columns} | {"meshes": len(rs)}
                    for cat, rs in sorted(per_cat.items())}
    template_supports = support_count(template_vox)
    return {
        "columns": columns,
        "models": {label: str(path) for label, path in models},
        "rows": rows,
        "mean": mean,
        "se": se,
        "paired": {"first": columns[0], "differences": paired},
        "counted": counted,
        "per_category": per_category,
        "supports": supports_summary(rows, columns, template_supports),
        "notes": notes,
        "data": str(data_dir),
        "split": split,
        "meshes": len(rows),
        "views_per_mesh": int(views),
        "retrieval_data": str(searcher.dataset.root) if searcher is not None else None,
        "retrieval_views": len(searcher) if searcher is not None else 0,
        "template": {"level": int(info["template_level"]), "radius": float(info["template_radius"]),
                     "vertices": int(template.num_vertices)},
        "augment_strength": float(augment_strength),
        "sketch_path": sketch_path,
        "voxel_resolution": int(voxel_resolution),
        "voxel_surface": bool(voxel_surface),
        "seconds": time.perf_counter() - t_start,
    }


def supports_summary(rows: list[dict], columns: list[str], template_supports: int) -> dict:
    """Per category, how the meshes stand (:func:`training.evaluation.metrics.support_count`), over the drawings of the
    shapes that stand on two or more supports (legs, end panels, wheels): the share of those drawings whose mesh stands
    on two or more too (``separate``), and the share whose mesh has the shape's own count (``same``), per column.

    Returns:
        {category: {"shapes": shapes in the category, "standing": those on two or more supports, "drawings": their
        drawings, "columns": {column: {"separate": share or None, "same": share or None}}}}; a column without a count
        for a drawing (a retrieval miss) is left out of that drawing's shares; the template sphere's count is the same
        for every drawing. ``same`` is strict: a bench on six slats' feet drawn as two end panels has two.
    """
    out: dict = {}
    for cat in sorted({r["category"] for r in rows}):
        rs = [r for r in rows if r["category"] == cat]
        standing = [r for r in rs if r["true_supports"] >= 2]
        shares: dict = {}
        for c in columns:
            pairs = [(r["true_supports"], template_supports if c == TEMPLATE else v["supports"].get(c))
                     for r in standing for v in r["per_view"]]
            pairs = [(g, p) for g, p in pairs if p is not None]
            shares[c] = {"separate": _mean(float(p >= 2) for _, p in pairs),
                         "same": _mean(float(p == g) for g, p in pairs)}
        out[cat] = {"shapes": len(rs), "standing": len(standing),
                    "drawings": sum(len(r["per_view"]) for r in standing), "columns": shares}
    return out


def _cell(x) -> str:
    return "-" if x is None else f"{x:.3f}"


def markdown_report(result: dict) -> str:
    """The per-mesh table with the means row, the paired differences, a line on each floor and the supports table."""
    cols = result["columns"]
    aug = f", hand-drawn at strength {result['augment_strength']:g}" if result["augment_strength"] > 0 else ""
    if result.get("sketch_path", "stored") != "stored":
        aug += f", {SKETCH_PATHS[result['sketch_path']]}"
    views = result["views_per_mesh"] or "all"
    cells = "" if result.get("voxel_surface", True) else ", voxels by cell centres only"
    lines = [f"Voxel IoU ({result['voxel_resolution']}^3) on the {result['split']} split of {result['data']}: "
             f"{result['meshes']} meshes, {views} views each{aug}{cells}", "",
             "| mesh | category | " + " | ".join(cols) + " |", "|---|---|" + "---:|" * len(cols)]
    for r in result["rows"]:
        lines.append(f"| {r['shape_id']} | {r['category']} | " + " | ".join(_cell(r["iou"][c]) for c in cols) + " |")
    lines.append(f"| **mean** ({result['meshes']} meshes) | | "
                 + " | ".join(f"**{_cell(result['mean'][c])}**" for c in cols) + " |")
    se = result.get("se", {})
    if any(se.get(c) is not None for c in cols):
        lines.append("| standard error | | " + " | ".join(_cell(se.get(c)) for c in cols) + " |")
    paired = result.get("paired", {})
    diffs = [(c, d) for c, d in paired.get("differences", {}).items() if d is not None]
    if diffs:
        lines += ["", f"Minus {paired['first']}'s on the same meshes (paired, mean +- standard error): "
                  + "; ".join(f"{c} {d['mean']:+.3f}" + (f" +- {d['se']:.3f}" if d["se"] is not None else "")
                              for c, d in diffs) + "."]
    lines.append("")
    lines.append("Each model's mesh is predicted from a view's line drawing by the app's engine and compared, in the "
                 "world frame, with the shape's own mesh; a mesh's IoU is the mean over its views. Higher is better.")
    if RETRIEVAL in cols:
        lines.append(f"retrieval: the shape of the nearest line drawing among the {result['retrieval_views']} train-split "
                     f"views of {result['retrieval_data']} (the mesh itself excluded).")
    t = result["template"]
    lines.append(f"template: the predictor's {t['vertices']}-vertex template sphere (radius {t['radius']:g}) at the "
                 "origin, a model that learned nothing.")
    sup = result.get("supports")
    if sup and any(e["standing"] for e in sup.values()):
        lines += ["", "How the meshes stand: of the drawings of shapes on two or more separate supports (legs, end panels, "
                  "wheels; pieces in the lowest quarter of the height, `metrics.support_count`), the share whose mesh "
                  "stands on two or more too / on the shape's own count:", "",
                  "| category | shapes standing | " + " | ".join(cols) + " |", "|---|---:|" + "---:|" * len(cols)]
        for cat, e in sup.items():
            if e["standing"]:
                lines.append(f"| {cat} | {e['standing']} of {e['shapes']} | "
                             + " | ".join(f"{_cell(e['columns'][c]['separate'])} / {_cell(e['columns'][c]['same'])}"
                                         for c in cols) + " |")
    lines += [f"note: {n}" for n in result["notes"]]
    return "\n".join(lines) + "\n"


def evaluate_models_cli(args: argparse.Namespace, model_specs: list[str]) -> int:
    """``sketchmesh eval --models DIR ...`` (see :mod:`training.cli.train`): checks, evaluates, writes all or nothing."""
    from engine.cliutil import check_output_dir, check_output_file
    from engine.fileio import StagedWrites

    folders = resolve_model_folders(model_specs)
    threads = args.threads or None
    engines = open_engines(folders, threads)
    if getattr(args, "mirror_only", False):  # the app's default alone: each folder mirror averaged, not plain
        engines = [MirrorAveraged(e) for e in engines]
        folders = [(f"{label} +mirror", path) for label, path in folders]
    elif getattr(args, "mirror_average", False):  # every folder again, averaged with the mirrored drawing's mesh
        engines += [MirrorAveraged(e) for e in engines]
        folders = folders + [(f"{label} +mirror", path) for label, path in folders]
    check_data(args.data, args.split)
    if args.retrieval_data and not args.no_retrieval:
        check_data(args.retrieval_data, "train", what="--retrieval-data", model_input=False)
    out = Path(args.out) if args.out else Path(args.data) / "eval"
    check_output_dir(out, "--out")
    if args.json:
        check_output_file(args.json, "--json")
    views = DEFAULT_VIEWS if args.views is None else args.views
    result = evaluate_models(folders, args.data, args.split, views=views, retrieval=not args.no_retrieval,
                             retrieval_data=args.retrieval_data, max_samples=args.max_samples,
                             augment_strength=args.augment_strength,
                             sketch_path=args.sketch_path, voxel_resolution=args.voxel_resolution,
                             voxel_surface=not args.voxel_centres, threads=threads, progress=not args.quiet, engines=engines, elevation=args.elevation)
    table = markdown_report(result)
    print(table)
    stem = f"eval_models_{args.split}"
    text = json.dumps(result, indent=2, sort_keys=True)
    with StagedWrites() as staged:
        staged.add(out / f"{stem}.md", table)
        staged.add(out / f"{stem}.json", text)
        if args.json:
            staged.add(args.json, text)
    print(f"wrote {out / (stem + '.md')}, {out / (stem + '.json')}" + (f" and {args.json}" if args.json else "")
          + f" in {result['seconds']:.1f} s")
    return 0


__all__ = ["ModelsEvalError", "SketchRetrieval", "evaluate_models", "evaluate_models_cli", "markdown_report",
           "pick_views", "resolve_model_folders", "sketch_feature", "supports_summary"]
