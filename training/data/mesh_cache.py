"""The arrays a mesh-mode step reads, decompressed once per dataset: an uncompressed memory map beside it.

A mesh-mode training sample needs, of its shape, the 64 x 64 normal image and silhouette of its
view and of K other views, and their cameras (``normals64``, ``silhouette64``, ``cameras`` of
docs/DATA_FORMAT.md). Read from the shape files, a random sample costs a decompression of its
shape's ``.npz`` members; this module decompresses every shape's three arrays once and keeps them,
for the whole dataset (every split), in one uncompressed file that training maps into memory::

    DIR/.cache/mesh_arrays.bin     (``.cache/`` is git-ignored; derived data, safe to delete)

Layout: 8 bytes :data:`MAGIC`, the header length as a little-endian uint64, the header (JSON,
UTF-8), zero padding to :data:`ALIGN` bytes, then each array C-contiguous at its header offset.
Header: ``format``, ``fingerprint`` (see :func:`fingerprint`), ``views`` (N), ``shapes``
(``{file: [first row, num_views]}``), ``arrays`` (``{key: {offset, shape, dtype}}``). Row
``start + v`` of every array is view ``v`` of the shape ``file``; the arrays keep the shape files'
dtypes, so what is read is bit for bit what the shape files hold:

========================  ================  =======
``normals64``             (N, s, s, 3)      float32
``silhouette64``          (N, s, s)         bool
``cameras``               (N, 16)           float64
========================  ================  =======

The cache is valid for one state of the dataset: the fingerprint holds the manifest's settings
and, per shape file, its path, view count, size and modification time. When any of them differs
(the dataset was rebuilt with other settings, a shape re-rendered, shapes added or removed) the
cache is stale: it is rebuilt, with a :class:`StaleCacheWarning` saying why. It is written
atomically (:func:`engine.fileio.atomic_open`): a reader sees the old file or the new one, never a
half-written one. Where the dataset folder cannot take it (read-only, full disk) the arrays are
kept in this process's memory instead, with a warning.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import struct
import warnings
from pathlib import Path

import numpy as np

from training.data.dataset import DatasetError, available_memory_bytes, load_manifest

CACHE_FORMAT = "sketchmesh-mesh-cache-1"
CACHE_DIR = ".cache"
CACHE_NAME = "mesh_arrays.bin"
MAGIC = b"SKMCACH1"
ALIGN = 4096
MESH_KEYS: tuple[str, ...] = ("normals64", "silhouette64", "cameras")
"""The shape-file arrays a mesh-mode step reads, in file order."""

LOCATIONS = ("auto", "disk", "memory")
MEMORY_SHARE = 0.5
"""Largest share of the available memory an in-memory cache may take."""


class StaleCacheWarning(UserWarning):
    """The cache beside a dataset did not match it (or could not be written there) and was rebuilt."""


def cache_path(root: str | os.PathLike) -> Path:
    """Where the cache of the dataset ``root`` lives."""
    return Path(root) / CACHE_DIR / CACHE_NAME


def fingerprint(root: str | os.PathLike, manifest: dict) -> dict:
    """What the cache must match: the manifest's settings and every shape file's path, views, size and mtime.

    Raises:
        DatasetError: a shape file of the manifest is missing.
    """
    root = Path(root)
    shapes = []
    for rec in manifest.get("shapes", []):
        path = root / rec["file"]
        try:
            st = path.stat()
        except FileNotFoundError:
            raise DatasetError(f"{root}: shape file {rec['file']} is missing (half-written dataset? rerun its "
                               "`sketchmesh data` command to finish it)") from None
        shapes.append([rec["file"], int(rec["num_views"]), st.st_size, st.st_mtime_ns])
    return {"format": CACHE_FORMAT, "dataset_format": manifest.get("format"), "settings": manifest.get("settings"),
            "shapes": shapes}


def _digest(fp: dict) -> str:
    return hashlib.sha256(json.dumps(fp, sort_keys=True).encode()).hexdigest()


def _stale_reason(old: dict, new: dict) -> str:
    """One phrase saying how an old fingerprint differs from the dataset's."""
    if old.get("format") != new["format"]:
        return f"it has another cache format ({old.get('format')!r})"
    if old.get("settings") != new["settings"] or old.get("dataset_format") != new["dataset_format"]:
        return "the dataset was built with other settings than the cache"
    before = {s[0]: s[1:] for s in old.get("shapes", [])}
    now = {s[0]: s[1:] for s in new["shapes"]}
    added, removed = sorted(set(now) - set(before)), sorted(set(before) - set(now))
    changed = sorted(f for f in set(now) & set(before) if now[f] != before[f])
    parts = [f"{len(x)} shape file{'s' if len(x) != 1 else ''} {what} (e.g. {x[0]})" for x, what in
             ((added, "added"), (removed, "removed"), (changed, "changed")) if x]
    return "; ".join(parts) or "its shape list is in another order"


