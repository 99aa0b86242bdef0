"""Exporting a category router into a model folder as ``router.onnx`` (:mod:`engine.contract`):
``sketchmesh router export``."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from engine import contract as C
from engine.models import is_specialist_file_name
from training._torch import require_torch
from training.loop.router import load_router_run
from training.model.router import RouterProbabilities

torch = require_torch()


PARITY_TOLERANCE = 1e-4
"""Largest |torch - ONNX Runtime| probability the export accepts."""


def parse_routes(specs: list[str], categories: list[str]) -> dict[str, list[str]]:
    """``FILE=cat,cat`` strings -> {file: [categories]}; ValueError naming a bad one."""
    routes: dict[str, list[str]] = {}
    for spec in specs:
        name, sep, cats = spec.partition("=")
        group = [c for c in cats.split(",") if c]
        if not sep or not name or not group:
            raise ValueError(f"--route {spec!r}: expected FILE=CATEGORY[,CATEGORY...]")
        if not is_specialist_file_name(name):
            raise ValueError(f"--route {spec!r}: FILE must be another .onnx file name in the model folder (not "
                             f"{C.GENERATOR_FILE}, {C.PREDICTOR_FILE} or {C.ROUTER_FILE})")
        unknown = [c for c in group if c not in categories]
        if unknown:
            raise ValueError(f"--route {spec!r}: {', '.join(unknown)} not among the router's categories {categories}")
        taken = [c for c in group if any(c in g for g in routes.values())] + [c for c in set(group) if group.count(c) > 1]
        if taken:
            raise ValueError(f"--route {spec!r}: {', '.join(sorted(set(taken)))} already routed (a category goes to one "
                             "specialist, once)")
        routes[name] = routes.get(name, []) + group
    return routes


def export_router(run: str | os.PathLike, models_dir: str | os.PathLike, routes: dict[str, list[str]],
                  threshold: float, *, mirror: bool = False) -> dict:
    """Write ``models_dir/router.onnx`` from a router run (atomic), checked by :func:`engine.models.load_router`
    and for parity with torch on random and blank inputs. The specialist files must already be in ``models_dir``.
    ``mirror`` sets ``route_mirror`` (:mod:`engine.contract`).

    Returns:
        {"path", "bytes", "parity_max_abs"}.
    """
    import io
    import warnings

    from engine.errors import ModelError
    from training.export.router_options import replace_router
    from training.export.to_onnx import OPSET, _with_metadata
    from training.loop.config import code_version

    if not 0.0 < threshold < 1.0:
        raise ValueError(f"--threshold must lie in (0, 1), got {threshold}")
    net, cfg = load_router_run(run)
    out = Path(models_dir)
    for name in routes:
        if not (out / name).is_file():
            raise ModelError(f"{out}: no {name} to route to (copy the specialist's mesh_predictor.onnx there under that name)")
    module = RouterProbabilities(net).eval()
    size = C.PREDICTOR_INPUT_SIZE
    x = torch.rand(4, 3, size, size, generator=torch.Generator().manual_seed(0))
    x[0] = 0.0
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(module, (x[:1],), buf, input_names=[C.ROUTER_INPUT], output_names=[C.ROUTER_OUTPUT],
                          dynamic_axes={C.ROUTER_INPUT: {0: "N"}, C.ROUTER_OUTPUT: {0: "N"}}, opset_version=OPSET,
                          dynamo=False, do_constant_folding=True)
    meta = {C.META_FORMAT: C.FORMAT_VERSION, C.META_ROLE: C.ROLE_ROUTER, C.META_CODE_VERSION: code_version(),
            C.META_CONFIG: cfg.to_json(), C.META_CONVENTIONS: C.CONVENTIONS_ID,
            C.META_CATEGORIES: json.dumps(cfg.categories), C.META_ROUTES: json.dumps(routes),
            C.META_ROUTE_THRESHOLD: repr(float(threshold)), C.META_ROUTE_MIRROR: json.dumps(bool(mirror))}
    data = _with_metadata(buf.getvalue(), meta)
    import onnxruntime as ort

    got = ort.InferenceSession(data, providers=["CPUExecutionProvider"]).run(None, {C.ROUTER_INPUT: x.numpy()})[0]
    with torch.no_grad():
        ref = module(x).numpy()
    err = float(np.abs(got - ref).max())
    if not err <= PARITY_TOLERANCE:
        raise ModelError(f"router export: ONNX Runtime differs from torch by {err:.3g} (tolerance {PARITY_TOLERANCE})")
    replace_router(out, data)  # checked as the engine will, before it replaces anything
    return {"path": str(out / C.ROUTER_FILE), "bytes": len(data), "parity_max_abs": err}
