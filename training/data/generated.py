"""Predictor inputs as the app sees them: the generator's own normal images of a dataset's sketches.

The mesh predictor is pre-trained on ground-truth normal images, but in the app it reads what the
generator draws from a hand-drawn sketch: softer, noisier and sometimes wrong. This module runs a
generator (an ONNX model folder, through the app's own engine code: clip to [0, 1], area-average
to 64 x 64) once over the hand-drawn-augmented sketch of every view of a split and keeps the
results beside the dataset, so a mesh-mode run can read them as its input
(``TrainConfig.input_normals``) while its targets stay the true normal images and silhouettes::

    DIR/.cache/generated/NAME/normals64.npy   (N, s, s, 3) float16, row r = row r of the mesh-array cache
    DIR/.cache/generated/NAME/done.npy        (N,) bool: rows written
    DIR/.cache/generated/NAME/info.json       generator (path, sha256), augmentation, seed, rows, mirror

A mirrored set (``mirror=True``) holds the generator's images of the same drawings flipped left to
right: the exact input of a mirrored training item (:mod:`training.data.mirror`), where flipping
the generator's image of the unflipped drawing only approximates what the generator makes of the
flipped one (the generator is not mirror-equivariant). Pair it with its unmirrored partner through
``TrainConfig.mirror_inputs``.

On a GPU machine (``torch_generator``; ``data generated --torch-device``) the same network runs in torch
instead: the caller rebuilds the generator from the ONNX file (:func:`training.export.from_onnx.generator_from_onnx`,
the weights ``import-models`` reads) and moves it to the GPU; the worker processes still draw the sketches, and the
rows agree with ONNX Runtime's within their float16 storage. There, ONNX Runtime on the CPU cores is most of the
cost of a set (about 220 views a second on 16 cores).

A grown dataset need not run the generator again over the shapes it shares with the one it grew from
(``reuse_from``; ``data generated --reuse``): the rows of every shape whose file is the same file in the other
dataset (a hard link, or equal bytes) are copied from that dataset's set of the same name, built with the same
generator, augmentation, seed and mirroring. They are that dataset's draws of the hand-drawn augmentation (its row
numbers seed them), as good a draw as this dataset's own and the same bytes on every rebuild: copied rows overwrite
whatever a row held before, so the result does not depend on how far an earlier call got. ``info.json`` names the
source under ``reused_from``.

Building resumes: rows are written shape by shape and ``done.npy`` is replaced atomically after
them, so a killed build keeps what it finished. A folder made from another generator, augmentation,
seed, mirroring or dataset state is refused with a message naming the difference.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import time
from pathlib import Path

import numpy as np

from engine.fileio import atomic_write_bytes, atomic_write_text
from engine.models import file_sha256
from training.data.dataset import DatasetError, load_manifest

GENERATED_DIR = "generated"
FORMAT = "sketchmesh-generated-normals-1"
ROW_SEED = 15485863
"""Mixed into a row's augmentation seed, so a row's sketch differs from the dataset's load-time one."""


def generated_dir(root: str | os.PathLike, name: str) -> Path:
    """Where the generated inputs ``name`` of the dataset ``root`` live."""
    if not name or "/" in name or name.startswith("."):
        raise DatasetError(f"generated-normals name must be a plain folder name, got {name!r}")
    return Path(root) / ".cache" / GENERATED_DIR / name


def _save_done(folder: Path, done: np.ndarray) -> None:
    buf = io.BytesIO()
    np.save(buf, done)
    atomic_write_bytes(folder / "done.npy", buf.getvalue())