def _layout(shapes: list[tuple[str, int]], small: int) -> tuple[int, dict, dict]:
    """(views, {file: [start, n]}, {key: {shape, dtype}}) of the cache of these shapes."""
    rows, start = {}, 0
    for file, n in shapes:
        rows[file] = [start, n]
        start += n
    arrays = {"normals64": {"shape": [start, small, small, 3], "dtype": "<f4"},
              "silhouette64": {"shape": [start, small, small], "dtype": "|b1"},
              "cameras": {"shape": [start, 16], "dtype": "<f8"}}
    return start, rows, arrays


def _nbytes(spec: dict) -> int:
    return int(np.prod(spec["shape"], dtype=np.int64)) * np.dtype(spec["dtype"]).itemsize


def _read_shape(root: Path, rec: dict, arrays: dict) -> dict[str, np.ndarray]:
    """The three arrays of one shape file, checked against the layout's per-view shape and dtype."""
    path = root / rec["file"]
    try:
        with np.load(path, allow_pickle=False) as z:
            out = {k: z[k] for k in MESH_KEYS}
    except Exception as exc:
        raise DatasetError(f"{root}: cannot read shape file {rec['file']} ({type(exc).__name__}: {exc}); "
                           "rerun its `sketchmesh data` command to redo it") from None
    n = int(rec["num_views"])
    for k, a in out.items():
        want = (n, *arrays[k]["shape"][1:])
        if a.shape != want or a.dtype != np.dtype(arrays[k]["dtype"]):
            raise DatasetError(f"{root}: {k} of shape file {rec['file']} is {a.shape} {a.dtype}, expected "
                               f"{want} {np.dtype(arrays[k]['dtype'])} (the manifest's settings and views)")
    return out


class MeshArrays:
    """The mesh-step arrays of every view of a dataset, memory-mapped (or in memory).

    Attributes:
        normals64: (N, s, s, 3) float32; silhouette64: (N, s, s) bool; cameras: (N, 16) float64.
        rows: ``{shape file (relative path as in the manifest): (first row, num_views)}``.
        path: the cache file, or None when the arrays are held in memory.
    """

    def __init__(self, arrays: dict[str, np.ndarray], rows: dict[str, tuple[int, int]], path: Path | None) -> None:
        # plain ndarray views of the maps (they keep the mapping alive): np.memmap's indexing costs ~5 us a call
        self.normals64 = arrays["normals64"].view(np.ndarray)
        self.silhouette64 = arrays["silhouette64"].view(np.ndarray)
        self.cameras = arrays["cameras"].view(np.ndarray)
        self.rows = {f: (int(a), int(b)) for f, (a, b) in rows.items()}
        self.path = path

    def row(self, file: str) -> int:
        """First row of a shape file's views."""
        try:
            return self.rows[file][0]
        except KeyError:
            raise DatasetError(f"shape file {file} is not in the mesh-array cache {self.path or '(memory)'}") from None

    def __reduce__(self):  # a spawned DataLoader worker maps the file again instead of receiving a copy
        if self.path is not None:
            return _open_file, (self.path,)
        return MeshArrays, ({k: getattr(self, k) for k in MESH_KEYS}, self.rows, None)


