"""The training dataset on disk: building it (resumable, sharded, parallel), merging shards, loading it.

Format (full description in docs/DATA_FORMAT.md)::

    DIR/manifest.json                      written atomically; settings + one record per shape and per view
    DIR/shapes/<category>/<shape_id>.npz   one compressed file per shape holding all of its views

Building is resumable: a shape whose file exists, opens, has every key and was rendered with
the same settings is skipped; each shape file is written atomically (engine.fileio), so an
interrupted run leaves no half-written file.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import warnings
import zlib
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from engine.contract import CONVENTIONS_ID
from engine.errors import SketchmeshError
from engine.fileio import atomic_open, atomic_write_text
from engine.mesh import Mesh

FORMAT_ID = "sketchmesh-data-1"
MANIFEST = "manifest.json"
SHAPES_DIR = "shapes"

SHAPE_KEYS: tuple[str, ...] = (
    "sketch", "normals256", "silhouette256", "normals64", "silhouette64", "cameras", "azimuths", "elevations",
    "poly_points", "poly_offsets", "poly_kinds", "view_poly_offsets", "vertices", "faces", "meta",
)
"""Keys every shape file holds (``sketch_aug`` is added when built with --augment-strength > 0)."""


class DatasetError(SketchmeshError):
    """A dataset folder is missing, corrupt, or does not match what was asked for."""


# --------------------------------------------------------------------------- splits and jobs
def split_of_id(category: str, shape_id: str) -> str:
    """Deterministic 80/10/10 split of a loaded (ShapeNet / folder) shape by a hash of its id."""
    h = zlib.crc32(f"split:{category}:{shape_id}".encode()) % 1000
    return "train" if h < 800 else ("val" if h < 900 else "test")


@dataclass(frozen=True)
class Job:
    """One shape to render: where it comes from and where it goes."""

    category: str
    shape_id: str
    split: str
    source: str  # "procedural" or "file"
    index: int = -1  # procedural index
    path: str = ""  # mesh file for "file" sources

    def load(self) -> Mesh:
        if self.source == "procedural":
            from training.data.shapes import make_shape

            return make_shape(self.category, self.index)
        from training.data.loaders import load_mesh_file

        return load_mesh_file(self.path)


def parse_source(source: str) -> tuple[str, str]:
    """``procedural`` | ``shapenet:PATH`` | ``meshes:PATH`` -> (kind, path)."""
    if source == "procedural":
        return "procedural", ""
    kind, sep, path = source.partition(":")
    if not sep or kind not in ("shapenet", "meshes") or not path:
        raise DatasetError(f"bad --source {source!r}: expected 'procedural', 'shapenet:PATH' or 'meshes:PATH'")
    return kind, path


def make_jobs(source: str, shapes_per_category: int | None = None, categories: Sequence[str] | None = None,
              first_shape: int = 0) -> list[Job]:
    """Every shape of a source, sorted (category, shape_id). Raises DatasetError / MeshInputError on bad sources.

    ``first_shape`` (procedural only): the shapes of each category start at this index, so a build from index N
    holds shapes no build of N per category holds (ids and splits are per index, as in a build from 0).
    """
    kind, path = parse_source(source)
    if first_shape < 0:
        raise DatasetError(f"--first-shape must be >= 0, got {first_shape}")
    if first_shape and kind != "procedural":
        raise DatasetError(f"--first-shape is for the procedural source only, not {source!r}")
    if kind == "procedural":
        from training.data.shapes import CATEGORIES, shape_id, split_of

        n = 10 if shapes_per_category is None else int(shapes_per_category)
        if n <= 0:
            raise DatasetError(f"--shapes-per-category must be > 0, got {n}")
        cats = list(categories) if categories else list(CATEGORIES)
        bad = sorted(set(cats) - set(CATEGORIES))
        if bad:
            raise DatasetError(f"unknown categories {bad}; expected some of {', '.join(CATEGORIES)}")
        return [Job(c, shape_id(c, i), split_of(c, i), "procedural", index=i)
                for c in cats for i in range(first_shape, first_shape + n)]
    from training.data.loaders import scan_mesh_folder, scan_shapenet

    records = scan_shapenet(path, categories) if kind == "shapenet" else scan_mesh_folder(path)
    if kind == "meshes" and categories:
        records = [r for r in records if r.category in set(categories)]
    jobs = []
    per_cat: dict[str, int] = {}
    for r in records:
        if shapes_per_category is not None and per_cat.get(r.category, 0) >= shapes_per_category:
            continue
        per_cat[r.category] = per_cat.get(r.category, 0) + 1
        sid = _safe_id(r.shape_id)
        jobs.append(Job(r.category, sid, split_of_id(r.category, sid), "file", path=str(r.path)))
    return jobs


def _safe_id(s: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in s)


def parse_shard(text: str | None) -> tuple[int, int]:
    """``"K/N"`` (0 <= K < N) -> (K, N); None -> (0, 1)."""
    if text is None:
        return 0, 1
    try:
        k, n = (int(x) for x in text.split("/"))
    except ValueError:
        raise DatasetError(f"bad --shard {text!r}: expected K/N with 0 <= K < N, e.g. 0/4") from None
    if not (n >= 1 and 0 <= k < n):
        raise DatasetError(f"bad --shard {text!r}: expected K/N with 0 <= K < N, e.g. 0/4")
    return k, n


def shape_file(root: Path, category: str, shape_id: str) -> Path:
    return Path(root) / SHAPES_DIR / category / f"{shape_id}.npz"


# --------------------------------------------------------------------------- building
@dataclass(frozen=True)
class BuildSettings:
    """Settings recorded in every shape file and the manifest; a resumed run must match them."""

    size: int = 256
    small_size: int = 64
    num_azimuths: int = 24
    elevations: tuple[float, ...] = (30.0,)
    augment_strength: float = 0.0
    seed: int = 0
    views_per_shape: int = 0

    @property
    def grid_size(self) -> int:
        """Views of the full grid: ``num_azimuths`` at each of ``elevations``."""
        return self.render_settings().num_views

    @property
    def shape_views(self) -> int:
        """Views rendered per shape: ``views_per_shape`` of the grid, or all of it (0)."""
        return int(self.views_per_shape) or self.grid_size

    def check(self) -> None:
        """Raise ValueError for settings no build can use (the render settings' own checks included)."""
        self.render_settings()
        if not isinstance(self.views_per_shape, (int, np.integer)) or not 0 <= self.views_per_shape <= self.grid_size:
            raise ValueError(f"views per shape must be between 1 and the grid's {self.grid_size} views "
                             f"({self.num_azimuths} azimuths x {len(self.elevations)} elevations), got {self.views_per_shape}")

    def grid_views(self, category: str, shape_id: str) -> list[int] | None:
        """The grid views one shape is rendered at (indices, see :func:`training.data.render.view_cameras`).

        None (every view) unless ``views_per_shape`` is set. Otherwise a draw without replacement
        that depends only on the seed and the shape, so a resumed or sharded build renders the same
        views; when ``views_per_shape`` is a multiple of the elevations it takes as many azimuths at
        each elevation (the elevations stay as evenly covered as in the full grid), else any of the
        grid's views. Sorted (elevation-major, like the full grid).
        """
        k = int(self.views_per_shape)
        if k == 0 or k == self.grid_size:
            return None
        rng = np.random.default_rng([int(self.seed), _shape_hash(category, shape_id), 0x5EED])
        n_az, n_el = int(self.num_azimuths), len(self.elevations)
        if k % n_el == 0:
            picks = [e * n_az + int(a) for e in range(n_el) for a in rng.choice(n_az, k // n_el, replace=False)]
        else:
            picks = rng.choice(n_az * n_el, k, replace=False).tolist()
        return sorted(int(i) for i in picks)

    def render_settings(self):
        from training.data.render import RenderSettings

        return RenderSettings(size=self.size, small_size=self.small_size, num_azimuths=self.num_azimuths,
                              elevations=tuple(float(e) for e in self.elevations))

    def to_json(self) -> str:
        d = asdict(self)
        d["elevations"] = [float(e) for e in self.elevations]
        if not self.views_per_shape:  # every view of the grid: as recorded before the option existed
            del d["views_per_shape"]
        d["conventions"] = CONVENTIONS_ID
        d["format"] = FORMAT_ID
        from training.data.shapes import LIBRARY_VERSION  # light: manifold3d loads on first use

        d["shape_library"] = LIBRARY_VERSION  # procedural shapes of an older library are redone
        return json.dumps(d, sort_keys=True)


MIN_DISK_BYTES_PER_VIEW = 4096
"""A lower bound of one view's share of a compressed shape file at 256 x 256 (procedural shapes
take about 10 KB); scaled by the image area. A request whose lower bound exceeds the free disk
space is refused before anything is rendered."""

MEMORY_SHARE = 0.8
"""Largest share of the available memory the shapes being rendered at once may take."""


def available_memory_bytes() -> int | None:
    """MemAvailable of /proc/meminfo (Linux), else free physical pages; None when unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def build_cost(n_shapes: int, settings: BuildSettings, workers: int = 1) -> dict[str, int]:
    """What a build request will take, estimated before any work.

    Returns:
        dict: ``views`` (total), ``memory_per_shape`` (bytes of one shape's arrays while it is
        rendered and compressed), ``memory`` (that times the shapes rendered at once) and
        ``disk_min`` (a lower bound of the dataset's size on disk), all ints.
    """
    S, s = int(settings.size), int(settings.small_size)
    n_views = settings.shape_views
    per_view = S * S * (1 + 3 + 1 + (1 if settings.augment_strength > 0 else 0)) + s * s * (12 + 1) + 16 * 8 + 16
    per_shape = 2 * n_views * per_view + 64 * S * S  # arrays + their compressed copy + one view's render buffers
    return {
        "views": int(n_shapes) * n_views,
        "memory_per_shape": per_shape,
        "memory": per_shape * max(1, min(int(workers), int(n_shapes))),
        "disk_min": int(n_shapes) * n_views * MIN_DISK_BYTES_PER_VIEW * S * S // (256 * 256),
    }


def check_build_request(out: str | os.PathLike, n_shapes: int, settings: BuildSettings, workers: int = 1) -> dict:
    """Refuse, before any work, a build that cannot fit in memory or on disk. Returns :func:`build_cost`.

    Raises:
        DatasetError: naming the request, what it needs and what there is.
    """
    import shutil

    from engine.fileio import nearest_existing

    cost = build_cost(n_shapes, settings, workers)
    n_views = settings.shape_views
    gb = 1024**3
    memory = available_memory_bytes()
    if memory is not None and cost["memory"] > MEMORY_SHARE * memory:
        at_once = f" x {min(workers, n_shapes)} workers" if min(workers, n_shapes) > 1 else ""
        raise DatasetError(
            f"{n_views} views per shape at {settings.size}x{settings.size} need {cost['memory_per_shape'] / gb:,.1f} GB "
            f"of memory per shape{at_once}, more than the {memory / gb:,.1f} GB available; "
            "use fewer --views, --elevations or --views-per-shape, a smaller --size or fewer --workers")
    folder = nearest_existing(out)
    if folder.is_dir():
        free = shutil.disk_usage(folder).free
        if cost["disk_min"] > free:
            raise DatasetError(
                f"{n_shapes} shapes x {n_views} views need at least {cost['disk_min'] / gb:,.1f} GB on disk, "
                f"but {folder} has {free / gb:,.1f} GB free; ask for fewer shapes or views")
    return cost


def _shape_hash(category: str, shape_id: str) -> int:
    """A stable per-shape number for seeding (CRC32 of ``category/shape_id``)."""
    return zlib.crc32(f"{category}/{shape_id}".encode())


def _view_seed(seed: int, category: str, shape_id: str, view: int) -> list[int]:
    return [int(seed), _shape_hash(category, shape_id), int(view)]


def render_job(job: Job, settings: BuildSettings) -> dict:
    """Load and render one shape into the arrays of its shape file (raises on a bad mesh)."""
    from training.data.augment import render_sketch
    from training.data.render import quantize_unit, render_shape, view_polylines

    mesh = job.load()
    arrays = render_shape(mesh, settings.render_settings(), grid_views=settings.grid_views(job.category, job.shape_id))
    if settings.augment_strength > 0:
        arrays["sketch_aug"] = np.stack([
            quantize_unit(render_sketch(view_polylines(arrays, v), settings.size, settings.augment_strength,
                                        _view_seed(settings.seed, job.category, job.shape_id, v)))
            for v in range(len(arrays["cameras"]))
        ])
    meta = {"category": job.category, "shape_id": job.shape_id, "split": job.split, "source": job.source,
            "path": job.path, "index": job.index, "settings": json.loads(settings.to_json())}
    arrays["meta"] = np.array(json.dumps(meta, sort_keys=True))
    return arrays


def _readable(path: Path) -> None:
    """Give an atomically written file (created 0600 by mkstemp) the usual umask permissions."""
    mask = os.umask(0)
    os.umask(mask)
    try:
        os.chmod(path, 0o666 & ~mask)
    except OSError:  # not ours to change (e.g. another user's folder): leave it
        pass


def write_shape_file(path: Path, arrays: dict) -> None:
    """np.savez_compressed into ``path`` atomically."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    with atomic_open(path, "wb") as fh:
        fh.write(buf.getbuffer())
    _readable(path)


def read_meta(path: Path) -> dict | None:
    """The ``meta`` record of a shape file, or None when the file is missing, corrupt or incomplete."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if not set(SHAPE_KEYS) <= set(z.files):
                return None
            meta = json.loads(str(z["meta"]))
            meta["azimuths"] = z["azimuths"].tolist()
            meta["elevations"] = z["elevations"].tolist()
            return meta
    except Exception:  # a truncated or foreign file means "not done"
        return None


def _is_complete(path: Path, settings: BuildSettings) -> bool:
    meta = read_meta(path)
    if meta is None:
        return False
    return json.dumps(meta.get("settings"), sort_keys=True) == settings.to_json()


def _worker_init() -> None:
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover - the CLI checks torch first
        pass


def _run_job(args: tuple[Job, BuildSettings, str]) -> tuple[Job, str | None]:
    job, settings, root = args
    try:
        arrays = render_job(job, settings)
        write_shape_file(shape_file(Path(root), job.category, job.shape_id), arrays)
        return job, None
    except SketchmeshError as exc:
        return job, str(exc)
    except Exception as exc:  # one broken shape must not stop a long build
        return job, f"{type(exc).__name__}: {exc}"


def build_dataset(out: str | os.PathLike, jobs: Sequence[Job], settings: BuildSettings, workers: int = 1,
                  shard: tuple[int, int] = (0, 1), progress: bool = True) -> dict:
    """Render the jobs of this shard into ``out`` and (re)write its manifest.

    A shape that fails is skipped with a warning. Warnings wait for the first shape that renders:
    if none does and the folder holds no earlier shape, nothing is written (no empty manifest, and
    folders this call created are removed) and the caller gets the failures to report as one error.

    Args:
        out: dataset folder (created).
        jobs: all shapes (the shard takes every N-th starting at K).
        settings: render settings (recorded; shapes rendered with other settings are redone).
        workers: processes rendering shapes in parallel (each uses one torch thread).
        shard: (K, N).
        progress: show a tqdm bar.

    Returns:
        Summary dict: rendered, skipped (already complete), failed (list of (shape, reason)),
        shapes and views (in the manifest; 0 when nothing was written).
    """
    from tqdm import tqdm

    root = Path(out)
    created = _missing_folders(root)
    k, n = shard
    mine = [j for idx, j in enumerate(jobs) if idx % n == k]
    todo = [j for j in mine if not _is_complete(shape_file(root, j.category, j.shape_id), settings)]
    failed: list[tuple[str, str]] = []
    held: list[str] = []  # failure warnings, shown once some shape renders (else reported as one error)
    bar = tqdm(total=len(todo), desc=f"rendering shapes (shard {k}/{n})", unit="shape", disable=not progress)
    args = [(j, settings, str(root)) for j in todo]

    done = [0]

    def record(job: Job, err: str | None) -> None:
        done[0] += 1
        if err:
            failed.append((f"{job.category}/{job.shape_id}", err))
            held.append(f"skipping {job.category}/{job.shape_id}: {err}")
        if len(failed) < done[0]:  # a shape rendered: from now on failures are shown as they come
            for message in held:
                warnings.warn(message, stacklevel=3)
            held.clear()
        bar.update(1)

    if workers > 1 and len(todo) > 1:
        import multiprocessing as mp

        ctx = mp.get_context("spawn")
        with ctx.Pool(workers, initializer=_worker_init) as pool:
            for job, err in pool.imap_unordered(_run_job, args):
                record(job, err)
    else:
        for a in args:
            record(*_run_job(a))
    bar.close()
    rendered = len(todo) - len(failed)
    if todo and rendered == 0 and len(todo) == len(mine):  # every shape failed, none was there before
        if not (root / MANIFEST).exists():
            for folder in [*sorted(root.glob(f"{SHAPES_DIR}/*"), reverse=True), root / SHAPES_DIR, *created]:
                with contextlib.suppress(OSError):
                    folder.rmdir()  # only empty folders go
        return {"rendered": 0, "skipped": 0, "failed": failed, "shapes": 0, "views": 0}
    for message in held:
        warnings.warn(message, stacklevel=2)
    if failed:
        warnings.warn(f"{len(failed)} of {len(todo)} shapes failed and were skipped", stacklevel=2)
    manifest = write_manifest(root, settings)
    return {"rendered": rendered, "skipped": len(mine) - len(todo), "failed": failed,
            "shapes": len(manifest["shapes"]), "views": len(manifest["views"])}


def _missing_folders(path: Path) -> list[Path]:
    """``path`` and its ancestors that do not exist yet, deepest first."""
    missing = []
    p = Path(os.path.abspath(path))
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    return missing


def write_manifest(root: str | os.PathLike, settings: BuildSettings | None = None) -> dict:
    """Scan ``root/shapes`` and write ``root/manifest.json`` atomically (complete files only)."""
    root = Path(root)
    shapes, views = [], []
    recorded = None
    for path in sorted((root / SHAPES_DIR).glob("*/*.npz")):
        meta = read_meta(path)
        if meta is None:
            warnings.warn(f"ignoring incomplete or corrupt shape file {path}", stacklevel=2)
            continue
        if settings is not None and json.dumps(meta["settings"], sort_keys=True) != settings.to_json():
            warnings.warn(f"ignoring {path}: rendered with other settings", stacklevel=2)
            continue
        recorded = recorded or meta["settings"]
        if meta["settings"] != recorded:
            raise DatasetError(f"{path} was rendered with settings that differ from the other shapes")
        rel = str(path.relative_to(root))
        shapes.append({"category": meta["category"], "shape_id": meta["shape_id"], "split": meta["split"],
                       "file": rel, "num_views": len(meta["azimuths"])})
        for v, (az, el) in enumerate(zip(meta["azimuths"], meta["elevations"])):
            views.append({"category": meta["category"], "shape_id": meta["shape_id"], "split": meta["split"],
                          "azimuth": az, "elevation": el, "file": rel, "view": v})
    manifest = {"format": FORMAT_ID, "conventions": CONVENTIONS_ID,
                "settings": recorded if recorded is not None else (json.loads(settings.to_json()) if settings else None),
                "categories": sorted({s["category"] for s in shapes}), "shapes": shapes, "views": views}
    atomic_write_text(root / MANIFEST, json.dumps(manifest, indent=1))
    _readable(root / MANIFEST)
    return manifest


def merge_datasets(out: str | os.PathLike, shard_dirs: Sequence[str | os.PathLike]) -> dict:
    """Merge shard outputs into ``out``: copy (hard-link where possible) every complete shape file, rewrite the manifest.

    Raises:
        DatasetError: a shard folder has no manifest, or shards were rendered with different settings.
    """
    out = Path(out)
    settings = None
    copied = 0
    for d in shard_dirs:
        d = Path(d)
        manifest = load_manifest(d)
        if manifest["settings"] is not None:
            if settings is not None and manifest["settings"] != settings:
                raise DatasetError(f"{d}: rendered with different settings than the other shards")
            settings = manifest["settings"]
        for rec in manifest["shapes"]:
            src, dst = d / rec["file"], out / rec["file"]
            if dst.exists() and dst.resolve() == src.resolve():
                continue
            dst.parent.mkdir(parents=True, exist_ok=True)
            tmp = dst.with_name(f".{dst.name}.merge.tmp")
            try:
                if tmp.exists():
                    tmp.unlink()
                os.link(src, tmp)
            except OSError:
                shutil.copyfile(src, tmp)
            os.replace(tmp, dst)
            copied += 1
    manifest = write_manifest(out)
    return {"copied": copied, "shapes": len(manifest["shapes"]), "views": len(manifest["views"])}


def load_manifest(root: str | os.PathLike) -> dict:
    """Read ``root/manifest.json``; DatasetError naming the problem if it is missing or corrupt."""
    path = Path(root) / MANIFEST
    if not path.is_file():
        raise DatasetError(f"{root}: not a dataset folder (no {MANIFEST}; build one with `sketchmesh data --source ...`)")
    try:
        manifest = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise DatasetError(f"{path}: cannot read manifest ({exc})") from None
    if manifest.get("format") != FORMAT_ID:
        raise DatasetError(f"{path}: unknown dataset format {manifest.get('format')!r} (expected {FORMAT_ID})")
    return manifest


def check_dataset(root: str | os.PathLike, split: str = "train", categories: Sequence[str] | None = None,
                  what: str = "--data") -> dict:
    """Check, before any work, that a dataset folder is usable for ``split``; returns its manifest.

    Reads the manifest and the zip directory of every shape file of the split (a few ms per
    thousand shapes), so a folder that is empty, half-written (a build killed before its
    manifest, a shape file cut short) or of another format is refused with one message.

    Raises:
        DatasetError: naming ``what`` (the flag), the folder and the problem.
    """
    import zipfile

    root = Path(root)
    if not root.exists():
        raise DatasetError(f"{what} {root}: does not exist (create a dataset with: sketchmesh data --out {root})")
    if not root.is_dir():
        raise DatasetError(f"{what} {root}: is a file, expected a dataset folder")
    manifest = load_manifest(root)
    shapes = [r for r in manifest.get("shapes", []) if split == "all" or r.get("split") == split]
    if categories:
        present = sorted({r.get("category") for r in manifest.get("shapes", [])})
        missing = sorted(set(categories) - set(present))
        if missing:
            raise DatasetError(f"{what} {root}: categories {missing} are not in it (it has {', '.join(present) or 'none'})")
        shapes = [r for r in shapes if r.get("category") in set(categories)]
    if not shapes:
        raise DatasetError(f"{what} {root}: the {split} split has no shapes")
    wanted = {f"{k}.npy" for k in SHAPE_KEYS}
    for rec in shapes:
        path = root / str(rec.get("file", ""))
        try:
            with zipfile.ZipFile(path) as z:
                names = set(z.namelist())
        except FileNotFoundError:
            raise DatasetError(f"{what} {root}: shape file {rec.get('file')} is missing (half-written dataset? "
                               "rerun its `sketchmesh data` command to finish it)") from None
        except (OSError, zipfile.BadZipFile) as exc:
            raise DatasetError(f"{what} {root}: shape file {rec.get('file')} is cut short or corrupt ({exc}); "
                               "rerun its `sketchmesh data` command to redo it") from None
        if not wanted <= names:
            raise DatasetError(f"{what} {root}: shape file {rec.get('file')} lacks {sorted(wanted - names)[:3]}")
    return manifest


# --------------------------------------------------------------------------- loading
class ShapeFileCache:
    """Small per-process LRU of opened shape files; arrays are decoded on first use and kept."""

    def __init__(self, capacity: int = 8) -> None:
        self.capacity = int(capacity)
        self._pid = os.getpid()
        self._files: OrderedDict[str, dict] = OrderedDict()

    def __getstate__(self) -> dict:  # pickled into a spawned worker: open files stay here, the copy starts empty
        return {"capacity": self.capacity}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["capacity"])

    def get(self, path: str, key: str) -> np.ndarray:
        if os.getpid() != self._pid:  # forked into a DataLoader worker: never share open handles
            self._pid, self._files = os.getpid(), OrderedDict()
        entry = self._files.get(path)
        if entry is None:
            try:
                entry = {"npz": np.load(path, allow_pickle=False)}
            except Exception as exc:
                raise DatasetError(f"{path}: cannot open shape file ({type(exc).__name__}: {exc})") from None
            self._files[path] = entry
            while len(self._files) > self.capacity:
                _, old = self._files.popitem(last=False)
                old["npz"].close()
        else:
            self._files.move_to_end(path)
        if key not in entry:
            try:
                entry[key] = entry["npz"][key]
            except Exception as exc:
                raise DatasetError(f"{path}: cannot read {key!r} ({type(exc).__name__}: {exc})") from None
        return entry[key]


def _torch():
    from training._torch import require_torch

    return require_torch()


try:  # the Dataset base class, without importing torch for users of the pure-numpy parts
    from torch.utils.data import Dataset as _DatasetBase
except ImportError:  # pragma: no cover
    _DatasetBase = object


def _mesh_fields(torch, n64, s64, cams, row, others) -> dict:
    """The mesh-step tensors of one item: row ``row`` of the (views, ...) arrays and rows ``others``."""
    return {
        "normals64": torch.from_numpy(np.ascontiguousarray(n64[row].transpose(2, 0, 1), np.float32)),
        "silhouette64": torch.from_numpy(s64[row].astype(np.float32)),
        "camera": torch.from_numpy(cams[row].astype(np.float64)),
        "other_normals64": torch.from_numpy(np.ascontiguousarray(n64[others].transpose(0, 3, 1, 2), np.float32)),
        "other_silhouette64": torch.from_numpy(s64[others].astype(np.float32)),
        "other_cameras": torch.from_numpy(cams[others].astype(np.float64)),
    }


class ShapeViewDataset(_DatasetBase):
    """One item per (shape, view) of a split: sketch, normal images, silhouettes, cameras, other views.

    Args:
        root: dataset folder (with manifest.json).
        split: "train", "val", "test" or "all".
        extra_views: K, the number of other views of the same shape returned per item (>= 0).
        augment_strength: hand-drawn augmentation strength in [0, 1] applied to the sketch at
            load time from the stored polylines (0 returns the stored clean sketch).
        seed: augmentation / extra-view seed; item i always gets the same augmentation and the
            same other views (deterministic in (seed, i), independent of the epoch).
        categories: restrict to these categories (default all in the dataset).
        shape_ids: restrict to these shape ids (default all); an id not in the split is an error.
        fields: ``"all"`` (every key below), ``"mesh"`` (only what a mesh-mode step reads:
            ``normals64``, ``silhouette64``, ``camera``, their ``other_*`` and the names; no
            sketch is loaded or augmented, ``augment_strength`` is not used), or ``"sketch"``
            (``"mesh"``'s keys and the ``sketch``, from the shape files: the 256 px normal image
            and silhouette are not read; what an evaluation reads).
        mesh_cache: where ``fields="mesh"`` reads its arrays from: ``"auto"`` / ``"disk"`` /
            ``"memory"``, the per-dataset cache of :func:`training.data.mesh_cache.open_mesh_cache`
            (decompressed once, bit-identical to the shape files), or ``"none"`` (the shape files).
        input_normals: ``fields="mesh"`` only: the name (or folder) of a set of generated normal
            images (:mod:`training.data.generated`); items then also hold ``input64`` (3, s, s), the
            generator's image of the view's sketch, which a mesh-mode run feeds its predictor.
            Several sets (a sequence, or names joined by commas; e.g. other augmentation seeds)
            make the dataset every (view, set) pair: item ``i`` is view ``i % V`` with the input
            of set ``i // V`` (V views), so an epoch shows each view once per set.
        input_share: share of items whose ``input64`` is the generated image (the others get the
            true normal image), fixed per (seed, item); in (0, 1].
        mirror_inputs: with ``input_normals`` only: the mirrored sets (``sketchmesh data generated
            --mirror``), one per input set and in the same order, each built from the same
            generator, augmentation and seed as its partner. Items then also hold
            ``input64_mirror``, the input of the item's mirror image (:mod:`training.data.mirror`):
            the generator's image of the flipped drawing, or for an item that reads the true image
            the true image mirrored exactly.

    ``__getitem__(i)`` returns a dict of torch tensors (NCHW without N, float32 in [0, 1]):
    ``sketch`` (1, S, S) 1 = ink; ``normals`` (3, S, S); ``silhouette`` (1, S, S);
    ``normals64`` (3, s, s); ``silhouette64`` (s, s); ``camera`` (16,) float64 framed camera;
    ``other_normals64`` (K, 3, s, s); ``other_silhouette64`` (K, s, s); ``other_cameras``
    (K, 16) float64; and ``category`` str, ``shape_id`` str, ``view`` int. S = 256, s = 64 by default.
    ``item(i, fields)`` returns the item with other fields than the dataset's.

    Raises:
        DatasetError: bad arguments, categories not in the dataset, or ``extra_views`` larger
            than the other views a shape of the split has.
    """

    FIELDS = ("all", "mesh", "sketch")
    MESH_CACHES = ("auto", "disk", "memory", "none")

    def __init__(self, root, split: str = "train", *, extra_views: int = 1, augment_strength: float = 0.5,
                 seed: int = 0, categories: Sequence[str] | None = None, shape_ids: Sequence[str] | None = None,
                 fields: str = "all", mesh_cache: str = "auto", input_normals: str | Sequence[str] | None = None,
                 input_share: float = 1.0, mirror_inputs: str | Sequence[str] | None = None) -> None:
        self.root = Path(root)
        if split not in ("train", "val", "test", "all"):
            raise DatasetError(f"split must be 'train', 'val', 'test' or 'all', got {split!r}")
        if fields not in self.FIELDS:
            raise DatasetError(f"fields must be one of {self.FIELDS}, got {fields!r}")
        if mesh_cache not in self.MESH_CACHES:
            raise DatasetError(f"mesh_cache must be one of {self.MESH_CACHES}, got {mesh_cache!r}")
        if not isinstance(extra_views, (int, np.integer)) or extra_views < 0:
            raise DatasetError(f"extra_views must be an int >= 0, got {extra_views!r}")
        if not (np.isfinite(augment_strength) and 0.0 <= augment_strength <= 1.0):
            raise DatasetError(f"augment_strength must be in [0, 1], got {augment_strength}")
        self.manifest = load_manifest(self.root)
        present = sorted({s["category"] for s in self.manifest["shapes"]})
        if categories is not None:
            missing = sorted(set(categories) - set(present))
            if missing:
                raise DatasetError(f"categories {missing} are not in {self.root} (it has {', '.join(present) or 'none'})")
            wanted = set(categories)
        else:
            wanted = set(present)
        self.split = split
        self.extra_views = int(extra_views)
        self.augment_strength = float(augment_strength)
        self.seed = int(seed)
        self._shapes = [s for s in self.manifest["shapes"] if s["category"] in wanted and (split == "all" or s["split"] == split)]
        if shape_ids is not None:
            missing = sorted(set(shape_ids) - {s["shape_id"] for s in self._shapes})
            if missing:
                raise DatasetError(f"shapes {missing} are not in the {split} split of {self.root}")
            self._shapes = [s for s in self._shapes if s["shape_id"] in set(shape_ids)]
        self.categories = sorted({s["category"] for s in self._shapes})
        self._items = [(si, v) for si, s in enumerate(self._shapes) for v in range(int(s["num_views"]))]
        self._by_id = {(s["category"], s["shape_id"]): s for s in self._shapes}
        settings = self.manifest.get("settings") or {}
        self.size = int(settings.get("size", 256))
        self.small_size = int(settings.get("small_size", 64))
        self._cache = ShapeFileCache()
        fewest = min((int(r["num_views"]) for r in self._shapes), default=1)
        if self.extra_views > max(fewest - 1, 1):
            raise DatasetError(f"extra_views {self.extra_views} is more than the {fewest - 1} other views a shape of "
                               f"{self.root} ({split} split) has; use at most {max(fewest - 1, 1)}")
        self.fields = fields
        self._arrays = None  # the mesh-array cache (fields "mesh")
        if fields == "mesh" and mesh_cache != "none" and self._shapes:
            from training.data.mesh_cache import open_mesh_cache

            self._arrays = open_mesh_cache(self.root, self.manifest, mesh_cache)
        self._inputs = None  # generated predictor inputs (fields "mesh")
        self.input_share = float(input_share)
        if input_normals:
            if self._arrays is None:
                raise DatasetError("input_normals needs fields='mesh' and the mesh-array cache (its rows index them)")
            if not 0.0 < self.input_share <= 1.0:
                raise DatasetError(f"input_share must be in (0, 1], got {input_share}")
            from training.data.generated import open_generated

            names = input_normals.split(",") if isinstance(input_normals, str) else list(input_normals)
            names = [n.strip() for n in names]
            if not all(names) or len(set(names)) != len(names):
                raise DatasetError(f"input_normals must name distinct sets, got {input_normals!r}")
            self._inputs = [open_generated(self.root, n) for n in names]
            for g in self._inputs:
                if g.info.get("mirror", False):
                    raise DatasetError(f"{g.folder} is a mirrored set (data generated --mirror): it is the input of "
                                       "mirrored items (mirror_inputs), not of the items themselves (input_normals)")
                if g.normals64.shape[0] != self._arrays.normals64.shape[0]:
                    raise DatasetError(f"{g.folder} has {g.normals64.shape[0]} rows, the dataset "
                                       f"{self._arrays.normals64.shape[0]}: it was built for another state of {self.root}")
            self._views = len(self._items)  # item i: view i % V with the input of set i // V
            self._items = self._items * len(self._inputs)
        self._mirrors = None  # generated inputs of the mirrored drawings, paired with self._inputs
        if mirror_inputs:
            if self._inputs is None:
                raise DatasetError("mirror_inputs needs input_normals (the unmirrored sets they pair with)")
            self._mirrors = self._open_mirrors(mirror_inputs)

    def _open_mirrors(self, mirror_inputs: str | Sequence[str]) -> list:
        """The mirrored generated sets, checked against their partners in ``self._inputs``."""
        from training.data.generated import open_generated

        names = mirror_inputs.split(",") if isinstance(mirror_inputs, str) else list(mirror_inputs)
        names = [n.strip() for n in names]
        if not all(names) or len(names) != len(self._inputs):
            raise DatasetError(f"mirror_inputs must name one mirrored set per input set ({len(self._inputs)}), "
                               f"got {mirror_inputs!r}")
        mirrors = [open_generated(self.root, n) for n in names]
        for m, g in zip(mirrors, self._inputs):
            if not m.info.get("mirror", False) or g.info.get("mirror", False):
                raise DatasetError(f"{m.folder} must be a mirrored set (sketchmesh data generated --mirror) and "
                                   f"{g.folder} an unmirrored one")
            diff = [k for k in ("generator_sha256", "augment_strength", "seed", "rows", "small_size", "row_files")
                    if m.info.get(k) != g.info.get(k)]
            if diff:
                raise DatasetError(f"{m.folder} is not the mirror of {g.folder}: they differ in {', '.join(diff)}")
            if (g.done & ~m.done).any():
                raise DatasetError(f"{m.folder} lacks rows that {g.folder} has (built for another split, or stopped): "
                                   "finish it with `sketchmesh data generated ... --mirror` for the same split")
        return mirrors

    def __len__(self) -> int:
        return len(self._items)

    def elevations(self) -> np.ndarray:
        """(len(self),) the elevation in degrees of every item's view, from the manifest."""
        if getattr(self, "_elevations", None) is None:
            by_view = {(r["category"], r["shape_id"], int(r["view"])): float(r["elevation"])
                       for r in self.manifest["views"]}
            self._elevations = np.array([by_view[(self._shapes[si]["category"], self._shapes[si]["shape_id"], v)]
                                         for si, v in self._items], dtype=np.float64)
        return self._elevations

    def shapes(self) -> list[tuple[str, str, str]]:
        """(category, shape_id, split) of every shape in this dataset view."""
        return [(s["category"], s["shape_id"], s["split"]) for s in self._shapes]

    def _path(self, rec: dict) -> str:
        return str(self.root / rec["file"])

    def shape_array(self, category: str, shape_id: str, key: str) -> np.ndarray:
        """One stored array of a shape (e.g. ``"cameras"`` (views, 16), ``"silhouette64"``), as on disk."""
        rec = self._by_id.get((category, shape_id))
        if rec is None:
            raise DatasetError(f"shape {category}/{shape_id} is not in this dataset ({self.split} split)")
        return self._cache.get(self._path(rec), key)

    def load_mesh(self, category: str, shape_id: str) -> Mesh:
        """The shape's normalised mesh (world frame, as rendered)."""
        return Mesh(self.shape_array(category, shape_id, "vertices"), self.shape_array(category, shape_id, "faces"))

    def view_key(self, i: int) -> tuple[str, str, int]:
        """(category, shape_id, view) of item ``i``, without loading it."""
        si, v = self._items[int(i)]
        return self._shapes[si]["category"], self._shapes[si]["shape_id"], int(v)

    def other_views(self, i: int) -> np.ndarray:
        """(K,) the other view indices item i returns: distinct where possible, deterministic in (seed, i)."""
        si, v = self._items[i]
        n = int(self._shapes[si]["num_views"])
        K = self.extra_views
        if K == 0:
            return np.zeros(0, np.int64)
        rng = np.random.default_rng([self.seed, 7919, i])
        pool = np.array([u for u in range(n) if u != v] or [v])
        return rng.choice(pool, size=K, replace=K > len(pool)).astype(np.int64)

    def __getitem__(self, i: int) -> dict:
        return self.item(i, self.fields)

    def __getitems__(self, indices: Sequence[int]) -> list[dict]:
        """The items of a batch (what a DataLoader with a batch sampler asks for), equal to ``[ds[i] for i in indices]``.

        With ``fields="mesh"`` and the mesh-array cache, every array of the batch is gathered at once.
        """
        if self.fields != "mesh" or self._arrays is None or len(indices) == 0:
            return [self[i] for i in indices]
        torch = _torch()
        n = len(self)
        for i in indices:
            if not -n <= i < n:
                raise IndexError(f"index {i} out of range for a dataset of {n} views")
        idx = [int(i) % n for i in indices]
        a = self._arrays
        recs = [self._shapes[self._items[i][0]] for i in idx]
        views = np.array([self._items[i][1] for i in idx], np.int64)
        first = np.array([a.row(r["file"]) for r in recs], np.int64)
        rows = first + views  # (B,)
        others = first[:, None] + np.stack([self.other_views(i) for i in idx]).reshape(len(idx), self.extra_views)
        batch = {
            "normals64": torch.from_numpy(np.ascontiguousarray(a.normals64[rows].transpose(0, 3, 1, 2), np.float32)),
            "silhouette64": torch.from_numpy(a.silhouette64[rows].astype(np.float32)),
            "camera": torch.from_numpy(a.cameras[rows].astype(np.float64)),
            "other_normals64": torch.from_numpy(np.ascontiguousarray(a.normals64[others].transpose(0, 1, 4, 2, 3),
                                                                     np.float32)),
            "other_silhouette64": torch.from_numpy(a.silhouette64[others].astype(np.float32)),
            "other_cameras": torch.from_numpy(a.cameras[others].astype(np.float64)),
        }
        if self._inputs is not None:
            batch["input64"] = torch.from_numpy(self._input_rows(idx, rows))
        if self._mirrors is not None:
            batch["input64_mirror"] = torch.from_numpy(self._input_rows(idx, rows, mirrored=True))
        return [{**{k: v[b] for k, v in batch.items()}, "category": r["category"], "shape_id": r["shape_id"],
                 "view": int(views[b])} for b, r in enumerate(recs)]

    def uses_generated(self, i: int) -> bool:
        """Whether item ``i`` reads the generated input image (see ``input_share``)."""
        if self._inputs is None:
            return False
        return self.input_share >= 1.0 or bool(np.random.default_rng([self.seed, 104729, i]).random() < self.input_share)

    def _input_rows(self, idx: Sequence[int], rows: np.ndarray, mirrored: bool = False) -> np.ndarray:
        """(B, 3, s, s) float32 predictor inputs of items ``idx`` (mesh-cache rows ``rows``); of their mirrors if ``mirrored``."""
        sets_used = self._mirrors if mirrored else self._inputs
        pick = np.array([self.uses_generated(i) for i in idx], bool)
        sets = np.asarray(idx, np.int64) // self._views
        if pick.all() and len(sets_used) == 1:  # the default (one set, input_share 1): no true image is read
            return sets_used[0].rows(rows)
        out = np.ascontiguousarray(self._arrays.normals64[rows].transpose(0, 3, 1, 2), np.float32)
        if mirrored:  # the true images' exact mirrors, their silhouettes as coverage
            from training.data.mirror import mirror_normal_image

            torch = _torch()
            sil = torch.from_numpy(self._arrays.silhouette64[rows].astype(np.float32))
            out = np.ascontiguousarray(mirror_normal_image(torch.from_numpy(out), sil).numpy())
        for k, g in enumerate(sets_used):
            sel = pick & (sets == k)
            if sel.any():
                out[sel] = g.rows(rows[sel])
        return out

    def _sketch_seed(self, i: int) -> list[int]:
        """The seed of item ``i``'s hand-drawn augmentation (``i`` normalised): its sketch and its strokes share it."""
        return [self.seed, i]

    def _clean_polylines(self, i: int) -> list[np.ndarray]:
        """Item ``i``'s clean line drawing as polylines (``i`` normalised)."""
        from training.data.render import view_polylines

        si, v = self._items[i]
        p = self._path(self._shapes[si])
        return view_polylines({k: self._cache.get(p, k) for k in ("view_poly_offsets", "poly_offsets", "poly_points")}, v)

    def view_strokes(self, i: int) -> list[np.ndarray]:
        """The polylines item ``i``'s sketch is drawn from: (N_k, 2) pixel coordinates (x = col, y = row).

        With ``augment_strength`` > 0 they are the hand-drawn ones of the item's sketch (the same seed),
        otherwise the clean ones; stroke widths and ink, which the app's canvas does not have, are left out.
        """
        from training.data.augment import augment_strokes

        if not -len(self) <= i < len(self):
            raise IndexError(f"index {i} out of range for a dataset of {len(self)} views")
        i = int(i) % len(self)
        clean = self._clean_polylines(i)
        if self.augment_strength <= 0:
            return clean
        return augment_strokes(clean, self.augment_strength, self._sketch_seed(i), self.size).polylines

    def item(self, i: int, fields: str = "all") -> dict:
        """Item ``i`` with ``fields`` ("all", "mesh" or "sketch"; see the class docstring)."""
        torch = _torch()
        if not -len(self) <= i < len(self):
            raise IndexError(f"index {i} out of range for a dataset of {len(self)} views")
        if fields not in self.FIELDS:
            raise DatasetError(f"fields must be one of {self.FIELDS}, got {fields!r}")
        i = int(i) % len(self)
        si, v = self._items[i]
        rec = self._shapes[si]
        others = self.other_views(i)
        if fields == "mesh":
            extra = {}
            if self._arrays is not None:
                a = self._arrays
                row = a.row(rec["file"])
                n64, s64, cams, v, others = a.normals64, a.silhouette64, a.cameras, row + v, row + others
                if self._inputs is not None:
                    extra["input64"] = torch.from_numpy(self._input_rows([i], np.array([v], np.int64))[0])
                if self._mirrors is not None:
                    extra["input64_mirror"] = torch.from_numpy(
                        self._input_rows([i], np.array([v], np.int64), mirrored=True)[0])
            else:
                p = self._path(rec)
                n64, s64, cams = (self._cache.get(p, k) for k in ("normals64", "silhouette64", "cameras"))
            return {**_mesh_fields(torch, n64, s64, cams, v, others), **extra, "category": rec["category"],
                    "shape_id": rec["shape_id"], "view": int(self._items[i][1])}
        p = self._path(rec)
        get = self._cache.get
        if self.augment_strength > 0:
            from training.data.augment import render_sketch

            sketch = render_sketch(self._clean_polylines(i), self.size, self.augment_strength, self._sketch_seed(i))
        else:
            sketch = get(p, "sketch")[v].astype(np.float32) / 255.0
        n64, s64 = get(p, "normals64"), get(p, "silhouette64")
        cams = get(p, "cameras")
        out = {"sketch": torch.from_numpy(np.ascontiguousarray(sketch, np.float32)[None])}
        if fields == "all":
            out["normals"] = torch.from_numpy(get(p, "normals256")[v].astype(np.float32).transpose(2, 0, 1) / 255.0)
            out["silhouette"] = torch.from_numpy(get(p, "silhouette256")[v].astype(np.float32)[None])
        return {**out, **_mesh_fields(torch, n64, s64, cams, v, others), "category": rec["category"],
                "shape_id": rec["shape_id"], "view": int(v)}