class GeneratedNormals:
    """An opened set of generated inputs: ``normals64`` (N, s, s, 3) float16 map, ``done`` (N,) bool."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        try:
            self.info = json.loads((folder / "info.json").read_text())
            self.normals64 = np.load(folder / "normals64.npy", mmap_mode="r")
            self.done = np.load(folder / "done.npy")
        except (OSError, ValueError) as exc:
            raise DatasetError(f"{folder}: not a generated-normals folder ({type(exc).__name__}: {exc}); "
                               "build it with `sketchmesh data generated`") from None
        if self.done.shape != (self.normals64.shape[0],):
            raise DatasetError(f"{folder}: done.npy has {self.done.shape}, normals64.npy {self.normals64.shape} rows")

    def rows(self, rows: np.ndarray) -> np.ndarray:
        """(len(rows), 3, s, s) float32 inputs of these mesh-cache rows; an unwritten row is an error."""
        rows = np.asarray(rows, np.int64)
        if not self.done[rows].all():
            missing = int(rows[~self.done[rows]][0])
            raise DatasetError(f"{self.folder}: row {missing} was not generated (its split was not built, or the "
                               "build was stopped): run `sketchmesh data generated` for that split")
        return np.ascontiguousarray(self.normals64[rows].transpose(0, 3, 1, 2), np.float32)

    def __reduce__(self):  # a DataLoader worker maps the file again
        return GeneratedNormals, (self.folder,)


def open_generated(root: str | os.PathLike, name: str) -> GeneratedNormals:
    """The generated inputs ``name`` of dataset ``root`` (or ``name`` as a folder path)."""
    if "/" in name and Path(name).is_dir():  # a folder given by its path
        folder = Path(name)
    else:
        folder = generated_dir(root, name)
    if not folder.is_dir():
        raise DatasetError(f"no generated normals {name!r} in {root} (build them with "
                           f"`sketchmesh data generated {root} --models DIR --name {name}`)")
    return GeneratedNormals(folder)


# ---- building ---------------------------------------------------------------------------------

_WORKER: dict = {}


def _worker_init(generator_path: str, threads: int) -> None:
    from engine.models import load_generator

    _WORKER["gen"] = load_generator(generator_path, threads=threads)


def _sketches(args: tuple) -> tuple[str, np.ndarray]:
    """(file, (views, S, S) float32): one shape file's augmented sketches (flipped left to right when mirrored)."""
    path, file, first, n_views, strength, seed, _small, mirror = args
    from training.data.augment import render_sketch
    from training.data.render import view_polylines

    with np.load(path) as z:
        arrays = {k: z[k] for k in ("view_poly_offsets", "poly_offsets", "poly_points")}
        size = int(z["sketch"].shape[-1])
    out = np.empty((n_views, size, size), np.float32)
    for v in range(n_views):
        sketch = render_sketch(view_polylines(arrays, v), size, strength, [seed, ROW_SEED, first + v])
        # a mirrored row: the same drawing, flipped left to right (pixel centres are symmetric about the middle)
        out[v] = sketch[..., ::-1] if mirror else sketch
    return file, out


def _shape_rows(args: tuple) -> tuple[str, np.ndarray]:
    """(file, (views, s, s, 3) float16) for one shape file: augmented sketches through the generator (ONNX Runtime)."""
    from engine.pipeline import downsample_normals

    small = args[6]
    gen = _WORKER["gen"]
    file, sketches = _sketches(args)
    out = np.empty((len(sketches), small, small, 3), np.float16)
    for v, sketch in enumerate(sketches):
        (normals,) = gen.session.run(None, {gen.input_name: np.ascontiguousarray(sketch)[None, None]})
        if not np.all(np.isfinite(normals)):
            raise DatasetError(f"{gen.path}: the generator produced NaN or inf for {file} view {v}")
        small_img = downsample_normals(np.clip(normals, 0.0, 1.0).astype(np.float32), small)
        out[v] = small_img[0].transpose(1, 2, 0)
    return file, out


TORCH_BATCH = 64
"""Sketches per forward pass of the torch runner (256 x 256: about 0.1 GB of activations at width 16)."""


