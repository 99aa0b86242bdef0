"""Cameras and every geometric convention Sketchmesh uses.

This docstring is the one place the conventions are written down; the data
generator, the differentiable rasterizer, the engine, the app and the
evaluation all import from here and point here.

World frame
    Right-handed, metres-free units, **+Y is up**. A shape's "front" faces +Z.

Shape normalisation (:func:`normalize_vertices`)
    Every shape -- procedural, ShapeNet or user mesh -- is centred on the centre
    of its axis-aligned bounding box and scaled uniformly so that the longest
    bounding-box side is 1. A normalised shape lies in [-0.5, 0.5]^3.

Cameras (:class:`Camera`)
    A pinhole camera in the OpenGL convention: in camera space **x points right,
    y up, and the camera looks down -z** (points in front of the camera have
    z < 0). ``p_cam = R @ p_world + t``. Projection to normalised device
    coordinates (NDC)::

        u = focal * x_cam / (-z_cam) + cx        (right is +u)
        v = focal * y_cam / (-z_cam) + cy        (up is +v)

    The visible image is u, v in [-1, 1] (square images only). ``focal`` is
    ``1 / tan(fov_y / 2)``. Depth is ``-z_cam`` (positive in front).

    :func:`look_at` places the camera on a sphere of radius ``distance`` around
    the origin, looking at the origin with +Y up. **Azimuth 0** puts the camera
    on the +Z axis (seeing the shape's front); positive azimuth moves it
    towards +X (counter-clockwise seen from above). **Elevation** is the angle
    above the XZ plane. The paper's views are :func:`paper_views`: 24 azimuths
    (every 15 degrees) at 30 degrees elevation.

Pixels and images
    Images are row-major, **pixel (0, 0) is the top-left**, rows grow
    downwards (y down), and pixel (row i, col j) is sampled at its centre::

        u = (2 * (j + 0.5) / W) - 1,   v = 1 - (2 * (i + 0.5) / H)

    Tensors and ONNX inputs are NCHW float32.

Normal images (:func:`encode_normals`)
    The unit surface normal in **camera space** n = (nx, ny, nz) (nz > 0 faces
    the viewer) is stored as RGB = (n + 1) / 2 in [0, 1]. Background pixels are
    ``NORMAL_BACKGROUND`` = 0 in all three channels. Silhouettes are 1 on the
    shape, 0 elsewhere.

Sketches
    A sketch raster is (H, W) float32 in [0, 1], **1 = ink, 0 = paper** (the
    generator's input is (1, 1, 256, 256) in that encoding). Image files with
    dark strokes on light paper are inverted into it by the engine.

Framing (:func:`frame_camera`)
    What the generator sees is *framed*: the drawing is cropped to its bounding
    box, centred, and scaled so its longer side spans ``1 - 2 * FRAME_MARGIN``
    of the image. The engine frames a user's sketch in 2D; the data generator
    frames each rendered view identically by adjusting that view's camera
    intrinsics (focal and principal point) with :func:`frame_camera`, so the
    normal images, silhouettes and line drawings of a view all agree with it.

The predicted mesh's frame (the "view frame")
    The mesh predictor outputs vertices in the sketch's own view frame: world
    coordinates rotated by the input view's rotation ``R`` (``p_view = R @
    p_world``), *not* translated. In that frame the camera that drew the sketch
    is ``view_camera(focal, principal)`` = identity rotation at
    ``(0, 0, DEFAULT_DISTANCE)``: the mesh appears in the viewport as it was
    drawn, +Y up on screen, the viewer on +Z. Another known view j of the same
    shape sees the view-frame mesh through rotation ``R_j @ R.T``
    (:func:`relative_camera`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DEFAULT_DISTANCE = 2.732
"""Camera distance from the origin (the Neural Mesh Renderer's setting)."""

DEFAULT_FOV_DEG = 30.0
"""Vertical field of view before framing, in degrees."""

PAPER_ELEVATION_DEG = 30.0
PAPER_NUM_AZIMUTHS = 24

FRAME_MARGIN = 0.1
"""Fraction of the image left empty on each side of the framed drawing."""

NORMAL_BACKGROUND = 0.0
"""Value of all three normal-image channels where no surface is visible."""

NEAR = 1e-3
"""Near-plane depth (in camera units); faces with any vertex closer are dropped."""


def focal_from_fov(fov_deg: float) -> float:
    """Return the NDC focal length ``1 / tan(fov / 2)`` for a vertical field of view in degrees."""
    if not 0.0 < fov_deg < 180.0:
        raise ValueError(f"field of view must be in (0, 180) degrees, got {fov_deg}")
    return float(1.0 / np.tan(np.radians(fov_deg) / 2.0))


@dataclass(frozen=True)
class Camera:
    """A pinhole camera; see the module docstring for the conventions.

    Attributes:
        R: (3, 3) float64 world-to-camera rotation.
        t: (3,) float64 translation, ``p_cam = R @ p_world + t``.
        focal: NDC focal length (> 0).
        principal: (2,) NDC principal point (cx, cy).
    """

    R: np.ndarray
    t: np.ndarray
    focal: float = focal_from_fov(DEFAULT_FOV_DEG)
    principal: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        R = np.asarray(self.R, dtype=np.float64)
        t = np.asarray(self.t, dtype=np.float64)
        if R.shape != (3, 3) or t.shape != (3,):
            raise ValueError(f"Camera needs R (3, 3) and t (3,), got {R.shape} and {t.shape}")
        if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
            raise ValueError("Camera R and t must be finite")
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6):
            raise ValueError("Camera R must be a rotation matrix")
        if not (np.isfinite(self.focal) and self.focal > 0):
            raise ValueError(f"Camera focal must be finite and > 0, got {self.focal}")
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "focal", float(self.focal))
        object.__setattr__(self, "principal", (float(self.principal[0]), float(self.principal[1])))

    @property
    def position(self) -> np.ndarray:
        """(3,) camera centre in world coordinates."""
        return -self.R.T @ self.t

    def projection(self) -> np.ndarray:
        """(3, 3) matrix K with ``[u*w, v*w, w] = K @ p_cam`` and ``w = -z_cam``."""
        cx, cy = self.principal
        return np.array([[self.focal, 0.0, -cx], [0.0, self.focal, -cy], [0.0, 0.0, -1.0]])

    def to_array(self) -> np.ndarray:
        """Pack into a (16,) float64 array: R (9), t (3), focal, cx, cy, 0 -- for manifests and batching."""
        return np.concatenate([self.R.ravel(), self.t, [self.focal, *self.principal, 0.0]])

    @staticmethod
    def from_array(a: np.ndarray) -> Camera:
        """Inverse of :meth:`to_array`."""
        a = np.asarray(a, dtype=np.float64)
        if a.shape != (16,):
            raise ValueError(f"camera array must be (16,), got {a.shape}")
        return Camera(a[:9].reshape(3, 3), a[9:12], float(a[12]), (float(a[13]), float(a[14])))


