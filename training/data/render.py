"""Render one shape's training views: normal images, silhouettes and line drawings.

For each view (by default the paper's 24 azimuths at 30 degrees elevation,
:func:`engine.camera.paper_views`) the camera is **framed** with
:func:`engine.camera.frame_camera` on the mesh vertices, so the drawing fills the image like
an engine-preprocessed sketch. Normal images, silhouettes and the depth / face-index buffers
come from the differentiable rasterizer's forward pass
(:func:`training.render.render_normals_numpy`, flat shading) at ``size`` (256) and, with the
same camera, directly at ``small_size`` (64): the 64x64 images are exactly the mesh
predictor's supervision targets. The line drawing (:mod:`training.data.lines`) uses the
256 depth and face-index buffers for hidden-line removal.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from engine.camera import Camera, frame_camera, look_at
from engine.mesh import Mesh
from training.data.lines import LineSettings, extract_lines, prepare_mesh, rasterize_polylines

DEFAULT_NUM_AZIMUTHS = 24
DEFAULT_ELEVATIONS: tuple[float, ...] = (30.0,)


@dataclass(frozen=True)
class RenderSettings:
    """What to render per shape.

    Attributes:
        size: sketch / normal image side (256 in the paper).
        small_size: side of the predictor's supervision images (64), rendered directly.
        num_azimuths: views per elevation, evenly spaced from azimuth 0.
        elevations: elevations in degrees, each in (-90, 90).
        lines: line-drawing settings.
    """

    size: int = 256
    small_size: int = 64
    num_azimuths: int = DEFAULT_NUM_AZIMUTHS
    elevations: tuple[float, ...] = DEFAULT_ELEVATIONS
    lines: LineSettings = field(default_factory=LineSettings)

    def __post_init__(self) -> None:
        for name in ("size", "small_size", "num_azimuths"):
            val = getattr(self, name)
            if not isinstance(val, (int, np.integer)) or val <= 0:
                raise ValueError(f"{name} must be a positive int, got {val!r}")
        if not self.elevations or any(not -90.0 < float(e) < 90.0 for e in self.elevations):
            raise ValueError(f"elevations must be a non-empty list of angles in (-90, 90), got {self.elevations}")

    @property
    def num_views(self) -> int:
        return self.num_azimuths * len(self.elevations)


def view_cameras(mesh: Mesh, settings: RenderSettings,
                 grid_views: Sequence[int] | None = None) -> list[tuple[float, float, Camera]]:
    """(azimuth_deg, elevation_deg, framed Camera) per view; elevation-major, azimuths 0, 360/n, ...

    ``grid_views``: indices into that grid (``elevation_index * num_azimuths + azimuth_index``) to
    keep, in the order given; None keeps every view.
    """
    grid = [(360.0 * k / settings.num_azimuths, float(el))
            for el in settings.elevations for k in range(settings.num_azimuths)]
    if grid_views is not None:
        bad = [int(i) for i in grid_views if not 0 <= int(i) < len(grid)]
        if bad or not len(grid_views):
            raise ValueError(f"grid_views must be a non-empty list of indices in [0, {len(grid)}), got {list(grid_views)}")
        grid = [grid[int(i)] for i in grid_views]
    return [(az, el, frame_camera(look_at(az, el), mesh.vertices)) for az, el in grid]


def _render(mesh: Mesh, camera: Camera, size: int) -> dict:
    from training.render import render_normals_numpy

    return render_normals_numpy(mesh, camera, size, shading="flat")


def quantize_unit(x: np.ndarray) -> np.ndarray:
    """[0, 1] floats -> uint8 (round to nearest, error <= 0.5 / 255)."""
    return np.round(np.clip(np.asarray(x, np.float64), 0.0, 1.0) * 255.0).astype(np.uint8)


def render_shape(mesh: Mesh, settings: RenderSettings = RenderSettings(), timings: dict | None = None,
                 grid_views: Sequence[int] | None = None) -> dict:
    """Render every view of one shape into the arrays of the on-disk format (docs/DATA_FORMAT.md).

    Args:
        mesh: a normalised mesh (world frame).
        settings: sizes, views, line settings.
        timings: if given, accumulates seconds spent in "render", "render_small", "lines", "raster".
        grid_views: render only these views of the grid (:func:`view_cameras`); None renders all.

    Returns:
        dict of numpy arrays; N = views, S = size, s = small_size, P = polylines, Q = points:
        ``sketch`` (N, S, S) uint8 clean drawing, 255 = ink; ``normals256`` (N, S, S, 3) uint8;
        ``silhouette256`` (N, S, S) bool; ``normals64`` (N, s, s, 3) float32 (exact rasterizer
        output); ``silhouette64`` (N, s, s) bool; ``cameras`` (N, 16) float64 framed cameras;
        ``azimuths`` / ``elevations`` (N,) float64 degrees; ``poly_points`` (Q, 2) float32
        pixel coordinates; ``poly_offsets`` (P + 1,) int64 (polyline p is
        ``poly_points[poly_offsets[p]:poly_offsets[p + 1]]``); ``poly_kinds`` (P,) int8;
        ``view_poly_offsets`` (N + 1,) int64 (view i owns polylines
        ``view_poly_offsets[i]:view_poly_offsets[i + 1]``); ``vertices`` (V, 3) float32 and
        ``faces`` (F, 3) int64 (the normalised mesh).
    """
    timings = timings if timings is not None else {}

    def tick(key: str, t0: float) -> float:
        t1 = time.perf_counter()
        timings[key] = timings.get(key, 0.0) + (t1 - t0)
        return t1

    t = time.perf_counter()
    prep = prepare_mesh(mesh, settings.lines)
    t = tick("lines", t)
    views = view_cameras(mesh, settings, grid_views)
    N, S, s = len(views), settings.size, settings.small_size
    out = {
        "sketch": np.zeros((N, S, S), np.uint8),
        "normals256": np.zeros((N, S, S, 3), np.uint8),
        "silhouette256": np.zeros((N, S, S), bool),
        "normals64": np.zeros((N, s, s, 3), np.float32),
        "silhouette64": np.zeros((N, s, s), bool),
        "cameras": np.zeros((N, 16), np.float64),
        "azimuths": np.array([v[0] for v in views], np.float64),
        "elevations": np.array([v[1] for v in views], np.float64),
    }
    points, offsets, kinds, view_offsets = [], [0], [], [0]
    for i, (_, _, cam) in enumerate(views):
        out["cameras"][i] = cam.to_array()
        big = _render(mesh, cam, S)
        t = tick("render", t)
        small = _render(mesh, cam, s)
        t = tick("render_small", t)
        out["normals256"][i] = quantize_unit(big["normals"])
        out["silhouette256"][i] = big["silhouette"]
        out["normals64"][i] = small["normals"]
        out["silhouette64"][i] = small["silhouette"]
        drawing = extract_lines(prep, cam, S, big["depth"], big["face_index"], settings.lines)
        t = tick("lines", t)
        out["sketch"][i] = quantize_unit(rasterize_polylines(drawing.polylines, S))
        t = tick("raster", t)
        for p in drawing.polylines:
            points.append(p.astype(np.float32))
            offsets.append(offsets[-1] + len(p))
        kinds.extend(drawing.kinds.tolist())
        view_offsets.append(view_offsets[-1] + len(drawing.polylines))
    out["poly_points"] = np.concatenate(points) if points else np.zeros((0, 2), np.float32)
    out["poly_offsets"] = np.asarray(offsets, np.int64)
    out["poly_kinds"] = np.asarray(kinds, np.int8)
    out["view_poly_offsets"] = np.asarray(view_offsets, np.int64)
    out["vertices"] = np.asarray(mesh.vertices, np.float32)
    out["faces"] = np.asarray(mesh.faces, np.int64)
    return out


def view_polylines(arrays: dict, view: int) -> list[np.ndarray]:
    """The clean polylines of one view from :func:`render_shape`'s (or a loaded file's) arrays."""
    vo, po, pts = arrays["view_poly_offsets"], arrays["poly_offsets"], arrays["poly_points"]
    return [np.asarray(pts[po[p]:po[p + 1]], np.float64) for p in range(int(vo[view]), int(vo[view + 1]))]
