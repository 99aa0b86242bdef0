"""The inference pipeline the app and the CLI call: sketch -> normal image -> mesh.

Stages (each timed in :attr:`Prediction.timings_ms`):

1. ``preprocess``  strokes / image file / raster -> framed (256, 256) raster (:mod:`engine.preprocess`);
2. ``generator``   (1, 1, 256, 256) -> normal image (1, 3, 256, 256) in [0, 1];
3. ``downsample``  area-average to (1, 3, 64, 64) (``cv2.INTER_AREA`` on the HWC image);
4. ``predictor``   -> ``local_offset`` (1, V, 3), ``global_offset`` (1, 3); where the model folder has a
   ``router.onnx`` (:mod:`engine.contract`), it first reads the same 64 x 64 image and picks the mesh
   predictor: a specialist when it is sure enough the drawing is of that specialist's categories, else
   ``mesh_predictor.onnx`` (its time counts here; a specialist is loaded on the first drawing sent to it);
5. ``assemble``    template vertices + local + global -> :class:`engine.mesh.Mesh` in the view
   frame (:mod:`engine.camera`);

   with ``mirror_average`` on, stages 2-5 also run on the drawing flipped left to right, and the two
   meshes are averaged vertex by vertex, the second mirrored back (:func:`engine.icosphere.mirror_average`):
   the two drawings go through each network as one batch of two (a network whose batch dimension is fixed
   at 1 runs twice), each stage's time covers both (the averaging counts in ``assemble``), the normal image
   kept is the plain drawing's, and both use the predictor the plain drawing was routed to (a router whose
   metadata says ``route_mirror`` reads both drawings, one batch, and routes both on their mean probabilities);
6. ``refine``      optional: N steps moving the mesh so its silhouette from the sketch's view
   matches the drawing's outline (:mod:`engine.refine`); 0.0 when off;
7. ``repair``      optional (``repair_folds``): where the final mesh crosses itself, smooth just there until it
   does not (:func:`engine.postprocess.repair_self_intersections`, what the app does to the mesh it
   exports); one self-intersection check when nothing crosses, none when the refinement has just counted none on
   the same mesh (:attr:`engine.refine.RefineResult.crossings`), 0.0 when off.

Sessions are created lazily, once, on first use (or :meth:`SketchEngine.load`). A small LRU
cache keyed on a hash of the preprocessed raster and the mirror and repair settings skips stages 2-5
when none has changed (refined and repaired meshes are cached with it, per step count). :meth:`SketchEngine.predict` is
thread-safe and never touches Qt.
"""

from __future__ import annotations

import hashlib
import os
import threading
import time
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from engine import contract as C
from engine.errors import EmptySketchError, ModelError, SketchInputError
from engine.icosphere import icosphere, mirror_average
from engine.mesh import Mesh
from engine.models import (
    LoadedModel,
    default_threads,
    load_predictor,
    load_router,
    load_runtime_generator,
    model_paths,
    resolve_models_dir,
    router_path,
)
from engine.preprocess import StrokeRasterizer, rasterize_strokes, sketch_raster_from_image
from engine.refine import MAX_STEPS, refine_prediction
from engine.strokes import Stroke

STAGES = ("preprocess", "generator", "downsample", "predictor", "assemble", "refine", "repair")
"""Keys of :attr:`Prediction.timings_ms`, in pipeline order."""

DEFAULT_CACHE_SIZE = 16
"""Predictions kept by the LRU cache (one is ~0.8 MB: the normal image plus the mesh)."""

MAX_OFFSET = 1e3
"""Largest |vertex coordinate| accepted from the predictor; beyond it the model is broken."""


