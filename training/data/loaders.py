"""Mesh loaders: a ShapeNetCore v1/v2 folder, or any folder of mesh files.

Every shape comes out as an :class:`engine.mesh.Mesh` normalised by the one convention
(:func:`engine.camera.normalize_vertices`). Multi-part files (OBJ groups, glTF scenes) are
merged into one mesh, a Scene's node transforms applied. A file that cannot be used
(corrupt, empty, no faces, NaN vertices) is skipped with a warning that names it; the
iterators count the skips and warn once more with the total at the end. They never raise
on a bad file.

ShapeNetCore layouts:
    v1: ``ROOT/<synset>/<model_id>/model.obj``
    v2: ``ROOT/<synset>/<model_id>/models/model_normalized.obj``
Only the 13 synsets in :data:`SHAPENET_SYNSETS` are read (others are ignored).
"""

from __future__ import annotations

import logging
import os
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.camera import normalize_vertices
from engine.errors import MeshInputError
from engine.mesh import Mesh

SHAPENET_SYNSETS: dict[str, str] = {
    "02691156": "airplane",
    "02828884": "bench",
    "02933112": "cabinet",
    "02958343": "car",
    "03001627": "chair",
    "03211117": "display",
    "03636649": "lamp",
    "03691459": "loudspeaker",
    "04090263": "rifle",
    "04256520": "sofa",
    "04379243": "table",
    "04401088": "telephone",
    "04530566": "watercraft",
}
"""ShapeNetCore synset id -> category name (the paper's 13 categories)."""

CATEGORY_SYNSETS: dict[str, str] = {v: k for k, v in SHAPENET_SYNSETS.items()}

MESH_SUFFIXES: tuple[str, ...] = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
"""File suffixes read by :func:`iter_mesh_folder` (case-insensitive)."""

DEGENERATE_AREA = 1e-14
"""Faces with a (normalised-space) area below this are dropped on load."""


class SkipCounter:
    """Counts skipped files during an iteration (``skipped`` list of (path, reason))."""

    def __init__(self) -> None:
        self.skipped: list[tuple[str, str]] = []
        self.loaded = 0

    def __len__(self) -> int:
        return len(self.skipped)


def load_mesh_file(path: str | os.PathLike) -> Mesh:
    """Read one mesh file into a normalised :class:`Mesh`, merging scenes and parts.

    Args:
        path: an OBJ, PLY, STL, OFF, GLB or glTF file.

    Returns:
        The merged triangle mesh, vertices normalised (longest bounding-box side 1, centred),
        degenerate (zero-area, repeated-index) faces and unreferenced vertices removed.

    Raises:
        MeshInputError: unreadable or corrupt file, unknown suffix, no triangles, NaN vertices.
    """
    import trimesh

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise MeshInputError(f"{path}: unsupported mesh suffix {suffix!r} (supported: {', '.join(MESH_SUFFIXES)})")
    if not path.is_file():
        raise MeshInputError(f"{path}: no such file")
    if path.stat().st_size == 0:
        raise MeshInputError(f"{path}: file is empty")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            logging.getLogger("trimesh").disabled = True
            try:
                loaded = trimesh.load(str(path), process=False, force=None)
            finally:
                logging.getLogger("trimesh").disabled = False
    except Exception as exc:  # trimesh raises many types on corrupt input
        raise MeshInputError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None
    vertices, faces = _merge_geometry(loaded)
    if len(faces) == 0:
        raise MeshInputError(f"{path}: mesh has no triangles")
    if not np.all(np.isfinite(vertices)):
        raise MeshInputError(f"{path}: mesh has NaN or infinite vertices")
    vertices, faces = _clean(vertices, faces)
    if len(faces) == 0:
        raise MeshInputError(f"{path}: mesh has only degenerate triangles")
    try:
        v = normalize_vertices(vertices)
    except ValueError as exc:
        raise MeshInputError(f"{path}: {exc}") from None
    return Mesh(v.astype(np.float32), faces)


def _merge_geometry(loaded) -> tuple[np.ndarray, np.ndarray]:
    """Trimesh / Scene / list -> one (V, 3) float64, (F, 3) int64 triangle soup with transforms applied."""
    import trimesh

    meshes: list[tuple[np.ndarray, np.ndarray]] = []
    if isinstance(loaded, trimesh.Scene):
        for node in loaded.graph.nodes_geometry:
            transform, geom_name = loaded.graph[node]
            geom = loaded.geometry.get(geom_name)
            if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
                v = np.asarray(geom.vertices, dtype=np.float64)
                v = v @ transform[:3, :3].T + transform[:3, 3]
                meshes.append((v, np.asarray(geom.faces, dtype=np.int64)))
    elif isinstance(loaded, trimesh.Trimesh):
        meshes.append((np.asarray(loaded.vertices, dtype=np.float64), np.asarray(loaded.faces, dtype=np.int64)))
    elif isinstance(loaded, (list, tuple)):
        for item in loaded:
            v, f = _merge_geometry(item)
            if len(f):
                meshes.append((v, f))
    if not meshes:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    offsets = np.cumsum([0] + [len(v) for v, _ in meshes[:-1]])
    vertices = np.concatenate([v for v, _ in meshes])
    faces = np.concatenate([f.reshape(-1, 3) + o for (_, f), o in zip(meshes, offsets)])
    return vertices, faces


