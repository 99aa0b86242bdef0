"""Refine a predicted mesh so its silhouette from the sketch's own view matches the drawing.

A network's prediction is an average of what it saw in training; an artist expects the mesh,
seen from their own view, to have *their* outline. This stage (after Sketch2Mesh, Guillard et
al. 2021, but without a network or torch in the loop) deforms the predicted mesh so that its
silhouette from the sketch's view matches a target outline, while the surface stays smooth and
closed and the depth the predictor chose stays where it was.

Design: a screen-space warp (conventions in :mod:`engine.camera`)
    Every vertex is written as (pixel position, depth) in the sketch camera. Refinement moves
    the pixel position only, by a smooth 2D displacement field ``d``; the depth along the view
    ray is kept, so the unseen depth is what the predictor said. Each step

    1. renders the mesh's silhouette ``S`` (a small numpy rasterizer, pixel-centre sampling)
       at ``resolution`` pixels;
    2. finds correspondences between ``S``'s boundary and the target's ``T``:
       *normal rays*: from each boundary pixel of ``S``, along its outward normal (from a
       smoothed signed distance of ``S``), march to where ``T`` changes -- outward while
       inside ``T`` (the mesh must grow there: the long neck), inward while outside it (it must
       shrink) -- and *back-links*: every boundary pixel of ``T`` further than a pixel from
       ``S`` pulls its nearest ``S`` boundary pixel towards itself (thin parts the rays miss);
    3. averages the correspondences over small cells (:data:`CELL_PX`, at most
       :data:`MAX_CONTROL_POINTS` control points) and fits a smoothed thin-plate spline warp
       ``d`` to them (:class:`ThinPlateWarp`): its affine part squashes and shifts the whole
       shape, its kernel part bends the details, and every vertex -- front and back layers,
       interior and contour -- moves by ``d`` at its pixel, so the surface stays smooth. The
       smoothing goes from stiff to supple over the steps (:data:`SMOOTHING_COARSE` ->
       :data:`SMOOTHING_FINE`);
    4. limits the step so that ``x -> x + d(x)`` does not fold: it is scaled until its Jacobian
       determinant is at least :data:`MIN_JACOBIAN` > 0 on a grid over the shape, and the
       motion of any face seen clearly from one side that would still turn round is halved
       until none does (slivers seen edge-on, on the contour, may turn: that is the contour
       sliding).

    The map (pixel, depth) -> (pixel + d(pixel), depth) is a bijection of the space in front
    of the camera where ``d`` does not fold, so faces are untouched (a closed mesh stays
    closed) and sheets at different depths cannot pass through each other. The discrete mesh
    only approximates that, so the result is checked: the step with the best silhouette IoU
    that adds no self-intersection (:func:`engine.postprocess.self_intersections`) is returned.

The sketch camera
    The predictor's mesh lives in the view frame; the camera that drew the sketch is
    :func:`engine.camera.view_camera` with the *framed* intrinsics (:func:`engine.camera.frame_camera`),
    which depend on the true shape. The engine does not know the true shape, so it frames the
    predicted mesh itself (:func:`sketch_camera`): exactly how the data generator framed the
    ground truth, with the prediction in its place. A bounding box is set by the prediction's
    most wrong part, though, so refinement then moves that camera's image by the scale and
    shift that best overlap the prediction's silhouette with the target (:func:`fit_camera`).
    Seen from the sketch's direction the outline is the drawing's either way; the better camera
    keeps it in proportion with the depth the predictor chose (``sketchmesh bench refine``, 156
    clean test sketches, N = 3: voxel IoU -0.004 against -0.016 with the bounding-box framing).

The target outline (:func:`target_outline`)
    The drawing's filled region: ink, closed with a small morphological closing, then
    everything that cannot be reached from the image border, cut back by half a stroke to the
    strokes' centre lines, where the contours lie (:func:`stroke_centre_region`). Where the drawing is not closed
    (the fill is not much more than the ink itself, or disagrees with the generator's
    silhouette) the generator's silhouette (normal-image pixels off the background) is the
    target instead; :func:`refine_prediction` (the engine's, the app's) does not refine to it and leaves the
    mesh as predicted, with a warning. On DATA2's validation split (``sketchmesh bench refine --split val``, which
    reports the target's own IoU against the true silhouette) this picks the drawing for 98 % of
    clean sketches, the target then at IoU 0.962 (0.910 before the cut back to the centre lines),
    and for 72 % of strongly augmented ones (0.759 in all).

Failure modes never crash and never give NaN: an empty or tiny target, a mesh behind the
camera, a non-finite result, or a refinement that lowers the silhouette IoU returns the
unrefined mesh with a ``warning``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from engine.camera import DEFAULT_FOV_DEG, NEAR, Camera, focal_from_fov, frame_camera, view_camera
from engine.contract import SKETCH_SIZE, SKETCH_STROKE_WIDTH_PX
from engine.mesh import Mesh, is_closed

DEFAULT_STEPS = 3
"""Refinement steps the app uses when refinement is on (chosen from ``sketchmesh bench refine``)."""

MAX_STEPS = 100
"""Largest accepted step count."""

DEFAULT_RESOLUTION = 96
"""Side of the square image the refinement works in (the 256 sketch is area-downsampled)."""

FIT_RESOLUTION = 64
"""Side of the images :func:`fit_camera` compares."""

FIT_SCALES = 7
FIT_SCALE_RANGE = 0.15
""":func:`fit_camera` tries this many scales, log-spaced over +-FIT_SCALE_RANGE around the area match."""

SMOOTHING_COARSE = 1e-1
SMOOTHING_FINE = 1e-3
"""Thin-plate smoothing of the first and the last step (the steps between go geometrically from
one to the other). Stiff early steps move the whole shape (a squash, a shift, the interior
following the outline); supple late steps fit details (a neck, a wing tip)."""

MAX_MARCH = 0.3
"""Longest normal-ray march, as a fraction of the image side."""

MIN_JACOBIAN = 0.25
"""Smallest Jacobian determinant of one step's map ``x -> x + d(x)`` (1 = no area change): a step
may squeeze an area to a quarter, never fold it."""

FOLD_AREA_FRACTION = 0.2
"""Faces whose screen area is above this fraction of the median are checked for folds each step."""

FOLD_MIN_HEIGHT_PX = 1.5
"""Faces thinner than this (working pixels) on screen are seen edge-on and not checked for folds."""

FOLD_ROUNDS = 8
"""Times a step halves the motion of the vertices of folding faces before it gives up."""

INJECTIVITY_GRID = 24
"""Side of the grid on which each step's warp is checked for folds (over the shape's bounding box)."""

CELL_PX = 3.0
"""Correspondences are averaged over cells of this many working pixels: one control point per cell."""

MAX_INTERSECTION_CHECKS = 3
"""Refined steps (best IoU first) checked for self-intersections before giving up and returning
the unrefined mesh."""

MAX_CONTROL_POINTS = 100
"""Most thin-plate control points per step (the solve is cubic in their number)."""

MIN_TARGET_FRACTION = 0.002
"""A target covering less than this fraction of the image is treated as empty."""

CLOSED_FILL_RATIO = 1.6
"""The drawing counts as closed when its filled region is at least this many times its ink."""

FILL_AGREEMENT_IOU = 0.6
"""Smallest IoU between the drawing's fill and the generator's silhouette for the fill to be used."""

CLOSING_PX = 9
"""Side of the square closing kernel (pixels at 256) that bridges small gaps in the outline."""

STROKE_HALF_WIDTH_PX = SKETCH_STROKE_WIDTH_PX / 2.0
"""How far (pixels at SKETCH_SIZE) a drawing's fill reaches past the outline: the outer half of the outline's
strokes, which :func:`stroke_centre_region` cuts away."""

GENERATOR_SILHOUETTE_THRESHOLD = 0.25
"""A normal-image pixel whose largest channel exceeds this is on the generator's silhouette
(background is 0; a visible surface has a blue channel (nz + 1) / 2 >= 0.5)."""

MAX_RASTER_SAMPLES = 4_000_000
"""(face, row) pairs :func:`render_silhouette` may visit; a mesh that needs more is refused."""


@dataclass(frozen=True, eq=False)
class RefineResult:
    """What :func:`refine_mesh` did.

    Attributes:
        mesh: the refined mesh (same faces), or the input mesh when refinement did not run.
        steps: steps run (0 when refinement was skipped).
        iou_before: silhouette IoU of the input mesh against the target, at the working resolution
            (NaN when it could not be measured).
        iou_after: the same for the returned mesh.
        warning: why the unrefined mesh was returned, else None.
        note: why refinement stopped before ``steps`` or stepped back to an earlier step (the
            result is still refined), else None.
        camera: the sketch camera the IoUs were measured in (None when refinement did not start).
        crossings: crossing face pairs of ``mesh`` where refinement counted them
            (:func:`engine.postprocess.self_intersections`), else None: a fold repair of a mesh known to have none
            has nothing to do.
    """

    mesh: Mesh
    steps: int
    iou_before: float
    iou_after: float
    warning: str | None = None
    note: str | None = None
    camera: Camera | None = None
    crossings: int | None = None


# --------------------------------------------------------------------------- camera and target
def sketch_camera(mesh: Mesh, fov_deg: float = DEFAULT_FOV_DEG) -> Camera:
    """The camera that sees the view-frame ``mesh`` framed like the sketch (see the module docstring).

    Raises:
        ValueError: the mesh has no vertex in front of the camera or projects to a point.
    """
    return frame_camera(view_camera(focal_from_fov(fov_deg)), np.asarray(mesh.vertices, np.float64))


def _target_at(target: np.ndarray, resolution: int) -> np.ndarray:
    """(H, H) mask (bool or [0, 1]) -> (resolution, resolution) bool, area-averaged when shrinking."""
    t = np.asarray(target)
    if t.dtype != bool:
        t = t.astype(np.float32) > 0.5
    if t.shape[0] != resolution:
        interp = cv2.INTER_AREA if t.shape[0] > resolution else cv2.INTER_LINEAR
        t = cv2.resize(t.astype(np.float32), (resolution, resolution), interpolation=interp) >= 0.5
    return t


def _similar(camera: Camera, scale: float, shift: tuple[float, float]) -> Camera:
    """``camera`` whose image is scaled by ``scale`` about the NDC origin, then moved by ``shift`` (NDC)."""
    cx, cy = camera.principal
    return Camera(camera.R, camera.t, camera.focal * scale, (cx * scale + shift[0], cy * scale + shift[1]))


def _ndc_moments(mask: np.ndarray) -> tuple[float, float, float]:
    """(area, mean u, mean v) of a (n, n) bool mask in NDC units (pixel centres; v up)."""
    rows, cols = np.nonzero(mask)
    n = mask.shape[0]
    u = (cols + 0.5) / n * 2.0 - 1.0
    v = 1.0 - (rows + 0.5) / n * 2.0
    return len(rows) * (2.0 / n) ** 2, float(u.mean()), float(v.mean())


def fit_camera(mesh: Mesh, target: np.ndarray, camera: Camera | None = None, *,
               resolution: int = FIT_RESOLUTION) -> Camera:
    """The sketch camera refinement works in: ``camera`` [:func:`sketch_camera`] moved to fit ``target``.

    Framing the prediction by its bounding box (:func:`sketch_camera`) lets one wrong part set the
    scale: a prediction with a spurious bulge is framed too small, and refinement then blows the
    rest of it up to the drawing's size. Here the image is scaled and shifted (the camera's focal
    and principal point; same centre and rotation, so depth is untouched) so the prediction's
    silhouette best overlaps the target: the area and centroid of the silhouette matched first,
    then the scale searched over +-15 % (:data:`FIT_SCALES` candidates, plus the bounding-box
    framing itself) for the best IoU at ``resolution`` pixels. Seen from the sketch's direction
    the refined outline is the same up to zoom whichever camera is used; the camera sets how
    that outline sits against the depth the predictor chose, i.e. the mesh's 3D proportions.

    Args:
        mesh: the predicted mesh in the view frame.
        target: (H, H) target outline (bool, or float in [0, 1]).
        camera: the starting camera; None uses :func:`sketch_camera` of ``mesh``.
        resolution: side of the images compared.

    Returns:
        The best camera; the starting one where the silhouette or the target is empty or the
        mesh cannot be projected.

    Raises:
        ValueError: as :func:`sketch_camera` when ``camera`` is None and the mesh cannot be framed.
    """
    base = camera if camera is not None else sketch_camera(mesh)
    t = _target_at(target, resolution)
    closed = is_closed(mesh.faces)

    def silhouettes(cams: list[Camera]) -> np.ndarray | None:
        """(K, n, n) silhouettes of ``mesh`` in ``cams``; None where one cannot be projected or rasterized."""
        poses = []
        for cam in cams:
            px, depth = pixel_coords(mesh.vertices, cam, resolution)
            if not (np.all(np.isfinite(px)) and np.all(depth > NEAR)):
                return None
            poses.append(px)
        try:
            return render_silhouettes(np.stack(poses), mesh.faces, resolution, closed=closed)
        except ValueError:
            return None

    sil = silhouettes([base])
    if sil is None or not sil[0].any() or not t.any():
        return base
    best, best_iou = base, silhouette_iou(sil[0], t)
    a0, u0, v0 = _ndc_moments(sil[0])
    a1, u1, v1 = _ndc_moments(t)
    s0 = float(np.sqrt(a1 / a0))
    cams = []
    for k in np.linspace(-FIT_SCALE_RANGE, FIT_SCALE_RANGE, FIT_SCALES):
        s = s0 * float(np.exp(k))  # about the silhouette's centroid, onto the target's
        cams.append(_similar(base, s, (u1 - s * u0, v1 - s * v0)))
    # every candidate in one pass (render_silhouettes); the depths are the base camera's (same centre and
    # rotation), so a candidate fails only where its scale overflows, and then each is tried alone
    sils = silhouettes(cams)
    for i, cam in enumerate(cams):
        one = sils[i:i + 1] if sils is not None else silhouettes([cam])
        iou = -1.0 if one is None else silhouette_iou(one[0], t)
        if iou > best_iou:
            best, best_iou = cam, iou
    return best


def fill_drawing(sketch: np.ndarray, closing_px: int = CLOSING_PX) -> np.ndarray:
    """The region a line drawing encloses: ink plus everything the border cannot reach.

    Args:
        sketch: (H, W) float in [0, 1], 1 = ink (:mod:`engine.camera`).
        closing_px: side of the closing kernel bridging small gaps (0 = none).

    Returns:
        (H, W) bool.
    """
    ink = (np.asarray(sketch, np.float32) > 0.5).astype(np.uint8)
    if closing_px > 1:
        ink = cv2.morphologyEx(ink, cv2.MORPH_CLOSE, np.ones((closing_px, closing_px), np.uint8))
    # a one-pixel paper frame so the flood fill reaches every border pixel, even where ink touches the edge
    padded = np.pad(ink, 1)
    mask = np.zeros((padded.shape[0] + 2, padded.shape[1] + 2), np.uint8)
    cv2.floodFill(padded, mask, (0, 0), 2)
    return padded[1:-1, 1:-1] != 2


def generator_silhouette(normals: np.ndarray) -> np.ndarray:
    """(H, W, 3) or (1, 3, H, W) normal image in [0, 1] -> (H, W) bool silhouette (off the background)."""
    a = np.asarray(normals, np.float32)
    if a.ndim == 4:
        a = a[0].transpose(1, 2, 0)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"normals must be (H, W, 3) or (1, 3, H, W), got {np.shape(normals)}")
    # channel by channel: numpy's max over a last axis of 3 takes 2.3 ms at 256 x 256, this 0.1
    return np.maximum(np.maximum(a[..., 0], a[..., 1]), a[..., 2]) > GENERATOR_SILHOUETTE_THRESHOLD


def target_outline(sketch: np.ndarray, normals: np.ndarray | None = None) -> tuple[np.ndarray, str]:
    """The outline refinement aims for: the drawing's filled region, or the generator's silhouette.

    The drawing counts as closed when its filled region is at least :data:`CLOSED_FILL_RATIO`
    times its ink and, given the normal image, overlaps the generator's silhouette with IoU at
    least :data:`FILL_AGREEMENT_IOU` (a broken outline leaks: its fill is little more than the
    strokes, or a few closed pockets of the shape).

    Args:
        sketch: (H, W) float in [0, 1], 1 = ink: the framed raster the generator saw.
        normals: the generator's normal image ((H, W, 3) or (1, 3, H, W)), or None.

    Returns:
        (mask (H, W) bool, source) with source ``"drawing"`` (the drawing is closed) or
        ``"generator"`` (it is not, and the normal image was given).
    """
    ink = np.asarray(sketch, np.float32) > 0.5
    fill = fill_drawing(sketch)
    closed = fill.sum() >= CLOSED_FILL_RATIO * max(int(ink.sum()), 1)
    if normals is None:
        return stroke_centre_region(fill), "drawing"
    gen = generator_silhouette(normals)
    if gen.shape != fill.shape:
        gen = cv2.resize(gen.astype(np.uint8), fill.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0
    if closed and silhouette_iou(fill, gen) >= FILL_AGREEMENT_IOU:
        return stroke_centre_region(fill), "drawing"
    return gen, "generator"


def stroke_centre_region(fill: np.ndarray) -> np.ndarray:
    """A drawing's filled region cut back to its outline strokes' centre lines.

    The contours of a shape lie on the centre lines of the strokes that draw them (the data generator draws
    the projected contours, the engine redraws a user's strokes about their centre lines, both
    :data:`engine.contract.SKETCH_STROKE_WIDTH_PX` wide at :data:`engine.contract.SKETCH_SIZE`), so the fill, which
    takes the whole outline stroke in, overshoots the outline by half a stroke all round (the target's IoU against the
    true silhouette on clean validation drawings 0.910 uncut, 0.962 cut back: ``reproduce_models.sh refine-target``). The outer half stroke is
    eroded away, by :data:`STROKE_HALF_WIDTH_PX` scaled to the mask's size (nothing where that is under half a
    pixel); a fill too thin to survive the erosion is returned as it is.
    """
    f = np.asarray(fill, bool)
    r = int(round(STROKE_HALF_WIDTH_PX * f.shape[0] / SKETCH_SIZE))
    if r < 1 or not f.any():
        return f
    eroded = cv2.erode(f.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))) > 0
    return eroded if eroded.any() else f


# --------------------------------------------------------------------------- rasterizer
def pixel_coords(vertices: np.ndarray, camera: Camera, size: int) -> tuple[np.ndarray, np.ndarray]:
    """View-frame vertices -> ((V, 2) continuous pixel coordinates (col, row), (V,) depth).

    Pixel (i, j) has its centre at (j + 0.5, i + 0.5) (:func:`engine.camera.ndc_to_pixel`).
    Vertices at depth <= NEAR get NaN coordinates.
    """
    p = np.asarray(vertices, np.float64) @ camera.R.T + camera.t
    depth = -p[:, 2]
    ok = depth > NEAR
    inv = np.where(ok, 1.0 / np.where(ok, depth, 1.0), np.nan)
    u = camera.focal * p[:, 0] * inv + camera.principal[0]
    v = camera.focal * p[:, 1] * inv + camera.principal[1]
    return np.stack([(u + 1.0) * 0.5 * size, (1.0 - v) * 0.5 * size], axis=1), depth


def render_silhouette(px: np.ndarray, faces: np.ndarray, size: int) -> np.ndarray:
    """Silhouette of triangles in pixel space: a pixel is covered when its centre is in a triangle.

    A scanline rasterizer vectorised over (face, row) pairs: each pair adds +1 at the first and
    -1 after the last covered pixel of its row, and a cumulative sum along rows counts coverage,
    so overlapping faces (front and back layers) need no depth test.

    Args:
        px: (V, 2) float continuous pixel coordinates (col, row), finite.
        faces: (F, 3) int vertex indices.
        size: image side.

    Returns:
        (size, size) bool; concretely ``mask[i, j]`` is True when the point (j + 0.5, i + 0.5)
        lies inside (or on an edge of) at least one face.

    Raises:
        ValueError: the faces span more than :data:`MAX_RASTER_SAMPLES` (face, row) pairs.
    """
    return render_silhouettes(np.asarray(px)[None], faces, size)[0]


def render_silhouettes(px: np.ndarray, faces: np.ndarray, size: int, *, closed: bool = False) -> np.ndarray:
    """:func:`render_silhouette` of K poses of one mesh at once: (K, V, 2) pixel coordinates -> (K, size, size) bool.

    The same pixels as K calls (each pose is clipped to its own image), in one pass of array operations: a 1280-face
    mesh at 64 pixels spans about 1,200 (face, row) pairs, so much of a single image's time is the fixed cost of the
    operations, which K poses share (:func:`fit_camera`'s candidate cameras).

    ``closed``: the faces form a closed, consistently oriented surface (every edge in two faces, once each way; see
    :func:`engine.mesh.is_closed`) that lies in front of the camera. Then every sight line that meets the surface
    crosses it as often inwards as outwards (the camera is outside it), so the faces of either winding on screen cover
    the whole silhouette: only those of the winding with fewer (face, row) pairs are rasterized, about half. The pixels
    are the same but where a pixel centre lies on the silhouette's edge to within rounding (a contour edge's two faces
    interpolate it from opposite ends).

    Raises:
        ValueError: the poses together span more than :data:`MAX_RASTER_SAMPLES` (face, row) pairs.
    """
    px = np.asarray(px, np.float64)
    K = px.shape[0]
    F = len(faces)
    tri = px[:, np.asarray(faces, np.int64)].reshape(K * F, 3, 2)  # pose-major: index = pose * F + face
    ys = tri[..., 1]
    r0 = np.clip(np.ceil(ys.min(axis=1) - 0.5), 0, size).astype(np.int64)
    r1 = np.clip(np.floor(ys.max(axis=1) - 0.5), -1, size - 1).astype(np.int64)
    n = np.maximum(r1 - r0 + 1, 0)
    if closed and F:
        area = _signed_areas_of(tri).reshape(K, F)
        rows = n.reshape(K, F)
        cw, ccw = area < 0, area > 0
        fewer = (rows * cw).sum(axis=1) <= (rows * ccw).sum(axis=1)
        n = np.where(np.where(fewer[:, None], cw, ccw), rows, 0).ravel()
    total = int(n.sum())
    if total == 0:
        return np.zeros((K, size, size), bool)
    if total > MAX_RASTER_SAMPLES:
        raise ValueError(f"the mesh spans too many rows to rasterize ({total})")
    f = np.repeat(np.arange(len(n)), n)
    row = r0[f] + np.arange(total) - np.repeat(np.cumsum(n) - n, n)
    y = row + 0.5
    t = tri[f]  # (T, 3, 2)
    xl = np.full(total, np.inf)
    xr = np.full(total, -np.inf)
    for k in range(3):
        p, q = t[:, k], t[:, (k + 1) % 3]
        dy = q[:, 1] - p[:, 1]
        lo_y, hi_y = np.minimum(p[:, 1], q[:, 1]), np.maximum(p[:, 1], q[:, 1])
        ok = (y >= lo_y) & (y <= hi_y)
        flat = np.abs(dy) < 1e-12
        s = np.where(flat, 0.0, (y - p[:, 1]) / np.where(flat, 1.0, dy))
        x = p[:, 0] + s * (q[:, 0] - p[:, 0])
        xa = np.where(flat, np.minimum(p[:, 0], q[:, 0]), x)
        xb = np.where(flat, np.maximum(p[:, 0], q[:, 0]), x)
        xl = np.where(ok, np.minimum(xl, xa), xl)
        xr = np.where(ok, np.maximum(xr, xb), xr)
    c0 = np.clip(np.ceil(xl - 0.5), 0, size).astype(np.int64)
    c1 = np.clip(np.floor(xr - 0.5), -1, size - 1).astype(np.int64)
    ok = (c1 >= c0) & np.isfinite(xl) & np.isfinite(xr)
    row = row[ok] + (f[ok] // F) * size  # the pose's image stacked below the ones before it
    c0, c1 = c0[ok], c1[ok]
    width = size + 1
    cells = K * size * width
    diff = np.bincount(row * width + c0, minlength=cells) - np.bincount(row * width + c1 + 1, minlength=cells)
    return np.cumsum(diff.reshape(K * size, width), axis=1)[:, :size].reshape(K, size, size) > 0


def silhouette_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two bool masks (1.0 when both are empty)."""
    union = int(np.count_nonzero(a | b))
    return 1.0 if union == 0 else int(np.count_nonzero(a & b)) / union