def _torch_rows(net, device, file: str, sketches: np.ndarray, small: int) -> np.ndarray:
    """(views, s, s, 3) float16: the engine's rows computed in torch (clip to [0, 1], then the area average, which for
    an integer factor is the mean of each block, as OpenCV's INTER_AREA)."""
    import torch
    import torch.nn.functional as F

    size = sketches.shape[-1]
    if size % small:
        raise DatasetError(f"the torch runner needs the sketch side ({size}) to be a multiple of {small}")
    out = []
    with torch.no_grad():
        for i in range(0, len(sketches), TORCH_BATCH):
            x = torch.from_numpy(np.ascontiguousarray(sketches[i:i + TORCH_BATCH]))[:, None].to(device)
            y = net(x).float()
            if not bool(torch.isfinite(y).all()):
                raise DatasetError(f"the generator produced NaN or inf for {file} (torch on {device})")
            y = F.avg_pool2d(y.clamp(0.0, 1.0), size // small)
            out.append(y.permute(0, 2, 3, 1).cpu().numpy().astype(np.float16))
    return np.concatenate(out)


def build_generated(root: str | os.PathLike, models_dir: str | os.PathLike, name: str, *, split: str = "train",
                    augment_strength: float = 0.5, seed: int = 0, workers: int = 1, progress: bool = True,
                    max_shapes: int | None = None, mirror: bool = False, torch_generator=None,
                    reuse_from: str | os.PathLike | None = None) -> dict:
    """Run the generator of ``models_dir`` over every view of ``split`` of the dataset ``root``; resumable.

    Args:
        root: dataset folder.
        models_dir: an ONNX model folder (its ``generator.onnx``; the predictor is not used).
        name: folder name under ``root/.cache/generated``.
        split: "train", "val", "test" or "all".
        augment_strength: hand-drawn augmentation of the sketches, in [0, 1] (training's default 0.5).
        seed: augmentation seed.
        workers: processes, one ONNX Runtime thread each.
        progress: tqdm bar.
        max_shapes: only the first this many shapes still to do (a bounded call; it resumes later).
        mirror: run the generator on every drawing flipped left to right (module doc).
        torch_generator: a torch module computing the generator of ``models_dir`` (module doc), run on the device
            its parameters are on instead of ONNX Runtime; the workers then only draw the sketches.
        reuse_from: another dataset folder whose generated set ``name`` (same settings) supplies the rows of the shapes
            both hold in the same file, copied before anything is generated (module doc).

    Returns:
        {"written": views this call, "done": views of the split done, "views": views of the split, "seconds",
        "reused": views copied from ``reuse_from``}.

    Raises:
        DatasetError: bad arguments, a missing generator, or a folder built with other settings.
    """
    from tqdm import tqdm

    from engine.models import model_paths, resolve_models_dir
    from training.data.mesh_cache import open_mesh_cache

    if split not in ("train", "val", "test", "all"):
        raise DatasetError(f"split must be 'train', 'val', 'test' or 'all', got {split!r}")
    if not (np.isfinite(augment_strength) and 0.0 <= augment_strength <= 1.0):
        raise DatasetError(f"augment_strength must be in [0, 1], got {augment_strength}")
    if workers < 1:
        raise DatasetError(f"workers must be >= 1, got {workers}")
    root = Path(root)
    manifest = load_manifest(root)
    gen_path, _ = model_paths(resolve_models_dir(models_dir))
    net, device = torch_generator, None
    if net is not None:
        device = next(net.parameters()).device
        net.eval()
    arrays = open_mesh_cache(root, manifest)
    n_rows = int(arrays.normals64.shape[0])
    small = int(arrays.normals64.shape[1])
    info = {"format": FORMAT, "generator": str(gen_path.resolve()), "generator_sha256": file_sha256(gen_path),
            "augment_strength": float(augment_strength), "seed": int(seed), "rows": n_rows, "small_size": small,
            "row_files": hashlib.sha256(json.dumps(sorted(arrays.rows.items())).encode()).hexdigest(),
            "mirror": bool(mirror)}
    folder = generated_dir(root, name)
    if (folder / "info.json").exists():
        old = json.loads((folder / "info.json").read_text())
        old.setdefault("mirror", False)  # folders built before mirrored sets existed
        diff = [k for k in info if k != "generator" and old.get(k) != info[k]]
        if diff:
            raise DatasetError(f"{folder} was built with other {', '.join(diff)}; choose another --name or delete it")
        normals = np.load(folder / "normals64.npy", mmap_mode="r+")
        done = np.load(folder / "done.npy")
    else:
        folder.mkdir(parents=True, exist_ok=True)
        normals = np.lib.format.open_memmap(folder / "normals64.npy", mode="w+", dtype=np.float16,
                                            shape=(n_rows, small, small, 3))
        done = np.zeros(n_rows, bool)
        _save_done(folder, done)
        atomic_write_text(folder / "info.json", json.dumps(info, indent=1) + "\n")
    shapes = [s for s in manifest["shapes"] if split == "all" or s["split"] == split]
    t0 = time.perf_counter()
    reused = 0
    if reuse_from is not None:
        reused = _reuse_rows(root, folder, info, arrays.rows, shapes, normals, done, Path(reuse_from), name, progress)
    todo = []
    for s in shapes:
        first, nv = arrays.rows[s["file"]]
        if not done[first:first + nv].all():
            todo.append((str(root / s["file"]), s["file"], first, nv, float(augment_strength), int(seed), small,
                         bool(mirror)))
    if max_shapes is not None:
        todo = todo[:max_shapes]
    total_views = sum(arrays.rows[s["file"]][1] for s in shapes)
    written = 0
    bar = tqdm(total=len(todo), desc=f"generated normals ({split})", unit="shape", disable=not progress)
    last_save = time.monotonic()

    def record(file: str, block: np.ndarray) -> None:
        nonlocal written, last_save
        first, nv = arrays.rows[file]
        normals[first:first + nv] = block
        done[first:first + nv] = True
        written += nv
        bar.update(1)
        if time.monotonic() - last_save > 10:  # rows first, then the mask that says they are there
            normals.flush()
            _save_done(folder, done)
            last_save = time.monotonic()

    if net is not None:  # the workers only draw; torch runs the generator here
        work, init, initargs = _sketches, None, ()

        def handle(file: str, sketches: np.ndarray) -> None:
            record(file, _torch_rows(net, device, file, sketches, small))
    else:  # the workers draw and run the generator (ONNX Runtime, one thread each)
        work, init, initargs, handle = _shape_rows, _worker_init, (str(gen_path), 1), record
    try:
        if workers > 1 and len(todo) > 1:
            import multiprocessing as mp

            with mp.get_context("spawn").Pool(workers, initializer=init, initargs=initargs) as pool:
                for file, block in pool.imap_unordered(work, todo):
                    handle(file, block)
        else:
            if net is None:
                _worker_init(str(gen_path), 2 if workers == 1 else 1)
            for t in todo:
                handle(*work(t))
    finally:
        normals.flush()
        _save_done(folder, done)
        bar.close()
    views_done = 0
    for s in shapes:
        first, nv = arrays.rows[s["file"]]
        views_done += int(done[first:first + nv].sum())
    return {"written": written, "done": views_done, "views": total_views, "seconds": time.perf_counter() - t0,
            "reused": reused}


def _same_file(a: Path, b: Path) -> bool:
    """True when ``a`` and ``b`` are one file (a hard link) or hold equal bytes."""
    try:
        if os.path.samefile(a, b):
            return True
        return a.stat().st_size == b.stat().st_size and file_sha256(a) == file_sha256(b)
    except OSError:
        return False


def _reuse_rows(root: Path, folder: Path, info: dict, rows: dict, shapes: list, normals, done: np.ndarray,
                other_root: Path, name: str, progress: bool) -> int:
    """Copy into ``normals``/``done`` the rows of ``shapes`` that ``other_root``'s set ``name`` holds for the same file;
    returns the views copied. The other set must have been built with this one's settings (module doc)."""
    from tqdm import tqdm

    from training.data.mesh_cache import open_mesh_cache

    if other_root.resolve() == root.resolve():
        raise DatasetError(f"--reuse {other_root} is the dataset being built")
    other = open_generated(other_root, name)
    diff = [k for k in ("generator_sha256", "augment_strength", "seed", "small_size", "mirror")
            if other.info.get(k, False if k == "mirror" else None) != info[k]]
    if diff:
        raise DatasetError(f"{other.folder} was built with other {', '.join(diff)} than {folder}; it cannot be reused")
    other_rows = open_mesh_cache(other_root, load_manifest(other_root)).rows
    copied = 0
    for s in tqdm(shapes, desc="reused rows", unit="shape", disable=not progress):
        f = s["file"]
        if f not in other_rows:
            continue
        (first, nv), (ofirst, onv) = rows[f], other_rows[f]
        if nv != onv or not other.done[ofirst:ofirst + onv].all() or not _same_file(root / f, other_root / f):
            continue
        normals[first:first + nv] = other.normals64[ofirst:ofirst + nv]
        done[first:first + nv] = True
        copied += nv
    normals.flush()  # rows first, then the mask that says they are there
    _save_done(folder, done)
    meta = json.loads((folder / "info.json").read_text())
    source = str(other.folder.resolve())
    if source not in meta.get("reused_from", []):
        meta["reused_from"] = [*meta.get("reused_from", []), source]
        atomic_write_text(folder / "info.json", json.dumps(meta, indent=1) + "\n")
    return copied
