"""Changing how a model folder's router routes, without retraining it: ``sketchmesh router set``.

The router's network is kept as it is; only its ``route_threshold`` and ``route_mirror`` metadata
(:mod:`engine.contract`) are rewritten, and the file is replaced atomically once the engine accepts it.
Needs the ``onnx`` package (the ``train`` extra), not torch.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from engine import contract as C
from engine.errors import ModelError


def replace_router(folder: Path, data: bytes):
    """Write ``data`` as ``folder/router.onnx`` only once :func:`engine.models.load_router` accepts it (written to a
    temporary name first, then renamed over the old file; no temporary left either way). Returns the loaded router."""
    from engine.fileio import atomic_write_bytes
    from engine.models import load_router

    check = folder / f".{C.ROUTER_FILE}.{os.getpid()}.check.onnx"
    atomic_write_bytes(check, data)
    try:
        router = load_router(check, threads=1)
        os.replace(check, folder / C.ROUTER_FILE)
    finally:
        check.unlink(missing_ok=True)
    return router


def set_router_options(models_dir: str | os.PathLike, *, threshold: float | None = None,
                       mirror: bool | None = None) -> dict:
    """Rewrite ``models_dir/router.onnx``'s threshold and/or mirror routing (atomic; checked by
    :func:`engine.models.load_router` before it replaces anything, so a router whose old values the engine refuses
    can be mended).

    Returns:
        {"path", "before": the old metadata strings (None where absent), "after": the values the engine now reads}.

    Raises:
        ModelError: no router in the folder, or a router the engine refuses (before or after).
        ValueError: nothing to change, or a threshold outside (0, 1).
    """
    import onnx

    from engine.bench import mark_meta

    if threshold is None and mirror is None:
        raise ValueError("nothing to change: give --threshold and/or --mirror / --no-mirror")
    if threshold is not None and not 0.0 < float(threshold) < 1.0:
        raise ValueError(f"--threshold must lie in (0, 1), got {threshold}")
    folder = Path(models_dir)
    path = folder / C.ROUTER_FILE
    if not path.is_file():
        raise ModelError(f"{folder}: no {C.ROUTER_FILE} to change (a folder without a router routes nothing)")
    try:
        model = onnx.load(str(path))
    except Exception as exc:  # a truncated or foreign file: onnx raises its own errors
        raise ModelError(f"{path}: cannot read it as an ONNX model ({exc.__class__.__name__})") from None
    meta = {p.key: p.value for p in model.metadata_props}
    before = {"route_threshold": meta.get(C.META_ROUTE_THRESHOLD), "route_mirror": meta.get(C.META_ROUTE_MIRROR)}
    if threshold is not None:
        mark_meta(model, C.META_ROUTE_THRESHOLD, repr(float(threshold)))
    if mirror is not None:
        mark_meta(model, C.META_ROUTE_MIRROR, json.dumps(bool(mirror)))
    new = replace_router(folder, model.SerializeToString())
    return {"path": str(path), "before": before,
            "after": {"route_threshold": new.route_threshold, "route_mirror": new.route_mirror}}
