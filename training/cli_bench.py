"""Registers ``sketchmesh bench renderer`` and ``sketchmesh bench fit``.

Cheap to import (argparse only): torch and the implementations are imported inside the
command functions, through :func:`training._torch.require_torch`.
"""

from __future__ import annotations

import math

from engine.cliutil import float_in, int_in, one_line_errors, positive_int

_resolution = int_in(1, 2048)
_non_negative_float = float_in(0.0, math.inf)


def _cmd_bench_renderer(args) -> int:
    from training._torch import require_torch

    require_torch()
    from training.bench_renderer import main_bench_renderer

    return main_bench_renderer(args)


def _cmd_bench_fit(args) -> int:
    from training._torch import require_torch

    require_torch()
    from training.fit import main_fit

    return main_fit(args)


def register(commands, bench) -> None:
    """Add ``bench renderer`` and ``bench fit`` to the ``bench`` sub-parsers (``commands`` unused)."""
    p = one_line_errors(bench.add_parser(
        "renderer",
        help="speed, memory and accuracy of the differentiable rasterizer (and the dense baseline)",
        description="Forward and forward+backward time (median), peak memory and error against a "
        "4x-supersampled render, on bumpy 642-vertex spheres from random views.",
    ))
    p.add_argument("--resolutions", type=_resolution, nargs="+", default=[32, 64, 128, 256], metavar="R")
    p.add_argument("--batches", type=positive_int, nargs="+", default=[1, 16, 64], metavar="B")
    p.add_argument("--repeats", type=positive_int, default=5, help="timed runs per configuration (median)")
    p.add_argument("--threads", type=positive_int, default=2, help="torch intra-op threads (default 2)")
    p.add_argument("--dense-max-mb", type=_non_negative_float, default=1024.0,
                   help="run the dense baseline where its estimated memory per image is below this (0: never)")
    p.add_argument("--dense-max-batch", type=positive_int, default=16,
                   help="largest batch at which the (slow) dense baseline runs")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--timeout", type=positive_int, default=1800, help="seconds per configuration")
    p.add_argument("--in-process", action="store_true",
                   help="measure in this process (faster to start; peak_mb then accumulates across rows)")
    p.add_argument("--json", metavar="PATH", help="write the records as a JSON list")
    p.set_defaults(func=_cmd_bench_renderer)

    q = one_line_errors(bench.add_parser(
        "fit",
        help="fit the template sphere to a target mesh's multi-view renders through the rasterizer",
    ))
    q.add_argument("--target", required=True, metavar="MESH_FILE", help="target mesh file")
    q.add_argument("--views", type=positive_int, default=8)
    q.add_argument("--iters", type=positive_int, default=300)
    q.add_argument("--resolution", type=_resolution, default=64)
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--json", metavar="PATH", help="write the results as JSON")
    q.set_defaults(func=_cmd_bench_fit)