@dataclass(frozen=True, eq=False)
class Prediction:
    """The result of one sketch.

    Attributes:
        mesh: the predicted mesh in the sketch's view frame (see :mod:`engine.camera`).
        normals: (256, 256, 3) float32 normal image in [0, 1] (HWC, (n + 1) / 2, background 0),
            only when asked for (``want_normals=True``), else None.
        sketch: (256, 256) float32 in [0, 1], 1 = ink: the raster the generator saw.
        timings_ms: one entry per stage in :data:`STAGES` (milliseconds); on a cache hit the
            skipped stages are 0.0.
        cached: True when stages 2-5 came from the cache.
        warnings: things the user should know about the result (a refinement that fell back to
            the unrefined mesh says why); empty when all went as asked.
        mirror_average: whether the mesh is the average with the flipped drawing's.
        repair_folds: whether self-intersections of the final mesh were repaired.
        route: the specialist predictor file the router sent the drawing to, or None (``mesh_predictor.onnx``,
            also when the folder has no router).
        category: the router's most likely category of the drawing, or None without a router.
    """

    mesh: Mesh
    normals: np.ndarray | None
    sketch: np.ndarray
    timings_ms: dict[str, float]
    cached: bool
    warnings: tuple[str, ...] = ()
    mirror_average: bool = False
    repair_folds: bool = False
    route: str | None = None
    category: str | None = None


@dataclass(frozen=True, eq=False)
class _Entry:
    mesh: Mesh
    normals_nchw: np.ndarray  # (1, 3, 256, 256) float32 generator output, read-only; HWC only on request
    route: str | None = None
    category: str | None = None
    refined: dict = field(default_factory=dict)  # steps -> engine.refine.RefineResult, under the cache lock
    repaired: dict = field(default_factory=dict)  # steps -> engine.postprocess.RepairResult, under the cache lock