def _read_header(path: Path) -> tuple[dict, int] | None:
    """(header, data start) of a cache file, or None when it is not one (or cut short)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
            if len(head) != 16 or head[:8] != MAGIC:
                return None
            (length,) = struct.unpack("<Q", head[8:])
            if length > 1 << 31:
                return None
            header = json.loads(fh.read(length).decode("utf-8"))
        size = path.stat().st_size
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    if not isinstance(header, dict) or header.get("format") != CACHE_FORMAT:
        return None
    try:
        end = max(spec["offset"] + _nbytes(spec) for spec in header["arrays"].values())
    except (KeyError, TypeError, ValueError):
        return None
    return (header, end) if size >= end else None


def _open_file(path: Path, header: dict | None = None) -> MeshArrays:
    if header is None:
        read = _read_header(path)
        if read is None:
            raise DatasetError(f"{path}: not a readable mesh-array cache (delete it; training rebuilds it)")
        header = read[0]
    arrays = {k: np.memmap(path, dtype=np.dtype(s["dtype"]), mode="r", offset=int(s["offset"]), shape=tuple(s["shape"]))
              for k, s in header["arrays"].items()}
    return MeshArrays(arrays, header["shapes"], Path(path))


def _progress(shapes: list, root: Path):
    """A progress bar over the shapes being cached, on a terminal only (once per dataset; minutes for a large one)."""
    from tqdm import tqdm

    return tqdm(shapes, desc=f"caching the mesh arrays of {root}", unit="shape", disable=None, leave=False)


def _write(path: Path, root: Path, manifest: dict, fp: dict, digest: str) -> None:
    """Decompress every shape's arrays into ``path`` (atomically), shape by shape."""
    from engine.fileio import atomic_open

    small = int((manifest.get("settings") or {}).get("small_size", 64))
    shapes = manifest["shapes"]
    views, rows, arrays = _layout([(r["file"], int(r["num_views"])) for r in shapes], small)
    header = {"format": CACHE_FORMAT, "fingerprint": fp, "digest": digest, "views": views, "shapes": rows,
              "arrays": arrays}
    # offsets depend on the header's length, which depends on the offsets: fix them on a padded guess
    body = json.dumps(header).encode()
    start = -(-(16 + len(body) + 64 * len(arrays)) // ALIGN) * ALIGN
    for spec in arrays.values():
        spec["offset"] = start
        start = -(-(start + _nbytes(spec)) // ALIGN) * ALIGN
    body = json.dumps(header).encode()
    if 16 + len(body) > arrays["normals64"]["offset"]:  # pragma: no cover - the padding above is generous
        raise DatasetError("mesh-array cache header does not fit its reserved space")
    with atomic_open(path, "wb") as fh:
        fh.write(MAGIC + struct.pack("<Q", len(body)) + body)
        for rec in _progress(shapes, root):
            first = rows[rec["file"]][0]
            for k, a in _read_shape(root, rec, arrays).items():
                fh.seek(arrays[k]["offset"] + first * (_nbytes(arrays[k]) // max(views, 1)))
                fh.write(np.ascontiguousarray(a).tobytes())
        fh.seek(start - 1)  # the file spans the last array's padding too
        fh.write(b"\0")


def _in_memory(root: Path, manifest: dict) -> MeshArrays:
    small = int((manifest.get("settings") or {}).get("small_size", 64))
    shapes = manifest["shapes"]
    views, rows, arrays = _layout([(r["file"], int(r["num_views"])) for r in shapes], small)
    need = sum(_nbytes(s) for s in arrays.values())
    memory = available_memory_bytes()
    if memory is not None and need > MEMORY_SHARE * memory:
        gb = 1024**3
        raise DatasetError(f"{root}: the mesh arrays of its {views} views take {need / gb:,.1f} GB, more than "
                           f"{MEMORY_SHARE:.0%} of the {memory / gb:,.1f} GB available, and they cannot be cached "
                           f"on disk beside the dataset; make {root / CACHE_DIR} writable")
    out = {k: np.empty(tuple(s["shape"]), np.dtype(s["dtype"])) for k, s in arrays.items()}
    for rec in _progress(shapes, root):
        first, n = rows[rec["file"]]
        for k, a in _read_shape(root, rec, arrays).items():
            out[k][first:first + n] = a
    return MeshArrays(out, rows, None)


def open_mesh_cache(root: str | os.PathLike, manifest: dict | None = None, location: str = "auto") -> MeshArrays:
    """The mesh-step arrays of every view of the dataset ``root``, building or rebuilding the cache as needed.

    Args:
        root: dataset folder (with manifest.json).
        manifest: its manifest, when already read.
        location: ``"auto"`` (a memory map of ``DIR/.cache/mesh_arrays.bin``, written when missing or
            stale; in memory when the folder cannot take it), ``"disk"`` (the memory map or a
            DatasetError) or ``"memory"`` (decompress into this process's memory; nothing written).

    Returns:
        :class:`MeshArrays` over every shape of the manifest (all splits), in manifest order.

    Raises:
        DatasetError: no manifest, no shapes, a shape file missing, unreadable or not matching the
            manifest, or (``"disk"``) the cache cannot be written.
    """
    if location not in LOCATIONS:
        raise DatasetError(f"mesh cache location must be one of {LOCATIONS}, got {location!r}")
    root = Path(root)
    manifest = manifest if manifest is not None else load_manifest(root)
    if not manifest.get("shapes"):
        raise DatasetError(f"{root}: the dataset has no shapes (build some with `sketchmesh data --out {root}`)")
    if location == "memory":
        return _in_memory(root, manifest)
    fp = fingerprint(root, manifest)
    digest = _digest(fp)
    path = cache_path(root)
    read = _read_header(path) if path.exists() else None
    if read is not None and read[0].get("digest") == digest and read[0].get("fingerprint") == fp:
        return _open_file(path, read[0])
    if path.exists():
        why = _stale_reason(read[0].get("fingerprint", {}), fp) if read is not None else "it is cut short or corrupt"
        warnings.warn(f"{path}: stale mesh-array cache ({why}); rebuilding it", StaleCacheWarning, stacklevel=2)
    views, _, arrays = _layout([(r["file"], int(r["num_views"])) for r in manifest["shapes"]],
                               int((manifest.get("settings") or {}).get("small_size", 64)))
    need = sum(_nbytes(s) for s in arrays.values()) + ALIGN * 8
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        free = shutil.disk_usage(path.parent).free
        if need > free:
            raise OSError(28, f"needs {need / 1024**2:,.0f} MB, {free / 1024**2:,.0f} MB free", str(path))
        _write(path, root, manifest, fp, digest)
    except OSError as exc:
        if location == "disk":
            raise DatasetError(f"cannot write the mesh-array cache {path}: {exc.strerror or exc}") from None
        warnings.warn(f"cannot write the mesh-array cache {path} ({exc.strerror or exc}); keeping the arrays in "
                      "memory", StaleCacheWarning, stacklevel=2)
        return _in_memory(root, manifest)
    read = _read_header(path)
    if read is None:  # pragma: no cover - we just wrote it
        raise DatasetError(f"{path}: the mesh-array cache just written cannot be read back")
    return _open_file(path, read[0])