def _clean(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop faces with repeated indices or (relative) zero area, then unreferenced vertices."""
    f = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    if len(f) == 0:
        return vertices, f
    size = float(np.max(np.ptp(vertices, axis=0))) or 1.0
    tri = vertices[f] / size
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    f = f[area > DEGENERATE_AREA]
    used = np.unique(f)
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[f]


@dataclass
class ShapeRecord:
    """A mesh file found by a scan: category, shape id, path."""

    category: str
    shape_id: str
    path: Path
    extra: dict = field(default_factory=dict)


def scan_shapenet(root: str | os.PathLike, categories: Sequence[str] | None = None) -> list[ShapeRecord]:
    """List the models of a ShapeNetCore v1 or v2 folder (sorted by category, then model id).

    Args:
        root: the folder holding the synset folders.
        categories: restrict to these category names (default: all 13).

    Raises:
        MeshInputError: ``root`` is not a folder or holds none of the 13 synsets.
    """
    root = Path(root)
    if not root.is_dir():
        what = "is a file, expected a ShapeNet folder" if root.exists() else "ShapeNet folder does not exist"
        raise MeshInputError(f"{root}: {what}")
    wanted = set(categories) if categories else set(SHAPENET_SYNSETS.values())
    unknown = wanted - set(SHAPENET_SYNSETS.values())
    if unknown:
        raise MeshInputError(f"unknown categories {sorted(unknown)}; expected some of {sorted(CATEGORY_SYNSETS)}")
    records: list[ShapeRecord] = []
    found_synset = False
    for synset in sorted(p.name for p in root.iterdir() if p.is_dir()):
        category = SHAPENET_SYNSETS.get(synset)
        if category is None or category not in wanted:
            continue
        found_synset = True
        for model in sorted(p for p in (root / synset).iterdir() if p.is_dir()):
            for rel in ("models/model_normalized.obj", "model.obj"):
                path = model / rel
                if path.is_file():
                    records.append(ShapeRecord(category, model.name, path))
                    break
            else:
                records.append(ShapeRecord(category, model.name, model / "model.obj", {"missing": True}))
    if not found_synset:
        raise MeshInputError(f"{root}: no ShapeNet synset folders found (expected e.g. {root}/03001627/<model>/model.obj)")
    return records


def scan_mesh_folder(root: str | os.PathLike, category: str | None = None) -> list[ShapeRecord]:
    """List mesh files under a folder (recursive, sorted).

    The category is ``category`` if given, else the name of the file's top-level sub-folder
    under ``root`` (files directly in ``root`` get the folder's own name). The shape id is
    the file's path relative to its category folder, without suffix, "/" replaced by "__"
    (files that differ only by suffix get it appended: ``chair_obj``, ``chair_ply``).

    Raises:
        MeshInputError: ``root`` is not a folder or holds no mesh files.
    """
    root = Path(root)
    if not root.is_dir():
        what = "is a file, expected a mesh folder" if root.exists() else "mesh folder does not exist"
        raise MeshInputError(f"{root}: {what}")
    records = []
    for path in sorted(root.rglob("*")):
        if not path.is_file() or path.suffix.lower() not in MESH_SUFFIXES:
            continue
        rel = path.relative_to(root)
        if category is not None:
            cat, inner = category, rel
        elif len(rel.parts) > 1:
            cat, inner = rel.parts[0], Path(*rel.parts[1:])
        else:
            cat, inner = root.resolve().name or "meshes", rel
        sid = str(inner.with_suffix("")).replace(os.sep, "__")
        records.append(ShapeRecord(cat, sid, path))
    if not records:
        raise MeshInputError(f"{root}: no mesh files found (looked for {', '.join(MESH_SUFFIXES)})")
    seen: dict[tuple[str, str], int] = {}
    for r in records:
        seen[(r.category, r.shape_id)] = seen.get((r.category, r.shape_id), 0) + 1
    for r in records:  # "chair.obj" and "chair.ply" side by side become chair_obj and chair_ply
        if seen[(r.category, r.shape_id)] > 1:
            r.shape_id = f"{r.shape_id}_{r.path.suffix.lower().lstrip('.')}"
    return records


def iter_records(records: Sequence[ShapeRecord], counter: SkipCounter | None = None) -> Iterator[tuple[str, str, Mesh]]:
    """Load scanned records, yielding (category, shape_id, Mesh); bad files warned about and skipped."""
    counter = counter if counter is not None else SkipCounter()
    for rec in records:
        try:
            if rec.extra.get("missing"):
                raise MeshInputError(f"{rec.path.parent}: no model.obj or models/model_normalized.obj")
            mesh = load_mesh_file(rec.path)
        except MeshInputError as exc:
            counter.skipped.append((str(rec.path), str(exc)))
            warnings.warn(f"skipping {exc}", stacklevel=2)
            continue
        counter.loaded += 1
        yield rec.category, rec.shape_id, mesh
    if counter.skipped:
        warnings.warn(f"skipped {len(counter.skipped)} of {len(records)} mesh files (see warnings above)", stacklevel=2)


def iter_shapenet(root: str | os.PathLike, categories: Sequence[str] | None = None,
                  counter: SkipCounter | None = None) -> Iterator[tuple[str, str, Mesh]]:
    """Iterate a ShapeNetCore v1/v2 folder: yields (category, model_id, normalised Mesh)."""
    return iter_records(scan_shapenet(root, categories), counter)


def iter_mesh_folder(root: str | os.PathLike, category: str | None = None,
                     counter: SkipCounter | None = None) -> Iterator[tuple[str, str, Mesh]]:
    """Iterate any folder of mesh files: yields (category, shape_id, normalised Mesh)."""
    return iter_records(scan_mesh_folder(root, category), counter)