def look_at(
    azimuth_deg: float,
    elevation_deg: float,
    distance: float = DEFAULT_DISTANCE,
    fov_deg: float = DEFAULT_FOV_DEG,
) -> Camera:
    """A camera on a sphere of radius ``distance`` looking at the origin, +Y up.

    Azimuth 0 is on +Z, positive azimuth moves towards +X; elevation is above
    the XZ plane. Elevations of exactly +-90 degrees are rejected (up is
    undefined there).
    """
    if not (np.isfinite(distance) and distance > 0):
        raise ValueError(f"camera distance must be finite and > 0, got {distance}")
    if abs(elevation_deg) >= 90.0:
        raise ValueError(f"elevation must be in (-90, 90) degrees, got {elevation_deg}")
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    eye = distance * np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    back = eye / np.linalg.norm(eye)  # camera +z axis (camera looks down -z)
    right = np.cross(np.array([0.0, 1.0, 0.0]), back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    R = np.stack([right, up, back])
    return Camera(R, -R @ eye, focal_from_fov(fov_deg))


def paper_views(
    num_azimuths: int = PAPER_NUM_AZIMUTHS,
    elevation_deg: float = PAPER_ELEVATION_DEG,
    distance: float = DEFAULT_DISTANCE,
) -> list[tuple[float, float, Camera]]:
    """The paper's views: ``num_azimuths`` evenly spaced azimuths at one elevation.

    Returns:
        A list of (azimuth_deg, elevation_deg, Camera), azimuths 0, 15, ..., 345 by default.
    """
    return [
        (360.0 * k / num_azimuths, elevation_deg, look_at(360.0 * k / num_azimuths, elevation_deg, distance))
        for k in range(num_azimuths)
    ]


def view_camera(focal: float, principal: tuple[float, float] = (0.0, 0.0), distance: float = DEFAULT_DISTANCE) -> Camera:
    """The camera that sees a view-frame mesh as it was drawn: identity rotation at (0, 0, distance)."""
    return Camera(np.eye(3), np.array([0.0, 0.0, -distance]), focal, principal)


def relative_camera(input_view: Camera, other_view: Camera) -> Camera:
    """Camera that renders a mesh given in ``input_view``'s view frame as ``other_view`` sees it.

    A view-frame point is ``p_view = R_in @ p_world``, so ``p_cam = R_o @ R_in.T @ p_view + t_o``.
    """
    return Camera(other_view.R @ input_view.R.T, other_view.t, other_view.focal, other_view.principal)


def project(points: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Project world points to NDC.

    Args:
        points: (N, 3) world coordinates.
        camera: the camera.

    Returns:
        uv: (N, 2) NDC coordinates (+u right, +v up); rows with depth <= NEAR are NaN.
        depth: (N,) ``-z_cam`` (positive in front of the camera).
    """
    p = np.asarray(points, dtype=np.float64) @ camera.R.T + camera.t
    depth = -p[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(depth > NEAR, 1.0 / np.where(depth > NEAR, depth, 1.0), np.nan)
    uv = camera.focal * p[:, :2] * inv[:, None] + np.asarray(camera.principal)
    return uv, depth


def ndc_to_pixel(uv: np.ndarray, size: int) -> np.ndarray:
    """(N, 2) NDC -> (N, 2) continuous pixel coordinates (col, row); pixel centres sit at k + 0.5."""
    uv = np.asarray(uv, dtype=np.float64)
    return np.stack([(uv[:, 0] + 1.0) * 0.5 * size, (1.0 - uv[:, 1]) * 0.5 * size], axis=1)


def pixel_centers_ndc(size: int) -> tuple[np.ndarray, np.ndarray]:
    """NDC (u, v) of the pixel centres of a size x size image, each (size, size), indexed [row, col]."""
    c = (np.arange(size) + 0.5) * (2.0 / size) - 1.0
    u = np.broadcast_to(c[None, :], (size, size))
    v = np.broadcast_to(-c[:, None], (size, size))
    return u.copy(), v.copy()


def frame_camera(camera: Camera, points: np.ndarray, margin: float = FRAME_MARGIN) -> Camera:
    """Adjust a camera's intrinsics so the projected points are framed like an engine sketch.

    The NDC bounding box of the projected points is centred and scaled so its
    longer side spans ``2 * (1 - 2 * margin)`` NDC units, i.e. ``1 - 2 * margin``
    of the image. The rotation and translation are unchanged.

    Args:
        camera: the unframed camera.
        points: (N, 3) world points, typically the mesh vertices (all in front of the camera).
        margin: empty fraction on each side, in [0, 0.5).
    """
    if not 0.0 <= margin < 0.5:
        raise ValueError(f"margin must be in [0, 0.5), got {margin}")
    base = Camera(camera.R, camera.t, camera.focal, (0.0, 0.0))
    uv, _ = project(points, base)
    uv = uv[np.all(np.isfinite(uv), axis=1)]
    if len(uv) == 0:
        raise ValueError("cannot frame: no point is in front of the camera")
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    extent = float(np.max(hi - lo))
    if extent <= 1e-12:
        raise ValueError("cannot frame: the points project to a single point")
    s = 2.0 * (1.0 - 2.0 * margin) / extent
    centre = (lo + hi) / 2.0
    return Camera(camera.R, camera.t, camera.focal * s, (float(-centre[0] * s), float(-centre[1] * s)))


def normalize_vertices(vertices: np.ndarray) -> np.ndarray:
    """Centre on the bounding-box centre and scale so the longest side is 1. Returns a new (V, 3) float64 array."""
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise ValueError(f"vertices must be (V, 3) with V > 0, got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("vertices contain NaN or inf")
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float(np.max(hi - lo))
    if size <= 0:
        raise ValueError("cannot normalise a shape whose bounding box has zero size")
    return (v - (lo + hi) / 2.0) / size


def encode_normals(normals: np.ndarray) -> np.ndarray:
    """Camera-space unit normals (..., 3) in [-1, 1] -> RGB (..., 3) in [0, 1]: (n + 1) / 2."""
    return (np.asarray(normals) + 1.0) * 0.5


def decode_normals(rgb: np.ndarray) -> np.ndarray:
    """Inverse of :func:`encode_normals` (background pixels decode to (-1, -1, -1); mask them first)."""
    return np.asarray(rgb) * 2.0 - 1.0