def downsample_normals(normals_nchw: np.ndarray, size: int = C.PREDICTOR_INPUT_SIZE) -> np.ndarray:
    """Area-average a normal image to the predictor's input size.

    Args:
        normals_nchw: (1, 3, H, W) float32.
        size: output side.

    Returns:
        (1, 3, size, size) float32, C-contiguous.
    """
    a = np.asarray(normals_nchw, dtype=np.float32)
    if a.ndim != 4 or a.shape[:2] != (1, 3):
        raise ValueError(f"normals must be (1, 3, H, W), got {a.shape}")
    hwc = np.ascontiguousarray(a[0].transpose(1, 2, 0))
    small = cv2.resize(hwc, (size, size), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(small.transpose(2, 0, 1)[None])


def _run_batch(model, names: list[str], x: np.ndarray) -> list[np.ndarray]:
    """``model``'s outputs ``names`` for the batch ``x``: one run, or one per row where the model's batch dimension is
    fixed at 1 (the contract allows it), stacked."""
    if len(x) == 1 or model.batch_dynamic:
        return model.session.run(names, {model.input_name: x})
    rows = [model.session.run(names, {model.input_name: x[i:i + 1]}) for i in range(len(x))]
    return [np.concatenate(parts) for parts in zip(*rows)]


def assemble_mesh(local_offset: np.ndarray, global_offset: np.ndarray, level: int, radius: float) -> Mesh:
    """Template + offsets -> Mesh (view frame).

    Args:
        local_offset: (1, V, 3) or (V, 3).
        global_offset: (1, 3) or (3,).
        level: icosphere level of the template (V = 10 * 4**level + 2).
        radius: template radius.

    Raises:
        ModelError: shapes that do not match the template, or non-finite / absurd values.
    """
    template = icosphere(level, radius)
    local = np.asarray(local_offset, dtype=np.float64).reshape(-1, 3) if np.size(local_offset) % 3 == 0 else None
    glob = np.asarray(global_offset, dtype=np.float64).reshape(-1)
    if local is None or local.shape != template.vertices.shape:
        raise ModelError(f"predictor local_offset must be (1, {template.num_vertices}, 3), got {np.shape(local_offset)}")
    if glob.shape != (3,):
        raise ModelError(f"predictor global_offset must be (1, 3), got {np.shape(global_offset)}")
    v = template.vertices.astype(np.float64) + local + glob[None, :]
    if not np.all(np.isfinite(v)) or np.abs(v).max() > MAX_OFFSET:
        raise ModelError("the mesh predictor produced non-finite or absurd vertex positions (broken model?)")
    return Mesh(v.astype(np.float32), template.faces)


def _check_flag(name: str, on) -> bool:
    if not isinstance(on, (bool, np.bool_)):
        raise ValueError(f"{name} must be a bool, got {on!r}")
    return bool(on)


def _check_steps(steps) -> int:
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 0 <= steps <= MAX_STEPS:
        raise ValueError(f"refinement steps must be an int in [0, {MAX_STEPS}], got {steps!r}")
    return int(steps)


def raster_key(raster: np.ndarray) -> str:
    """Cache key of a preprocessed raster: a hash of its float32 bytes and shape."""
    a = np.ascontiguousarray(raster, dtype=np.float32)
    return hashlib.blake2b(a.tobytes() + str(a.shape).encode(), digest_size=16).hexdigest()


def _check_raster(raster: np.ndarray) -> np.ndarray:
    a = np.asarray(raster)
    if a.shape != (C.SKETCH_SIZE, C.SKETCH_SIZE):
        raise SketchInputError(
            f"a sketch raster must be the preprocessed ({C.SKETCH_SIZE}, {C.SKETCH_SIZE}) float32 (use "
            f"engine.preprocess.preprocess_raster first), got {a.shape} {a.dtype}"
        )
    if not np.issubdtype(a.dtype, np.number):
        raise SketchInputError(f"sketch raster must be numeric, got {a.dtype}")
    a = a.astype(np.float32)
    if not np.all(np.isfinite(a)):
        raise SketchInputError("sketch raster contains NaN or inf")
    if a.min() < 0.0 or a.max() > 1.0:
        raise SketchInputError(f"sketch raster values must lie in [0, 1], got [{a.min():.3g}, {a.max():.3g}]")
    if not np.any(a > C.SKETCH_INK_THRESHOLD):
        raise EmptySketchError("the sketch is blank: no ink")
    return a


def to_raster(sketch, rasterize=rasterize_strokes) -> np.ndarray:
    """Any accepted sketch form -> the preprocessed (256, 256) float32 raster.

    Args:
        sketch: a (256, 256) raster (used as given), a sequence of :class:`Stroke`, or an image path.
        rasterize: what draws strokes (:func:`engine.preprocess.rasterize_strokes`, or a
            :class:`engine.preprocess.StrokeRasterizer` that remembers the last drawing).
    """
    if isinstance(sketch, (str, os.PathLike)):
        return sketch_raster_from_image(sketch)
    if isinstance(sketch, np.ndarray):
        return _check_raster(sketch)
    if isinstance(sketch, Stroke):
        return rasterize([sketch])
    if isinstance(sketch, Sequence):
        return rasterize(sketch)
    raise SketchInputError(f"a sketch must be a (256, 256) raster, a list of strokes or an image path, got {type(sketch).__name__}")


class SketchEngine:
    """Sketch -> mesh with the two ONNX models. Nothing is loaded until first needed.

    Args:
        models_dir: folder with ``generator.onnx`` and ``mesh_predictor.onnx``; None uses the
            bundled ``assets.MODELS_DIR``. A given folder replaces the bundled one entirely.
        threads: onnxruntime intra-op threads; None = physical cores (capped).
        cache_size: predictions kept in the LRU cache (0 disables caching).
        refine_steps: refinement steps :meth:`predict` runs when not told (0 = off;
            :attr:`refine_steps` can be changed later, e.g. by the app's toggle).
        mirror_average: also predict from the drawing flipped left to right and average the two
            meshes (module doc); :attr:`mirror_average` can be changed later.
        repair_folds: repair the final mesh where its surface crosses itself (module doc);
            :attr:`repair_folds` can be changed later.
    """

    def __init__(self, models_dir: str | os.PathLike | None = None, *, threads: int | None = None,
                 cache_size: int = DEFAULT_CACHE_SIZE, refine_steps: int = 0, mirror_average: bool = False,
                 repair_folds: bool = False):
        if threads is not None and (not isinstance(threads, int) or threads < 1):
            raise ValueError(f"threads must be a positive int or None, got {threads!r}")
        if not isinstance(cache_size, int) or cache_size < 0:
            raise ValueError(f"cache_size must be an int >= 0, got {cache_size!r}")
        self.refine_steps = refine_steps
        self.mirror_average = mirror_average
        self.repair_folds = repair_folds
        self._models_dir = resolve_models_dir(models_dir)
        self._threads = threads or default_threads()
        self._cache_size = cache_size
        self._cache: OrderedDict[str, _Entry] = OrderedDict()
        self._generator: LoadedModel | None = None
        self._predictor: LoadedModel | None = None
        self._router: LoadedModel | None = None
        self._specialists: dict[str, LoadedModel] = {}
        self._specialist_errors: dict[str, ModelError] = {}  # a specialist that failed to load is not tried again
        self._load_lock = threading.Lock()
        self._run_lock = threading.Lock()
        self._cache_lock = threading.Lock()
        self._rasterize = StrokeRasterizer()  # a growing drawing's strokes are drawn once each

    @property
    def models_dir(self) -> Path:
        """The model folder this engine reads."""
        return self._models_dir

    @property
    def threads(self) -> int:
        return self._threads

    @property
    def refine_steps(self) -> int:
        """Refinement steps :meth:`predict` runs by default (0 = off)."""
        return self._refine_steps

    @refine_steps.setter
    def refine_steps(self, steps: int) -> None:
        self._refine_steps = _check_steps(steps)

    @property
    def mirror_average(self) -> bool:
        """Whether :meth:`predict` averages with the mirrored drawing's prediction (module doc)."""
        return self._mirror_average

    @mirror_average.setter
    def mirror_average(self, on: bool) -> None:
        self._mirror_average = _check_flag("mirror_average", on)

    @property
    def repair_folds(self) -> bool:
        """Whether :meth:`predict` repairs self-intersections of the final mesh (module doc)."""
        return self._repair_folds

    @repair_folds.setter
    def repair_folds(self, on: bool) -> None:
        self._repair_folds = _check_flag("repair_folds", on)

    def load(self) -> None:
        """Create and validate the sessions now (otherwise done on the first prediction): both networks and, when
        the folder has one, the router (its specialists are checked to exist and loaded when first routed to).

        Raises:
            ModelError: missing folder/files, corrupt or non-conforming models.
        """
        with self._load_lock:
            if self._generator is not None and self._predictor is not None:
                return
            _, pred_path = model_paths(self._models_dir)
            import engine.postprocess  # noqa: F401  refinement's self-intersection check: its scipy import stays out of the first prediction
            generator = load_runtime_generator(self._models_dir, self._threads)
            predictor = load_predictor(pred_path, self._threads)
            rpath = router_path(self._models_dir)
            self._router = load_router(rpath, self._threads) if rpath is not None else None
            self._generator, self._predictor = generator, predictor

    def _specialist(self, name: str) -> LoadedModel:
        """The router's specialist ``name``, loaded and checked against the main predictor's template on first use."""
        with self._load_lock:
            model = self._specialists.get(name)
            if model is None:
                if name in self._specialist_errors:
                    raise self._specialist_errors[name]
                try:
                    model = load_predictor(self._models_dir / name, self._threads)
                    main = self._predictor
                    if (model.template_level, model.template_radius) != (main.template_level, main.template_radius):
                        raise ModelError(
                            f"{model.path}: template level {model.template_level} radius {model.template_radius} "
                            f"differs from {main.path.name}'s ({main.template_level}, {main.template_radius}); a "
                            "specialist must deform the same sphere")
                except ModelError as exc:
                    self._specialist_errors[name] = exc
                    raise
                self._specialists[name] = model
            return model

    def _route(self, small: np.ndarray) -> tuple[str | None, str]:
        """(specialist file or None, most likely category) of (n, 3, 64, 64) predictor inputs of one drawing (n = 1, or
        2 with its flip), routed on the rows' mean probabilities; call under _run_lock."""
        router = self._router
        (probs,) = _run_batch(router, [C.ROUTER_OUTPUT], small)
        probs = np.asarray(probs, np.float64)
        if probs.shape != (len(small), len(router.categories)):
            raise ModelError(f"{router.path}: router output must be {len(router.categories)} finite probabilities, "
                             f"got shape {np.shape(probs)}")
        if not np.all(np.isfinite(probs)):
            raise ModelError(f"{router.path}: router output must be {len(router.categories)} finite probabilities, "
                             "got NaN or inf (broken model?)")
        sums = probs.sum(axis=1)
        worst = int(np.argmax(np.abs(sums - 1.0)))
        if probs.min() < -1e-6 or abs(sums[worst] - 1.0) > 1e-3:
            raise ModelError(f"{router.path}: router output must be probabilities that sum to 1 (a softmax), got sum "
                             f"{sums[worst]:.4g} and min {probs.min():.4g}")
        p = probs.mean(axis=0)
        best, best_p = None, router.route_threshold
        for name, group in router.routes.items():
            q = float(sum(p[router.categories.index(c)] for c in group))
            if q > best_p:
                best, best_p = name, q
        return best, router.categories[int(np.argmax(p))]

    @property
    def is_loaded(self) -> bool:
        return self._generator is not None and self._predictor is not None

    def model_info(self) -> dict:
        """Paths, metadata, shapes and template level of both models (loads them if needed)."""
        self.load()
        return {
            "models_dir": str(self._models_dir),
            "threads": self._threads,
            "generator": self._generator.info(),
            "predictor": self._predictor.info(),
            "template_level": self._predictor.template_level,
            "template_radius": self._predictor.template_radius,
            "router": self._router.info() if self._router is not None else None,
        }

    def clear_cache(self) -> None:
        with self._cache_lock:
            self._cache.clear()

    def _run_models(self, raster: np.ndarray, timings: dict[str, float], mirror: bool) -> _Entry:
        gen, pred = self._generator, self._predictor
        x = raster[None, None].astype(np.float32)
        if mirror:  # the flipped drawing in the same batch: one run of each network serves both (module doc)
            x = np.concatenate([x, x[..., ::-1]])
        n = len(x)
        route, category = None, None
        with self._run_lock:
            t0 = time.perf_counter()
            (normals,) = _run_batch(gen, [C.GENERATOR_OUTPUT], x)
            t1 = time.perf_counter()
            expected = (n, 3, C.SKETCH_SIZE, C.SKETCH_SIZE)
            if normals.shape != expected:
                raise ModelError(f"{gen.path}: generator output must be {expected}, got {normals.shape}")
            if not np.all(np.isfinite(normals)):
                raise ModelError(f"{gen.path}: the generator produced NaN or inf (broken model?)")
            normals = np.clip(normals, 0.0, 1.0).astype(np.float32, copy=False)
            small = np.concatenate([downsample_normals(normals[i:i + 1]) for i in range(n)])
            t2 = time.perf_counter()
            if self._router is not None:  # the plain drawing is routed (with its flip: route_mirror); both follow it
                route, category = self._route(small if self._router.route_mirror else small[:1])
                if route is not None:  # the load lock is never held while waiting for the run lock
                    pred = self._specialist(route)
            local, glob = _run_batch(pred, pred.output_names, small)
            t3 = time.perf_counter()
            if len(local) != n or len(glob) != n:
                raise ModelError(f"{pred.path}: a batch of {n} drawings gave {len(local)} local and {len(glob)} global "
                                 "offsets (a predictor must keep the batch dimension)")
        meshes = [assemble_mesh(local[i:i + 1], glob[i:i + 1], pred.template_level, pred.template_radius)
                  for i in range(n)]
        mesh = meshes[0]
        if mirror:
            mesh = Mesh(mirror_average(meshes[0].vertices, meshes[1].vertices).astype(np.float32), mesh.faces)
        t4 = time.perf_counter()
        kept = normals[:1].copy()  # not a view: the cache keeps one image, not the batch
        kept.setflags(write=False)
        timings.update(zip(("generator", "downsample", "predictor", "assemble"),
                           ((t1 - t0) * 1e3, (t2 - t1) * 1e3, (t3 - t2) * 1e3, (t4 - t3) * 1e3)))
        return _Entry(mesh, kept, route, category)

    def predict(self, sketch, *, want_normals: bool = False, refine: int | None = None) -> Prediction:
        """Predict a mesh from a sketch.

        Args:
            sketch: a preprocessed (256, 256) float32 raster (1 = ink), a sequence of
                :class:`engine.strokes.Stroke`, or a path to an image file.
            want_normals: also return the (256, 256, 3) normal image.
            refine: refinement steps (:mod:`engine.refine`; 0 = off); None uses :attr:`refine_steps`.

        Returns:
            A :class:`Prediction`; ``cached`` is True when the same raster was seen recently with
            the same :attr:`mirror_average` and :attr:`repair_folds` settings.

        Raises:
            SketchInputError / EmptySketchError: unusable or blank sketch.
            ModelError: missing or broken models.
        """
        steps = self._refine_steps if refine is None else _check_steps(refine)
        t0 = time.perf_counter()
        raster = to_raster(sketch, self._rasterize)
        raster = np.array(raster, dtype=np.float32)
        raster.setflags(write=False)
        mirror, repair = self._mirror_average, self._repair_folds
        key = raster_key(raster) + (":mirror" if mirror else "") + (":repair" if repair else "")
        timings = {"preprocess": (time.perf_counter() - t0) * 1e3}
        self.load()
        entry = None
        if self._cache_size:
            with self._cache_lock:
                entry = self._cache.get(key)
                if entry is not None:
                    self._cache.move_to_end(key)
        cached = entry is not None
        if cached:
            timings.update({s: 0.0 for s in STAGES[1:]})
        else:
            entry = self._run_models(raster, timings, mirror)
            if self._cache_size:
                with self._cache_lock:
                    self._cache[key] = entry
                    self._cache.move_to_end(key)
                    while len(self._cache) > self._cache_size:
                        self._cache.popitem(last=False)
        mesh, warnings = entry.mesh, ()
        timings["refine"] = timings["repair"] = 0.0
        if steps:
            with self._cache_lock:
                result = entry.refined.get(steps)
            if result is None:
                t1 = time.perf_counter()
                result = refine_prediction(entry.mesh, raster, entry.normals_nchw, steps)
                timings["refine"] = (time.perf_counter() - t1) * 1e3
                with self._cache_lock:
                    entry.refined[steps] = result
            mesh = result.mesh
            warnings = (result.warning,) if result.warning else ()
        if repair:
            from engine.postprocess import repair_folds

            with self._cache_lock:
                fixed = entry.repaired.get(steps)
            if fixed is None:
                t1 = time.perf_counter()
                fixed = repair_folds(mesh, result.crossings if steps else None)  # none counted: nothing to check
                timings["repair"] = (time.perf_counter() - t1) * 1e3
                with self._cache_lock:
                    entry.repaired[steps] = fixed
            mesh = fixed.mesh
            if fixed.after:
                warnings += (f"the surface still crosses itself ({fixed.after} face pairs, {fixed.before} before "
                             "the fold repair)",)
        return Prediction(
            mesh=mesh,
            normals=np.ascontiguousarray(entry.normals_nchw[0].transpose(1, 2, 0)) if want_normals else None,
            sketch=raster,
            timings_ms={s: float(timings[s]) for s in STAGES},
            cached=cached,
            warnings=warnings,
            mirror_average=mirror,
            repair_folds=repair,
            route=entry.route,
            category=entry.category,
        )
