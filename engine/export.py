"""Mesh export: one table from file suffix to writer; every write atomic; vertex order kept.

Supported: ``.obj`` (with vertex normals), ``.glb``, ``.gltf`` (self-contained: the buffer is
embedded as a data URI, so no loose ``.bin`` file can be overwritten by a later export),
``.ply`` (binary) and ``.stl`` (binary; STL has no shared vertices or vertex normals).
Meshes are handed to trimesh with ``process=False`` so what was predicted is what is written.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from engine.errors import ExportError
from engine.fileio import atomic_write_bytes
from engine.mesh import Mesh, vertex_normals

OBJ_DIGITS = 9
"""Decimal places written for OBJ coordinates (float32 positions of |x| < 10 survive to ~1e-9)."""


def _trimesh(mesh: Mesh, include_normals: bool):
    import trimesh

    kwargs = {}
    if include_normals:
        kwargs["vertex_normals"] = vertex_normals(mesh.vertices, mesh.faces)
    return trimesh.Trimesh(vertices=np.asarray(mesh.vertices, np.float64), faces=mesh.faces, process=False, validate=False, **kwargs)


def _obj(mesh: Mesh, include_normals: bool) -> bytes:
    from trimesh.exchange.obj import export_obj

    text = export_obj(_trimesh(mesh, include_normals), include_normals=include_normals, include_color=False,
                      include_texture=False, digits=OBJ_DIGITS, header="Sketchmesh")
    return text.encode("utf-8")


def _ply(mesh: Mesh, include_normals: bool) -> bytes:
    from trimesh.exchange.ply import export_ply

    return export_ply(_trimesh(mesh, include_normals), encoding="binary", vertex_normal=include_normals, include_attributes=False)


def _stl(mesh: Mesh, include_normals: bool) -> bytes:
    from trimesh.exchange.stl import export_stl

    return export_stl(_trimesh(mesh, False))


_ARRAY_BUFFER = 34962
_ELEMENT_ARRAY_BUFFER = 34963


def _set_buffer_view_targets(doc: dict) -> dict:
    """Mark each bufferView used by a primitive as vertex (ARRAY_BUFFER) or index data.

    trimesh leaves ``bufferView.target`` unset, which the Khronos validator reports as
    BUFFER_VIEW_TARGET_MISSING; setting it lets loaders upload the views without guessing.
    """
    accessors, views = doc.get("accessors", []), doc.get("bufferViews", [])
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            for acc in prim.get("attributes", {}).values():
                view = accessors[acc].get("bufferView")
                if view is not None:
                    views[view].setdefault("target", _ARRAY_BUFFER)
            if "indices" in prim:
                view = accessors[prim["indices"]].get("bufferView")
                if view is not None:
                    views[view].setdefault("target", _ELEMENT_ARRAY_BUFFER)
    return doc


def _glb(mesh: Mesh, include_normals: bool) -> bytes:
    import json
    import struct

    import trimesh
    from trimesh.exchange.gltf import export_glb

    data = export_glb(trimesh.Scene(_trimesh(mesh, include_normals)), include_normals=include_normals)
    # GLB: 12-byte header, then a JSON chunk (length, type, data) and the BIN chunk
    magic, version, _ = struct.unpack("<4sII", data[:12])
    json_len, json_type = struct.unpack("<I4s", data[12:20])
    if magic != b"glTF" or json_type != b"JSON":
        raise ExportError("unexpected GLB layout from trimesh")
    doc = _set_buffer_view_targets(json.loads(data[20 : 20 + json_len]))
    text = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)  # chunks are 4-byte aligned, JSON padded with spaces
    rest = data[20 + json_len :]
    body = struct.pack("<I4s", len(text), b"JSON") + text + rest
    return struct.pack("<4sII", magic, version, 12 + len(body)) + body


def _gltf(mesh: Mesh, include_normals: bool) -> bytes:
    import trimesh
    from trimesh.exchange.gltf import export_gltf

    files = export_gltf(trimesh.Scene(_trimesh(mesh, include_normals)), include_normals=include_normals, embed_buffers=True)
    if len(files) != 1:  # embed_buffers must leave nothing but the JSON
        raise ExportError(f"glTF export produced {len(files)} files, expected one self-contained file")
    import json

    data = next(iter(files.values()))
    doc = _set_buffer_view_targets(json.loads(data))
    return json.dumps(doc, separators=(",", ":")).encode("utf-8")


WRITERS: dict[str, Callable[[Mesh, bool], bytes]] = {
    ".obj": _obj,
    ".glb": _glb,
    ".gltf": _gltf,
    ".ply": _ply,
    ".stl": _stl,
}
"""Suffix -> writer(mesh, include_normals) -> file bytes. The single table of export formats."""


def supported_suffixes() -> tuple[str, ...]:
    """The suffixes :func:`export_mesh` accepts, e.g. ``('.obj', '.glb', ...)``."""
    return tuple(WRITERS)


def _suffix(path: Path, fmt: str | None) -> str:
    suffix = ("." + fmt.lower().lstrip(".")) if fmt else path.suffix.lower()
    if suffix not in WRITERS:
        what = (f"unknown format {fmt!r}" if fmt else f"unknown file suffix {path.suffix!r}" if path.suffix
                else "the file name has no suffix to choose the format by")
        raise ExportError(f"cannot export {path.name}: {what}; supported: {', '.join(WRITERS)}")
    return suffix


def check_export_path(path: str | os.PathLike, fmt: str | None = None) -> str:
    """Validate an output path's format before any work is done. Returns the suffix (e.g. ``'.glb'``).

    Raises:
        ExportError: unknown suffix or format (the message lists the supported ones).
    """
    return _suffix(Path(path), fmt)


def mesh_to_bytes(mesh: Mesh, suffix: str, *, include_normals: bool = True) -> bytes:
    """Serialise a mesh in the format of ``suffix`` (e.g. ``'.obj'``)."""
    if not isinstance(mesh, Mesh):
        raise ExportError(f"export needs an engine.mesh.Mesh, got {type(mesh).__name__}")
    if mesh.num_faces == 0:
        raise ExportError("cannot export a mesh with no faces")
    return WRITERS[_suffix(Path("mesh" + suffix), None)](mesh, include_normals)


def export_mesh(mesh: Mesh, path: str | os.PathLike, *, include_normals: bool = True, fmt: str | None = None) -> Path:
    """Write a mesh to ``path`` atomically, in the format chosen by its suffix (or ``fmt``).

    Args:
        mesh: the mesh (vertex order is kept).
        path: output file; parent folders are created.
        include_normals: write area-weighted vertex normals where the format has them (OBJ, PLY, glTF).
        fmt: format name overriding the suffix (``"obj"``, ``"glb"``, ...).

    Returns:
        The written path.

    Raises:
        ExportError: unknown suffix/format, empty mesh, or the file cannot be written.
    """
    path = Path(path)
    suffix = _suffix(path, fmt)
    data = mesh_to_bytes(mesh, suffix, include_normals=include_normals)
    if path.is_dir():
        raise ExportError(f"cannot write {path}: it is a folder")
    try:
        atomic_write_bytes(path, data)
    except OSError as exc:
        raise ExportError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path