# --------------------------------------------------------------------------- one step
def _signed_distance(mask: np.ndarray) -> np.ndarray:
    """Signed distance in pixels, > 0 inside ``mask``, < 0 outside (float32)."""
    m = mask.astype(np.uint8)
    inside = cv2.distanceTransform(m, cv2.DIST_L2, 3)
    outside = cv2.distanceTransform(1 - m, cv2.DIST_L2, 3)
    return inside - outside


def _boundary(mask: np.ndarray) -> np.ndarray:
    """(N, 2) int (row, col) of mask pixels with a 4-neighbour outside the mask."""
    m = mask.astype(np.uint8)
    eroded = cv2.erode(m, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return np.argwhere((m > 0) & (eroded == 0))


def correspondences(silhouette: np.ndarray, target: np.ndarray, max_march_px: int) -> tuple[np.ndarray, np.ndarray]:
    """Where the silhouette's boundary should go: normal rays and back-links (module docstring, step 2).

    Args:
        silhouette, target: (H, W) bool masks.
        max_march_px: longest normal-ray march in pixels.

    Returns:
        (points (K, 2), displacements (K, 2)) float64 in pixels (col, row): boundary pixel centres
        of ``silhouette`` and where each should move; K = 0 when either mask is empty.
    """
    H, W = silhouette.shape
    src = _boundary(silhouette)  # (N, 2) row, col
    empty = np.zeros((0, 2))
    if len(src) == 0 or not target.any():
        return empty, empty
    sd_s = cv2.GaussianBlur(_signed_distance(silhouette), (0, 0), 1.5)
    gy, gx = np.gradient(sd_s)
    r, c = src[:, 0], src[:, 1]
    n = -np.stack([gx[r, c], gy[r, c]], axis=1)  # outward normal (col, row)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-6)
    start_in = target[r, c]
    steps = np.arange(1, max_march_px + 1, dtype=np.float64)
    direction = np.where(start_in[:, None], n, -n)
    origin = np.stack([c + 0.5, r + 0.5], axis=1)
    pos = origin[:, None, :] + steps[None, :, None] * direction[:, None, :]
    inside_img = (pos[..., 0] >= 0) & (pos[..., 0] < W) & (pos[..., 1] >= 0) & (pos[..., 1] < H)
    pc = np.clip(np.floor(pos[..., 0]).astype(np.int64), 0, W - 1)
    pr = np.clip(np.floor(pos[..., 1]).astype(np.int64), 0, H - 1)
    t = target[pr, pc] & inside_img
    changed = t != start_in[:, None]  # (N, M): the first sample across T's boundary
    hit = changed.any(axis=1)
    first = np.where(hit, changed.argmax(axis=1), max_march_px - 1)
    # the boundary lies between the last unchanged sample and the first changed one
    dist = np.where(hit, steps[first] - 0.5, steps[first])
    # a shrinking ray that leaves the silhouette before meeting the target (a part the target
    # lacks) moves at most to the middle of the part, so the part thins instead of folding over
    exits = ~silhouette[pr, pc] | ~inside_img
    exit_first = np.where(exits.any(axis=1), exits.argmax(axis=1), max_march_px - 1)
    dist = np.where(start_in, dist, np.minimum(dist, 0.5 * steps[exit_first]))
    points, disp = [origin], [direction * dist[:, None]]
    # back-links: target boundary far from the silhouette pulls its nearest silhouette boundary pixel
    tb = _boundary(target)
    if len(tb):
        not_edge = np.ones((H, W), np.uint8)
        not_edge[r, c] = 0
        d_edge, labels = cv2.distanceTransformWithLabels(not_edge, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
        far = d_edge[tb[:, 0], tb[:, 1]] > 1.5
        if np.any(far):
            tb = tb[far]
            zeros = np.argwhere(not_edge == 0)  # labels number the zero pixels from 1 in row-major order
            near = zeros[labels[tb[:, 0], tb[:, 1]] - 1]
            points.append(np.stack([near[:, 1] + 0.5, near[:, 0] + 0.5], axis=1))
            disp.append(np.stack([tb[:, 1] - near[:, 1], tb[:, 0] - near[:, 0]], axis=1).astype(np.float64))
    return np.concatenate(points), np.concatenate(disp)


def _pool(points: np.ndarray, disp: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Average correspondences over square cells of side ``cell`` pixels (one control point per cell)."""
    key = np.floor(points / cell).astype(np.int64)
    _, inv = np.unique(key[:, 0] * 1_000_003 + key[:, 1], return_inverse=True)
    inv = inv.ravel()
    count = np.bincount(inv).astype(np.float64)[:, None]
    p = np.stack([np.bincount(inv, weights=points[:, j]) for j in range(2)], axis=1) / count
    d = np.stack([np.bincount(inv, weights=disp[:, j]) for j in range(2)], axis=1) / count
    return p, d


def _tps_kernel(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, M) thin-plate kernel ``U = r^2 log r`` between point sets (N, 2) and (M, 2) (U(0) = 0)."""
    r2 = (a * a).sum(axis=1)[:, None] + (b * b).sum(axis=1)[None, :] - 2.0 * (a @ b.T)
    np.maximum(r2, 0.0, out=r2)
    return 0.5 * r2 * np.log(r2 + 1e-30)


class ThinPlateWarp:
    """A 2D thin-plate spline displacement ``d(x)`` fitted to control points, with smoothing.

    Solves ``[[K + lam I, P], [P^T, 0]] [w; a] = [d; 0]`` with ``K_ij = U(|c_i - c_j|)``,
    ``U(r) = r^2 log r`` and ``P = [1, c]``; coordinates are divided by ``scale`` so ``lam`` does not
    depend on the image size. ``d(x) = sum_i w_i U(|x - c_i|) + a_0 + a_1 x + a_2 y``: the affine
    part moves the whole shape (a squash, a shift), the kernel part the details.
    """

    def __init__(self, points: np.ndarray, disp: np.ndarray, lam: float, scale: float) -> None:
        self.scale = float(scale)
        c = points / self.scale
        n = len(c)
        A = np.zeros((n + 3, n + 3))
        A[:n, :n] = _tps_kernel(c, c) + lam * np.eye(n)
        A[:n, n] = 1.0
        A[:n, n + 1:] = c
        A[n, :n] = 1.0
        A[n + 1:, :n] = c.T
        rhs = np.zeros((n + 3, 2))
        rhs[:n] = disp
        try:
            sol = np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError:
            sol = np.linalg.lstsq(A, rhs, rcond=None)[0]
        self.centres, self.w, self.a = c, sol[:n], sol[n:]

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) pixel positions -> (N, 2) displacements in pixels."""
        x = xy / self.scale
        return _tps_kernel(x, self.centres) @ self.w + self.a[0] + x @ self.a[1:]


def _injective_scale_at(warp: ThinPlateWarp, lo: np.ndarray, hi: np.ndarray, cells: int = INJECTIVITY_GRID) -> float:
    """:func:`_injective_scale` of ``warp`` sampled on a square ``cells`` x ``cells`` grid covering [lo, hi]."""
    side = float(np.max(hi - lo))
    if not np.isfinite(side) or side <= 0:
        return 1.0
    centre = (lo + hi) / 2.0
    g = np.linspace(-side / 2.0, side / 2.0, cells)
    X, Y = np.meshgrid(centre[0] + g, centre[1] + g)
    field = warp(np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(cells, cells, 2)
    return _injective_scale(field, side / (cells - 1))


def _injective_scale(field: np.ndarray, k: float) -> float:
    """Largest ``a`` in [0, 1] with ``det(I + a * J) >= MIN_JACOBIAN`` on every cell of the field.

    ``J`` is the field's Jacobian (finite differences, per full-resolution pixel). The map
    ``x -> x + a d(x)`` is then a local diffeomorphism that is the identity far away, hence a
    bijection of the plane: it squeezes and stretches but never folds.
    ``det(I + a J) = 1 + a tr(J) + a^2 det(J)``; the answer is the smallest positive root of
    ``1 + a tr + a^2 det = MIN_JACOBIAN`` over all cells, or 1 when there is none below 1.
    """
    dx_dr, dx_dc = np.gradient(field[..., 0])
    dy_dr, dy_dc = np.gradient(field[..., 1])
    tr = ((dx_dc + dy_dr) / k).ravel().astype(np.float64)
    dt = ((dx_dc * dy_dr - dx_dr * dy_dc) / k**2).ravel().astype(np.float64)
    c = 1.0 - MIN_JACOBIAN
    with np.errstate(divide="ignore", invalid="ignore"):
        # linear case (det ~ 0): 1 + a tr = MIN  ->  a = -c / tr for tr < 0
        lin = np.where(tr < 0, -c / tr, np.inf)
        disc = tr * tr - 4.0 * dt * c
        sq = np.sqrt(np.maximum(disc, 0.0))
        r1 = (-tr - sq) / (2.0 * dt)
        r2 = (-tr + sq) / (2.0 * dt)
        roots = np.stack([r1, r2])
        roots = np.where((roots > 0) & (disc >= 0)[None], roots, np.inf).min(axis=0)
    a = np.where(np.abs(dt) < 1e-12, lin, roots)
    best = float(np.min(a)) if a.size else np.inf
    return 1.0 if not np.isfinite(best) or best >= 1.0 else max(0.0, 0.9 * best)


def _damp_folds(px: np.ndarray, d: np.ndarray, faces: np.ndarray) -> np.ndarray | None:
    """``px + d`` with the motion of vertices of folding faces halved until no face folds.

    A face folds when it is seen clearly from one side (screen area above
    :data:`FOLD_AREA_FRACTION` of the median, and no thinner than :data:`FOLD_MIN_HEIGHT_PX`) and
    the step turns it round. Nearly edge-on faces (slivers on the contour) may turn: that is the
    contour sliding. Returns None when halving
    :data:`FOLD_ROUNDS` times does not remove every fold.
    """
    area = _signed_areas(px, faces)
    t = px[faces]
    longest = np.max(np.linalg.norm(t - np.roll(t, 1, axis=1), axis=2), axis=1)
    height = np.abs(area) / np.maximum(longest, 1e-12)  # the face's smallest height in pixels
    checked = (np.abs(area) > FOLD_AREA_FRACTION * float(np.median(np.abs(area)))) & (height > FOLD_MIN_HEIGHT_PX)
    f = faces[checked]
    orient = np.sign(area[checked])
    d = d.copy()
    for _ in range(FOLD_ROUNDS):
        trial = px + d
        flipped = np.sign(_signed_areas(trial, f)) * orient < 0
        if not np.any(flipped):
            return trial
        d[np.unique(f[flipped])] *= 0.5
    return None


def _signed_areas(px: np.ndarray, faces: np.ndarray) -> np.ndarray:
    return _signed_areas_of(px[faces])


def _signed_areas_of(t: np.ndarray) -> np.ndarray:
    """(N, 3, 2) screen triangles -> (N,) twice their signed areas."""
    return (t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1]) - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0])


def _unproject(px: np.ndarray, depth: np.ndarray, camera: Camera, size: int) -> np.ndarray:
    """Inverse of :func:`pixel_coords`: (V, 2) pixel coordinates at (V,) depths -> (V, 3) view-frame points."""
    u = px[:, 0] * 2.0 / size - 1.0
    v = 1.0 - px[:, 1] * 2.0 / size
    x = (u - camera.principal[0]) * depth / camera.focal
    y = (v - camera.principal[1]) * depth / camera.focal
    p_cam = np.stack([x, y, -depth], axis=1)
    return (p_cam - camera.t) @ camera.R


# --------------------------------------------------------------------------- the stage
def refine_mesh(
    mesh: Mesh,
    target: np.ndarray,
    steps: int = DEFAULT_STEPS,
    *,
    camera: Camera | None = None,
    resolution: int = DEFAULT_RESOLUTION,
    smoothing: tuple[float, float] = (SMOOTHING_COARSE, SMOOTHING_FINE),
    check_intersections: bool = True,
) -> RefineResult:
    """Move the mesh's vertices in the sketch's image plane so its silhouette matches ``target``.

    Args:
        mesh: the predicted mesh in the view frame (:mod:`engine.camera`).
        target: (H, W) bool target outline in the sketch's pixels (H = W; any size, usually 256).
        steps: refinement steps, 0..:data:`MAX_STEPS` (0 returns the mesh unchanged).
        camera: the sketch camera; None uses :func:`fit_camera` of ``mesh`` and ``target`` (the
            result's ``camera``).
        resolution: side of the working image.
        smoothing: (first, last) step's thin-plate smoothing ``lam`` (larger = stiffer, closer to affine).
        check_intersections: count self-intersections of the result (:func:`engine.postprocess.self_intersections`,
            a few ms) and step back to an earlier step if refinement added any.

    Returns:
        A :class:`RefineResult`. Refinement never raises on degenerate geometry or targets:
        it returns the unrefined mesh with a ``warning`` instead.

    Raises:
        ValueError: bad arguments (not a Mesh, a non-square or non-2D target, steps out of range).
    """
    if not isinstance(mesh, Mesh):
        raise ValueError(f"mesh must be an engine.mesh.Mesh, got {type(mesh).__name__}")
    t = np.asarray(target)
    if t.ndim != 2 or t.shape[0] != t.shape[1] or t.shape[0] < 8:
        raise ValueError(f"target must be a square (H, W) mask with H >= 8, got {t.shape}")
    if not isinstance(steps, (int, np.integer)) or not 0 <= steps <= MAX_STEPS:
        raise ValueError(f"steps must be an int in [0, {MAX_STEPS}], got {steps!r}")
    if not isinstance(resolution, (int, np.integer)) or not 16 <= resolution <= 1024:
        raise ValueError(f"resolution must be an int in [16, 1024], got {resolution!r}")
    if len(smoothing) != 2 or not all(np.isfinite(x) and 0.0 < x <= 1e3 for x in smoothing):
        raise ValueError(f"smoothing must be two values in (0, 1000], got {smoothing}")
    nan = float("nan")
    if steps == 0:
        return RefineResult(mesh, 0, nan, nan)

    def skip(why: str, before: float = nan) -> RefineResult:
        return RefineResult(mesh, 0, before, before, f"refinement skipped: {why}; the mesh is unrefined")

    t = _target_at(t, resolution)
    if t.sum() < MIN_TARGET_FRACTION * resolution * resolution:
        return skip("the target outline is empty or too small")
    if t.all():
        return skip("the target outline fills the whole image")
    if mesh.num_faces == 0:
        return skip("the mesh has no faces")
    try:
        cam = camera if camera is not None else fit_camera(mesh, target)
    except ValueError as exc:
        return skip(f"no sketch camera ({exc})")
    px, depth = pixel_coords(mesh.vertices, cam, resolution)
    if not (np.all(np.isfinite(px)) and np.all(depth > NEAR)):
        return skip("part of the mesh is behind the sketch camera")
    faces = mesh.faces
    closed = is_closed(faces)  # half the faces rasterized (render_silhouettes)
    try:
        sil = render_silhouettes(px[None], faces, resolution, closed=closed)[0]
    except ValueError as exc:
        return skip(str(exc))
    iou0 = silhouette_iou(sil, t)
    lams = np.geomspace(smoothing[0], smoothing[1], int(steps)) if steps > 1 else np.array([np.sqrt(smoothing[0] * smoothing[1])])
    max_march = max(2, int(round(MAX_MARCH * resolution)))
    states: list[tuple[float, np.ndarray]] = []  # (IoU, pixel coordinates) after each step
    done, note = 0, None
    cur = px
    for lam in lams:
        pts, disp = correspondences(sil, t, max_march)
        if len(pts):
            pts, disp = _pool(pts, disp, CELL_PX)
            if len(pts) > MAX_CONTROL_POINTS:  # a long outline: coarser cells (LAPACK time grows fast above ~150)
                pts, disp = _pool(pts, disp, CELL_PX * len(pts) / MAX_CONTROL_POINTS)
        if len(pts) < 3:
            note = "stopped early: too few outline correspondences"
            break
        warp = ThinPlateWarp(pts, disp, float(lam), float(resolution))
        lo = np.minimum(cur.min(axis=0), pts.min(axis=0))
        hi = np.maximum(cur.max(axis=0), pts.max(axis=0))
        d = _injective_scale_at(warp, lo, hi) * warp(cur)
        if not np.all(np.isfinite(d)):
            note = "stopped early: a non-finite step"
            break
        trial = _damp_folds(cur, d, faces)
        if trial is None:
            note = "stopped early: a step would fold the surface"
            break
        cur = trial
        try:
            sil = render_silhouettes(cur[None], faces, resolution, closed=closed)[0]
        except ValueError:
            note = "stopped early: the mesh grew too large to rasterize"
            break
        done += 1
        iou = silhouette_iou(sil, t)
        states.append((iou, cur))
    # the best step that raised the IoU and added no self-intersection
    better = sorted((st for st in states if st[0] > iou0), key=lambda st: -st[0])[:MAX_INTERSECTION_CHECKS]
    if not better:
        why = f"refinement did not raise the silhouette IoU ({note})" if note else "refinement did not raise the silhouette IoU"
        return RefineResult(mesh, done, iou0, iou0, f"{why}; the mesh is unrefined", note, cam)
    allowed = None
    for iou, state in better:
        v = _unproject(state, depth, cam, resolution)
        if not np.all(np.isfinite(v)):
            continue
        refined = mesh.with_vertices(v.astype(np.float32))
        n = None
        if check_intersections:
            from engine.postprocess import self_intersections

            n = self_intersections(refined)
            if n:
                allowed = self_intersections(mesh) if allowed is None else allowed  # the prediction's own
                if n > allowed:
                    note = "stepped back: a later step made the surface cross itself"
                    continue
        return RefineResult(refined, done, iou0, iou, None, note, cam, n)
    return skip("every refined step made the surface cross itself or was not finite", iou0)


def refine_prediction(
    mesh: Mesh,
    sketch: np.ndarray,
    normals: np.ndarray | None,
    steps: int = DEFAULT_STEPS,
    **kwargs,
) -> RefineResult:
    """:func:`refine_mesh` towards the drawn outline (:func:`target_outline` of the sketch and generator normals).

    A drawing without a closed outline (:func:`target_outline` falls back to the generator's silhouette) has no drawn
    outline to refine to: the mesh stays as predicted, with a warning saying so. Refining it to the generator's
    silhouette instead, as before 2026-11-28, moved strongly augmented sketches' meshes away from the true shape in
    3D and in outline alike (``reproduce_models.sh refine-open``): the predictor has already read that silhouette,
    and the estimated camera misplaces it.
    """
    if steps == 0:
        return refine_mesh(mesh, np.zeros((16, 16), bool), 0)
    target, source = target_outline(sketch, normals)
    if source != "drawing":
        return RefineResult(mesh, 0, float("nan"), float("nan"), OPEN_OUTLINE_WARNING)
    return refine_mesh(mesh, target, steps, **kwargs)


OPEN_OUTLINE_WARNING = "refinement skipped: the drawing has no closed outline to refine to; the mesh is unrefined"
""":func:`refine_prediction`'s warning for a drawing without a closed outline (the app shows it in the status bar)."""
