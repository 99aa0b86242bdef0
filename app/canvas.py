"""The sketch canvas: vector strokes drawn with mouse, pen tablet or touch.

Coordinates are canvas pixels, x right, y down, origin top-left (as :mod:`engine.strokes`
and the image conventions of :mod:`engine.camera`). Everything drawn is kept as vector
data (:class:`engine.strokes.Stroke`); the eraser splits strokes where it passes, so
undo/redo (:mod:`app.history`) restores them exactly. An opened image becomes a background
layer (:class:`BackgroundLayer`) placed in canvas coordinates that the user can draw over.

What the model sees (:meth:`SketchCanvas.model_input`): the stroke list when there is no
background (the engine rasterises it with ``engine.preprocess.rasterize_strokes``), else the
composite of background ink and strokes rendered at canvas resolution (:meth:`render_raster`)
and normalised by ``engine.preprocess.preprocess_raster`` into the 256x256 framed input. The
app hands the worker thread a :class:`CanvasComposite` (an immutable description, from
:meth:`SketchCanvas.composite_request`) and renders it there, so a large scan never costs the
UI thread a composite.

Rendering cost on the UI thread scales with what changed: committed strokes are cached in a
pixmap; a new stroke is painted onto it, anything else (undo, erase, resize) repaints the
rectangle it changed, each stroke from a path built once while it lives (:class:`StrokeShape`);
the background layer is drawn from an image tinted and scaled once per layer and size; while
drawing, only the live stroke is painted on top. The worker's composite (:func:`render_ink`)
likewise paints only the strokes added since its last render.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass

import numpy as np
from PySide6.QtCore import QEvent, QLineF, QPointF, QRect, QRectF, QSize, Qt, Signal
from PySide6.QtGui import (
    QColor,
    QImage,
    QMouseEvent,
    QPainter,
    QPainterPath,
    QPaintEvent,
    QPen,
    QPixmap,
    QResizeEvent,
    QTabletEvent,
)
from PySide6.QtWidgets import QSizePolicy, QWidget

from app.history import History, SketchState
from engine.camera import FRAME_MARGIN
from engine.strokes import Stroke

TOOL_PEN = "pen"
TOOL_ERASER = "eraser"
TOOLS = (TOOL_PEN, TOOL_ERASER)

MAX_COMPOSITE_PIXELS = 4_000_000
"""Largest model-input composite (background image + strokes) rendered, in pixels."""

MIN_POINT_SPACING_PX = 0.75
"""Input points closer than this to the previous one are dropped (mouse jitter)."""

PAPER_COLOR = QColor(255, 255, 255)
INK_COLOR = QColor(20, 20, 20)
BACKGROUND_INK_COLOR = QColor(90, 110, 160)  # background layer shown tinted so it reads as a layer
GUIDE_COLOR = QColor(80, 140, 230, 70)
ERASER_COLOR = QColor(220, 80, 80, 120)

_ERASE_EPS = 1e-9


# --------------------------------------------------------------------------------------
# pure helpers (numpy, no widgets)
# --------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class BackgroundLayer:
    """An opened image, placed on the canvas.

    Attributes:
        ink: (H, W) float32 in [0, 1], 1 = ink, read-only (as engine.preprocess.load_sketch_image returns).
        rect: (x, y, w, h) canvas pixels where the image is drawn (w, h > 0).
    """

    ink: np.ndarray
    rect: tuple[float, float, float, float]

    def __post_init__(self) -> None:
        ink = np.array(self.ink, dtype=np.float32)
        if ink.ndim != 2 or ink.shape[0] < 1 or ink.shape[1] < 1:
            raise ValueError(f"background ink must be (H, W), got {ink.shape}")
        if not np.all(np.isfinite(ink)):
            raise ValueError("background ink contains NaN or inf")
        ink = np.clip(ink, 0.0, 1.0)
        ink.setflags(write=False)
        rect = tuple(float(r) for r in self.rect)
        if len(rect) != 4 or not all(np.isfinite(rect)) or rect[2] <= 0 or rect[3] <= 0:
            raise ValueError(f"background rect must be finite (x, y, w, h) with w, h > 0, got {self.rect}")
        object.__setattr__(self, "ink", ink)
        object.__setattr__(self, "rect", rect)


def fit_rect(content_w: float, content_h: float, box_w: float, box_h: float) -> tuple[float, float, float, float]:
    """Largest (x, y, w, h) of aspect ``content_w:content_h`` centred in a ``box_w x box_h`` box."""
    if min(content_w, content_h, box_w, box_h) <= 0:
        raise ValueError(f"fit_rect needs positive sizes, got content {content_w}x{content_h} box {box_w}x{box_h}")
    s = min(box_w / content_w, box_h / content_h)
    w, h = content_w * s, content_h * s
    return ((box_w - w) / 2.0, (box_h - h) / 2.0, w, h)


def guide_rect(width: float, height: float, margin: float = FRAME_MARGIN) -> tuple[float, float, float, float]:
    """The framing guide: the centred square of side ``min(w, h)`` shrunk by ``margin`` on each side.

    The engine frames a drawing to its bounding box with ``FRAME_MARGIN`` on each side
    (see engine.camera); drawing inside this square at about this size means the framing
    changes the drawing least.
    """
    side = min(width, height)
    inner = side * (1.0 - 2.0 * margin)
    return ((width - inner) / 2.0, (height - inner) / 2.0, inner, inner)


def point_segment_distances(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance from each point to a polyline.

    Args:
        points: (N, 2) float64.
        path: (M, 2) float64, M >= 1 (M == 1 is a single point).

    Returns:
        (N,) float64 distances to the closest point of the polyline.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    q = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    if len(q) == 0:
        raise ValueError("path must have at least one point, got (0, 2)")
    if len(q) == 1:
        return np.linalg.norm(p - q[0], axis=1)
    a, b = q[:-1], q[1:]  # (M-1, 2) segment ends
    ab = b - a
    denom = np.einsum("ij,ij->i", ab, ab)  # (M-1,)
    ap = p[:, None, :] - a[None, :, :]  # (N, M-1, 2)
    t = np.einsum("nmk,mk->nm", ap, ab) / np.maximum(denom, _ERASE_EPS)
    t = np.clip(t, 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(p[:, None, :] - closest, axis=2).min(axis=1)


def resample_polyline(points: np.ndarray, pressure: np.ndarray | None, spacing: float) -> tuple[np.ndarray, np.ndarray | None]:
    """Insert points so consecutive points are at most ``spacing`` apart (original points kept).

    Args:
        points: (N, 2).
        pressure: (N,) or None; interpolated linearly along with the points.
        spacing: maximum gap (> 0).

    Returns:
        (N', 2) points and (N',) pressure (or None), N' >= N, the same polyline.
    """
    out, out_pr, _original = _resample(points, pressure, spacing)
    return out, out_pr


def _resample(points: np.ndarray, pressure: np.ndarray | None, spacing: float) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """:func:`resample_polyline`, and an (N',) mask of the output points that are the input's own."""
    if not (np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing must be finite and > 0, got {spacing}")
    p = np.asarray(points, dtype=np.float64)
    if len(p) < 2:
        out_pr = None if pressure is None else np.asarray(pressure, dtype=np.float64).copy()
        return p.copy(), out_pr, np.ones(len(p), dtype=bool)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)  # (N-1,)
    n_sub = np.maximum(np.ceil(seg / spacing).astype(np.int64), 1)  # pieces per segment
    # parameter of every output point: segment index + fraction
    seg_idx = np.repeat(np.arange(len(seg)), n_sub)
    first = np.cumsum(n_sub) - n_sub  # index of each segment's first output point: the input's own
    frac = (np.arange(int(n_sub.sum())) - np.repeat(first, n_sub)) / np.repeat(n_sub, n_sub)
    out = p[seg_idx] + frac[:, None] * (p[seg_idx + 1] - p[seg_idx])
    out = np.vstack([out, p[-1:]])
    original = np.zeros(len(out), dtype=bool)
    original[first] = original[-1] = True
    if pressure is None:
        return out, None, original
    pr = np.asarray(pressure, dtype=np.float64)
    out_pr = pr[seg_idx] + frac * (pr[seg_idx + 1] - pr[seg_idx])
    return out, np.concatenate([out_pr, pr[-1:]]), original


def erase_strokes(
    strokes: tuple[Stroke, ...] | list[Stroke], eraser_path: np.ndarray, radius: float
) -> tuple[tuple[Stroke, ...], bool]:
    """Remove the parts of strokes within ``radius`` of an eraser path, splitting strokes.

    Only strokes whose padded bounding box meets the eraser's, and whose recorded points come
    within reach of it (allowing for their longest segment), are examined (the rest are
    returned as the same objects). A hit stroke is resampled to spacing ``radius / 2`` so
    that a long segment crossing the eraser is cut even if none of its recorded points lies
    under it; each surviving run of samples becomes a new stroke of the stroke's own points
    in it plus the run's two ends (same width, pressure alongside), so what is left is drawn
    as it was and a stroke does not gain points each time it is erased. Runs of a single
    sample are dropped unless the original stroke was a single dot.

    Args:
        strokes: the current strokes.
        eraser_path: (M, 2) canvas points the eraser passed, M >= 1.
        radius: eraser radius in canvas pixels (> 0).

    Returns:
        (new strokes, changed) -- ``changed`` is False when nothing was erased (the input
        objects are returned unchanged).
    """
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"eraser radius must be finite and > 0, got {radius}")
    path = np.asarray(eraser_path, dtype=np.float64).reshape(-1, 2)
    if len(path) == 0:
        return tuple(strokes), False
    lo, hi = path.min(axis=0) - radius, path.max(axis=0) + radius
    out: list[Stroke] = []
    changed = False
    for s in strokes:
        pad = s.width / 2.0
        smin, smax = s.points.min(axis=0) - pad, s.points.max(axis=0) + pad
        if np.any(smax < lo) or np.any(smin > hi):
            out.append(s)
            continue
        reach = radius + pad  # the eraser touches the stroke's visible ink, not only its centre line
        # Every point of a segment lies within half its length of one of its ends, so when no
        # recorded point comes within reach + the longest half-segment, no resampled one can.
        half = np.linalg.norm(np.diff(s.points, axis=0), axis=1).max() / 2.0 if len(s.points) > 1 else 0.0
        if point_segment_distances(s.points, path).min() > reach + half:
            out.append(s)
            continue
        pts, pr, original = _resample(s.points, s.pressure, max(radius / 2.0, 0.25))
        hit = point_segment_distances(pts, path) <= reach
        if not hit.any():
            out.append(s)
            continue
        changed = True
        keep = ~hit
        # runs of consecutive kept points
        edges = np.diff(np.concatenate([[0], keep.astype(np.int8), [0]]))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        for a, b in zip(starts, ends):
            if b - a < 2 and len(s.points) > 1:
                continue
            # a piece keeps the stroke's own points and the two ends of the run (where the eraser
            # cut or the stroke ends): it is drawn as the stroke was, not through the dense samples
            run = original[a:b].copy()
            run[0] = run[-1] = True
            out.append(Stroke(pts[a:b][run], None if pr is None else pr[a:b][run], s.width))
    if not changed:
        return tuple(strokes), False
    return tuple(out), True


def ink_to_qimage(ink: np.ndarray) -> QImage:
    """(H, W) float ink in [0, 1] (1 = ink) -> Grayscale8 QImage, dark ink on white paper."""
    a = np.asarray(ink, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"ink must be (H, W), got {a.shape}")
    gray = np.ascontiguousarray(np.round((1.0 - np.clip(np.nan_to_num(a), 0.0, 1.0)) * 255.0).astype(np.uint8))
    h, w = gray.shape
    return QImage(gray.data, w, h, w, QImage.Format.Format_Grayscale8).copy()


def qimage_to_ink(image: QImage) -> np.ndarray:
    """QImage (any format) -> (H, W) float32 ink in [0, 1], 1 = dark (luminance inverted)."""
    g = image.convertToFormat(QImage.Format.Format_Grayscale8)
    h, w, bpl = g.height(), g.width(), g.bytesPerLine()
    if h == 0 or w == 0:
        return np.zeros((h, w), dtype=np.float32)
    buf = np.frombuffer(g.constBits(), dtype=np.uint8, count=h * bpl).reshape(h, bpl)[:, :w]
    return (1.0 - buf.astype(np.float32) / 255.0).astype(np.float32)


def stroke_path(points: np.ndarray) -> QPainterPath:
    """A smooth QPainterPath through the points: quadratic curves between segment midpoints.

    Built from plain floats (one ``quadTo`` call a point, no QPointF each): what a repaint
    of many strokes spends its Python time on.
    """
    pts = np.asarray(points, dtype=np.float64)
    x0, y0 = pts[0].tolist()
    path = QPainterPath(QPointF(x0, y0))
    if len(pts) == 1:
        path.lineTo(x0 + 0.01, y0)  # a dot: round caps draw a disc
        return path
    if len(pts) == 2:
        path.lineTo(*pts[1].tolist())
        return path
    mids = (pts[1:] + pts[:-1]) / 2.0
    path.lineTo(*mids[0].tolist())
    quad_to = path.quadTo
    for cx, cy, ex, ey in np.hstack([pts[1:-1], mids[1:]]).tolist():  # control point, then end point
        quad_to(cx, cy, ex, ey)
    path.lineTo(*pts[-1].tolist())
    return path


@dataclass(frozen=True, eq=False)
class StrokeShape:
    """What painting one stroke needs, built once (:func:`stroke_shape`) and kept while the
    stroke lives (strokes are immutable), so a repaint of many strokes does no Python work a point.

    Attributes:
        width: the pen width of ``path``.
        path: the smooth path, drawn with one pen (no pressure, or pressure that hardly varies);
            None when the pressure varies.
        segments: (pen width, segment) a segment, when the pressure varies; empty otherwise.
    """

    width: float
    path: QPainterPath | None
    segments: tuple[tuple[float, QLineF], ...] = ()


def stroke_shape(stroke: Stroke) -> StrokeShape:
    """The stroke's :class:`StrokeShape`: one path at the (mean) pressure's width, or one line a
    segment at the mean pressure of its two ends when the pressure varies."""
    pr = stroke.pressure
    if pr is None or len(stroke.points) < 2 or float(np.ptp(pr)) < 1e-3:
        width = stroke.width if pr is None else max(stroke.width * float(pr.mean()), 0.5)
        return StrokeShape(width, stroke_path(stroke.points))
    pts = stroke.points
    widths = np.maximum(stroke.width * (pr[1:] + pr[:-1]) / 2.0, 0.5)
    rows = np.column_stack([pts[:-1], pts[1:], widths]).tolist()
    return StrokeShape(stroke.width, None, tuple((w, QLineF(x0, y0, x1, y1)) for x0, y0, x1, y1, w in rows))


def paint_stroke(painter: QPainter, stroke: Stroke, color: QColor, shape: StrokeShape | None = None) -> None:
    """Draw one stroke antialiased with round caps; pressure varies the width per segment.

    ``shape``: the stroke's :func:`stroke_shape` when the caller keeps it (built here otherwise).
    """
    shape = stroke_shape(stroke) if shape is None else shape
    pen = QPen(color, shape.width, Qt.PenStyle.SolidLine, Qt.PenCapStyle.RoundCap, Qt.PenJoinStyle.RoundJoin)
    if shape.path is not None:
        painter.setPen(pen)
        painter.setBrush(Qt.BrushStyle.NoBrush)
        painter.drawPath(shape.path)
        return
    for w, line in shape.segments:
        pen.setWidthF(w)
        painter.setPen(pen)
        painter.drawLine(line)


def background_image(layer: BackgroundLayer, color: QColor) -> QImage:
    """A layer's ink as an RGBA image of ``color`` with the ink as alpha (full resolution)."""
    ink = layer.ink
    h, w = ink.shape
    rgba = np.empty((h, w, 4), dtype=np.uint8)
    rgba[..., 0], rgba[..., 1], rgba[..., 2] = color.red(), color.green(), color.blue()
    rgba[..., 3] = np.round(ink * 255.0).astype(np.uint8)
    return QImage(rgba.data, w, h, 4 * w, QImage.Format.Format_RGBA8888).copy()


def _stroke_rect(stroke: Stroke) -> QRectF:
    """Canvas rectangle a stroke's ink can cover (its points padded by the pen width)."""
    lo, hi = stroke.points.min(axis=0), stroke.points.max(axis=0)
    pad = stroke.width / 2.0 + 2.0
    return QRectF(lo[0] - pad, lo[1] - pad, hi[0] - lo[0] + 2 * pad, hi[1] - lo[1] + 2 * pad)


def _strokes_rect(strokes: list[Stroke]) -> QRectF | None:
    """Union of :func:`_stroke_rect` over ``strokes`` (None for none), snapped outwards to pixels."""
    if not strokes:
        return None
    r = _stroke_rect(strokes[0])
    for st in strokes[1:]:
        r = r.united(_stroke_rect(st))
    return QRectF(r.toAlignedRect())


def paint_background(painter: QPainter, layer: BackgroundLayer, color: QColor) -> None:
    """Draw a background layer's ink (as ``color`` with ink as alpha) into its rect."""
    painter.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform, True)
    painter.drawImage(QRectF(*layer.rect), background_image(layer, color))


_SHOWN_BACKGROUNDS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_SHOWN_LOCK = threading.Lock()


def shown_background(layer: BackgroundLayer, color: QColor) -> QImage:
    """The layer tinted and scaled once to its rect's size (cached per layer): what the canvas
    draws on every rebuild of its pixmap, so a large scan is converted once, not per stroke."""
    w, h = max(1, round(layer.rect[2])), max(1, round(layer.rect[3]))
    key = (color.rgba(), w, h)
    with _SHOWN_LOCK:
        hit = _SHOWN_BACKGROUNDS.get(layer)
    if hit is not None and hit[0] == key:
        return hit[1]
    img = background_image(layer, color).scaled(w, h, Qt.AspectRatioMode.IgnoreAspectRatio, Qt.TransformationMode.SmoothTransformation)
    with _SHOWN_LOCK:
        _SHOWN_BACKGROUNDS[layer] = (key, img)
    return img


class _RenderCache:
    """What :func:`render_ink` painted last, so the next call paints only what changed.

    The worker renders the composite for every prediction, and PySide6 holds Python's GIL through
    each QPainter call, so the UI thread waits on the longest one; painting every stroke again grew
    with the drawing (README "The app under the pen": 10.5-12.7 ms p50 per render with this cache
    on two busy cores, the session report's ``composite_ms``). Kept here: the page with the background
    painted in (per layer and size), and the last render with and without its last stroke. A
    render whose strokes extend the last one's (a new stroke), or replace only its last stroke
    (the live stroke growing), starts from a copy of those; anything else (undo further back, an
    erase, which makes new strokes) starts from the cached page. Strokes are immutable, so
    identity tells them apart. The pixels are those of a render from scratch: the same calls on
    the same pixels, in the same order.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._page = None  # (key, background, QImage: white + background)
        self._last = None  # (key, background, strokes, QImage all strokes, QImage all but the last or None)

    def page(self, key: tuple, background: BackgroundLayer | None, scale: tuple[float, float]) -> QImage:
        with self._lock:
            hit = self._page
        if hit is not None and hit[0] == key and hit[1] is background:
            return hit[2]
        img = QImage(key[0], key[1], QImage.Format.Format_Grayscale8)
        img.fill(QColor(255, 255, 255))
        if background is not None:
            p = _ink_painter(img, scale)
            try:
                paint_background(p, background, QColor(0, 0, 0))
            finally:
                p.end()
        with self._lock:
            self._page = (key, background, img)
        return img

    def _shared(self, key: tuple, background: BackgroundLayer | None, strokes: tuple[Stroke, ...]) -> tuple:
        """(the last render's entry, how many leading strokes it shares with ``strokes``), or (None, 0)."""
        with self._lock:
            last = self._last
        if last is None or last[0] != key or last[1] is not background:
            return None, 0
        k = 0
        for a, b in zip(last[2], strokes):
            if a is not b:
                break
            k += 1
        return last, k

    def start(self, key: tuple, background: BackgroundLayer | None, strokes: tuple[Stroke, ...]) -> tuple[QImage | None, int]:
        """(a cached image to start from, how many of ``strokes`` it holds) or (None, 0)."""
        last, k = self._shared(key, background, strokes)
        if last is not None and k == len(last[2]):
            return last[3], k
        if last is not None and k == len(last[2]) - 1 and last[4] is not None:
            return last[4], k
        return None, 0

    def holds(self, key: tuple, background: BackgroundLayer | None, strokes: tuple[Stroke, ...]) -> bool:
        """Whether the last render is of exactly these strokes (its entry is worth keeping)."""
        last, k = self._shared(key, background, strokes)
        return last is not None and k == len(last[2]) == len(strokes)

    def store(self, key: tuple, background: BackgroundLayer | None, strokes: tuple[Stroke, ...], full: QImage,
              but_last: QImage | None) -> None:
        with self._lock:
            self._last = (key, background, strokes, full, but_last)


_RENDERS = _RenderCache()


def _ink_painter(img: QImage, scale: tuple[float, float]) -> QPainter:
    p = QPainter(img)
    p.setRenderHint(QPainter.RenderHint.Antialiasing, True)
    p.scale(*scale)
    return p


def _paint_strokes(img: QImage, strokes: tuple[Stroke, ...], scale: tuple[float, float]) -> None:
    if not strokes:
        return
    p = _ink_painter(img, scale)
    try:
        for s in strokes:
            paint_stroke(p, s, QColor(0, 0, 0))
    finally:
        p.end()


def render_ink(
    strokes: tuple[Stroke, ...] | list[Stroke],
    background: BackgroundLayer | None,
    canvas_size: tuple[int, int],
    size: tuple[int, int],
) -> np.ndarray:
    """Background ink + strokes in black on white, the canvas scaled into ``size``.

    Pure (a QImage, no widget): runs on any thread. Paints only what changed since the last call
    (:class:`_RenderCache`), with the same result as painting everything.

    Args:
        strokes: canvas-pixel strokes, drawn in order.
        background: the background layer or None.
        canvas_size: (width, height) of the canvas the coordinates refer to.
        size: (width, height) of the output; stroke widths scale with it.

    Returns:
        (H, W) float32 in [0, 1], 1 = ink.
    """
    w, h = int(size[0]), int(size[1])
    if w < 1 or h < 1:
        raise ValueError(f"raster size must be positive, got {w}x{h}")
    strokes = tuple(strokes)
    cw, ch = max(int(canvas_size[0]), 1), max(int(canvas_size[1]), 1)
    key, scale = (w, h, cw, ch), (w / cw, h / ch)
    base, done = _RENDERS.start(key, background, strokes)
    if base is None:
        base, done = _RENDERS.page(key, background, scale), 0
    if len(strokes) > done:  # cached images are never painted on: paint a copy
        img = base.copy()
        _paint_strokes(img, strokes[done:-1], scale)
        but_last = img.copy()
        _paint_strokes(img, strokes[-1:], scale)
        _RENDERS.store(key, background, strokes, img, but_last)
    else:
        img = base
        if not _RENDERS.holds(key, background, strokes):
            _RENDERS.store(key, background, strokes, img, None)
    return qimage_to_ink(img)


@dataclass(frozen=True, eq=False)
class CanvasComposite:
    """What the model sees when the canvas has a background layer and strokes, not yet rendered.

    Immutable (strokes and layer are read-only values), so it crosses to the worker thread,
    which calls :meth:`render` (:func:`render_ink`) and frames the result.

    Attributes:
        strokes: the strokes, in drawing order (the live one last, if included).
        background: the background layer.
        canvas_size: (width, height) of the canvas.
        size: (width, height) to render at (:meth:`SketchCanvas.composite_size`).
    """

    strokes: tuple[Stroke, ...]
    background: BackgroundLayer
    canvas_size: tuple[int, int]
    size: tuple[int, int]

    def render(self) -> np.ndarray:
        """(H, W) float32 ink in [0, 1] at ``size``."""
        return render_ink(self.strokes, self.background, self.canvas_size, self.size)


# --------------------------------------------------------------------------------------
# the widget
# --------------------------------------------------------------------------------------


class SketchCanvas(QWidget):
    """Freehand vector sketching widget with pen/eraser tools, background layer and history.

    Signals:
        sketchChanged(): a committed change (stroke finished, erase finished, undo, redo,
            clear, background opened/removed, state loaded). Inference and autosave listen.
        strokeProgress(): the live stroke grew (for optional live inference while drawing).
        historyChanged(): undo/redo availability may have changed.
    """

    sketchChanged = Signal()
    strokeProgress = Signal()
    historyChanged = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setAttribute(Qt.WidgetAttribute.WA_AcceptTouchEvents, True)
        self.setAttribute(Qt.WidgetAttribute.WA_StaticContents, True)
        self.setMouseTracking(False)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setMinimumSize(160, 160)
        self.setCursor(Qt.CursorShape.CrossCursor)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)  # keeps Ctrl+Z away from text fields
        self.history = History()
        self._tool = TOOL_PEN
        self._brush_width = 3.0
        self._eraser_width = 12.0
        self._show_guide = True
        self._live_points: list[tuple[float, float]] = []
        self._live_pressure: list[float] | None = None
        self._eraser_trail: list[tuple[float, float]] = []
        self._erase_working: tuple[Stroke, ...] | None = None
        self._active_device: str | None = None  # "mouse", "tablet", "touch" while a gesture runs
        self._cache: QPixmap | None = None
        self._cache_key: tuple | None = None
        self._cache_strokes: tuple[Stroke, ...] | None = None
        self._shapes: weakref.WeakKeyDictionary[Stroke, StrokeShape] = weakref.WeakKeyDictionary()  # UI thread only

    # ---- state -------------------------------------------------------------------------
    def sizeHint(self) -> QSize:  # noqa: N802 (Qt API)
        return QSize(512, 512)

    @property
    def state(self) -> SketchState:
        """The committed sketch state (what undo/redo moves between)."""
        return self.history.current

    def strokes(self) -> tuple[Stroke, ...]:
        """Committed strokes, oldest first (includes the working result of an eraser drag)."""
        return self._erase_working if self._erase_working is not None else self.state.strokes

    @property
    def background(self) -> BackgroundLayer | None:
        bg = self.state.background
        return bg if isinstance(bg, BackgroundLayer) else None

    @property
    def is_empty(self) -> bool:
        return self.state.is_empty and not self._live_points

    @property
    def is_drawing(self) -> bool:
        return self._active_device is not None

    def _commit(self, state: SketchState) -> bool:
        changed = self.history.push(state)
        if changed:
            self._invalidate()
            self.sketchChanged.emit()
            self.historyChanged.emit()
        return changed

    def load_state(self, state: SketchState, *, reset_history: bool = False) -> None:
        """Show ``state``; as a new undo step, or as the only state when ``reset_history``."""
        self._cancel_gesture()
        if reset_history:
            self.history.reset(state)
            self._invalidate()
            self.sketchChanged.emit()
            self.historyChanged.emit()
        else:
            self._commit(state)

    def new_sketch(self) -> None:
        """Empty canvas with a fresh history."""
        self.load_state(SketchState(), reset_history=True)

    def clear(self) -> None:
        """Remove all strokes and the background (one undo step)."""
        self._cancel_gesture()
        self._commit(SketchState((), None, "Clear"))

    def clear_strokes(self) -> None:
        """Remove the strokes but keep the background layer (one undo step)."""
        self._cancel_gesture()
        self._commit(SketchState((), self.state.background, "Clear strokes"))

    def undo(self) -> None:
        self._cancel_gesture()
        before = self.history.current
        if self.history.undo() is not before:
            self._invalidate()
            self.sketchChanged.emit()
            self.historyChanged.emit()

    def redo(self) -> None:
        self._cancel_gesture()
        before = self.history.current
        if self.history.redo() is not before:
            self._invalidate()
            self.sketchChanged.emit()
            self.historyChanged.emit()

    def add_stroke(self, stroke: Stroke) -> None:
        """Append a stroke programmatically (one undo step)."""
        self._commit(SketchState(self.state.strokes + (stroke,), self.state.background, "Stroke"))

    def set_background_ink(self, ink: np.ndarray) -> None:
        """Place an image's (H, W) ink (1 = ink) as the background layer, fitted to the canvas (one undo step)."""
        a = np.asarray(ink)
        if a.ndim != 2 or a.shape[0] < 1 or a.shape[1] < 1:
            raise ValueError(f"background ink must be (H, W), got {a.shape}")
        rect = fit_rect(a.shape[1], a.shape[0], max(self.width(), 1), max(self.height(), 1))
        self._cancel_gesture()
        self._commit(SketchState(self.state.strokes, BackgroundLayer(a, rect), "Open image"))

    def clear_background(self) -> None:
        """Remove the background layer (one undo step)."""
        self._cancel_gesture()
        self._commit(SketchState(self.state.strokes, None, "Remove background"))

    # ---- tools -------------------------------------------------------------------------
    @property
    def tool(self) -> str:
        return self._tool

    def set_tool(self, tool: str) -> None:
        if tool not in TOOLS:
            raise ValueError(f"tool must be one of {TOOLS}, got {tool!r}")
        self._cancel_gesture()
        self._tool = tool
        self.update()

    @property
    def brush_width(self) -> float:
        return self._brush_width

    def set_brush_width(self, width: float) -> None:
        w = float(width)
        if not (np.isfinite(w) and w > 0):
            raise ValueError(f"brush width must be finite and > 0, got {width}")
        self._brush_width = w

    @property
    def eraser_width(self) -> float:
        return self._eraser_width

    def set_eraser_width(self, width: float) -> None:
        w = float(width)
        if not (np.isfinite(w) and w > 0):
            raise ValueError(f"eraser width must be finite and > 0, got {width}")
        self._eraser_width = w

    @property
    def show_guide(self) -> bool:
        return self._show_guide

    def set_show_guide(self, on: bool) -> None:
        self._show_guide = bool(on)
        self.update()

    # ---- model input ---------------------------------------------------------------------
    def render_raster(self, size: tuple[int, int] | None = None, *, include_live: bool = False) -> np.ndarray:
        """Render background ink + strokes in black on white, scaled to ``size``.

        Args:
            size: (width, height) in pixels; defaults to the widget size. The whole canvas is
                scaled into it (stroke widths scale too).
            include_live: also draw the stroke being drawn.

        Returns:
            (H, W) float32 in [0, 1], 1 = ink.
        """
        w, h = size if size is not None else (self.width(), self.height())
        strokes = list(self.strokes())
        live = self._live_stroke() if include_live else None
        if live is not None:
            strokes.append(live)
        return render_ink(strokes, self.background, (self.width(), self.height()), (int(w), int(h)))

    def composite_size(self) -> tuple[int, int]:
        """(width, height) of the model-input composite: the canvas, enlarged so an opened image
        keeps its own resolution (a thin line in a large scan must not vanish when the image is
        shown small), capped at :data:`MAX_COMPOSITE_PIXELS`."""
        w, h = max(self.width(), 1), max(self.height(), 1)
        bg = self.background
        s = 1.0
        if bg is not None:
            s = max(1.0, bg.ink.shape[1] / bg.rect[2], bg.ink.shape[0] / bg.rect[3])
            s = min(s, max(1.0, float(np.sqrt(MAX_COMPOSITE_PIXELS / (w * h)))))
        return max(1, int(w * s)), max(1, int(h * s))  # floor: stays within the cap

    def model_input(self, *, include_live: bool = False, preprocess: bool = True) -> list[Stroke] | np.ndarray | None:
        """What the engine should see, or None for an empty sketch.

        Pure strokes go as a list of Stroke (the engine rasterises them with
        ``engine.preprocess.rasterize_strokes``). With a background layer and no strokes, the
        image's own ink is used as loaded (exactly what ``sketchmesh infer IMAGE`` sees); with
        both, the composite (:meth:`render_raster` at :meth:`composite_size`, (H, W) float32,
        1 = ink). Either is passed through ``engine.preprocess.preprocess_raster`` into the
        (256, 256) float32 framed raster; with ``preprocess=False`` the unframed ink is returned
        (the app frames it on the worker thread, see app.worker.CanvasRaster).
        """
        strokes = list(self.strokes())
        live = self._live_stroke() if include_live else None
        if live is not None:
            strokes.append(live)
        bg = self.background
        if bg is None:
            return strokes or None
        composite = bg.ink if not strokes else self.render_raster(self.composite_size(), include_live=include_live)
        if not preprocess:
            return composite
        from engine.preprocess import preprocess_raster  # noqa: PLC0415 (engine module loaded lazily)

        return preprocess_raster(composite)

    def composite_request(self, *, include_live: bool = False) -> list[Stroke] | np.ndarray | CanvasComposite | None:
        """Like ``model_input(preprocess=False)``, but a composite of background and strokes is
        returned undrawn, as a :class:`CanvasComposite` for the worker thread to render. The
        UI thread only collects references: no pixels are touched."""
        strokes = list(self.strokes())
        live = self._live_stroke() if include_live else None
        if live is not None:
            strokes.append(live)
        bg = self.background
        if bg is None:
            return strokes or None
        if not strokes:
            return bg.ink
        return CanvasComposite(tuple(strokes), bg, (max(self.width(), 1), max(self.height(), 1)), self.composite_size())

    # ---- gestures ------------------------------------------------------------------------
    def _live_stroke(self) -> Stroke | None:
        if not self._live_points:
            return None
        return Stroke(np.array(self._live_points), None if self._live_pressure is None else np.array(self._live_pressure), self._brush_width)

    def _begin(self, device: str, x: float, y: float, pressure: float | None) -> None:
        self._active_device = device
        if self._tool == TOOL_PEN:
            self._live_points = [(x, y)]
            self._live_pressure = None if pressure is None else [pressure]
        else:
            self._eraser_trail = [(x, y)]
            self._erase_working = self.state.strokes
            self._erase_step()
        self.update()

    def _extend(self, x: float, y: float, pressure: float | None) -> None:
        if self._tool == TOOL_PEN:
            lx, ly = self._live_points[-1]
            if (x - lx) ** 2 + (y - ly) ** 2 < MIN_POINT_SPACING_PX**2:
                return
            self._live_points.append((x, y))
            if self._live_pressure is not None:
                self._live_pressure.append(1.0 if pressure is None else pressure)
            self.update(self._live_tail_rect())  # only the new piece: the rest is on screen already
            self.strokeProgress.emit()
        else:
            self._eraser_trail.append((x, y))
            self._erase_step()

    def _live_tail_rect(self) -> QRect:
        """Widget rectangle the last piece of the live stroke can change (the smoothed path
        between the last three points, padded by the pen width)."""
        pts = np.asarray(self._live_points[-3:], dtype=np.float64)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = self._brush_width / 2.0 + 3.0
        return QRectF(lo[0] - pad, lo[1] - pad, hi[0] - lo[0] + 2 * pad, hi[1] - lo[1] + 2 * pad).toAlignedRect()

    def _eraser_cursor_rect(self, x: float, y: float) -> QRect:
        r = self._eraser_width / 2.0 + 3.0
        return QRectF(x - r, y - r, 2 * r, 2 * r).toAlignedRect()

    def _erase_step(self) -> None:
        """Cut the strokes under the eraser's last move; repaint only what changed and the cursor."""
        trail = self._eraser_trail[-2:]
        before = self._erase_working or ()
        working, changed = erase_strokes(before, np.array(trail), self._eraser_width / 2.0)
        dirty = QRect()
        for x, y in trail:
            dirty = dirty.united(self._eraser_cursor_rect(x, y))
        if changed:
            self._erase_working = working
            now, old = {id(st) for st in working}, {id(st) for st in before}
            cut = _strokes_rect([st for st in before if id(st) not in now] + [st for st in working if id(st) not in old])
            if cut is not None:
                dirty = dirty.united(cut.toAlignedRect())
        self.update(dirty)

    def _end(self) -> None:
        device, self._active_device = self._active_device, None
        if device is None:
            return
        if self._tool == TOOL_PEN:
            stroke = self._live_stroke()
            self._live_points, self._live_pressure = [], None
            if stroke is not None:
                self._commit(SketchState(self.state.strokes + (stroke,), self.state.background, "Stroke"))
        else:
            working, self._erase_working, self._eraser_trail = self._erase_working, None, []
            if working is not None:
                self._commit(SketchState(working, self.state.background, "Erase"))
        self.update()

    def _cancel_gesture(self) -> None:
        if self._active_device is None and not self._live_points and self._erase_working is None:
            return
        self._active_device = None
        self._live_points, self._live_pressure = [], None
        self._eraser_trail, self._erase_working = [], None
        self._invalidate()

    def mousePressEvent(self, event: QMouseEvent) -> None:  # noqa: N802 (Qt API)
        if event.button() != Qt.MouseButton.LeftButton or self._active_device is not None:
            event.ignore()
            return
        pos = event.position()
        self._begin("mouse", pos.x(), pos.y(), None)
        event.accept()

    def mouseMoveEvent(self, event: QMouseEvent) -> None:  # noqa: N802 (Qt API)
        if self._active_device != "mouse":
            event.ignore()
            return
        pos = event.position()
        self._extend(pos.x(), pos.y(), None)
        event.accept()

    def mouseReleaseEvent(self, event: QMouseEvent) -> None:  # noqa: N802 (Qt API)
        if self._active_device != "mouse" or event.button() != Qt.MouseButton.LeftButton:
            event.ignore()
            return
        pos = event.position()
        self._extend(pos.x(), pos.y(), None)
        self._end()
        event.accept()

    def tabletEvent(self, event: QTabletEvent) -> None:  # noqa: N802 (Qt API)
        pos, pressure = event.position(), float(np.clip(event.pressure(), 0.0, 1.0))
        t = event.type()
        if t == QEvent.Type.TabletPress and self._active_device is None:
            self._begin("tablet", pos.x(), pos.y(), pressure)
        elif t == QEvent.Type.TabletMove and self._active_device == "tablet":
            self._extend(pos.x(), pos.y(), pressure)
        elif t == QEvent.Type.TabletRelease and self._active_device == "tablet":
            self._end()
        event.accept()  # no synthesized mouse events for tablet input

    def event(self, event: QEvent) -> bool:
        t = event.type()
        if t in (QEvent.Type.TouchBegin, QEvent.Type.TouchUpdate, QEvent.Type.TouchEnd, QEvent.Type.TouchCancel):
            pts = event.points()
            if t == QEvent.Type.TouchCancel:
                self._cancel_gesture()
                self.update()
            elif pts:
                pos = pts[0].position()
                if t == QEvent.Type.TouchBegin and self._active_device is None:
                    self._begin("touch", pos.x(), pos.y(), None)
                elif t == QEvent.Type.TouchUpdate and self._active_device == "touch":
                    self._extend(pos.x(), pos.y(), None)
                elif t == QEvent.Type.TouchEnd and self._active_device == "touch":
                    self._extend(pos.x(), pos.y(), None)
                    self._end()
            event.accept()
            return True
        return super().event(event)

    # ---- painting ------------------------------------------------------------------------
    def _invalidate(self) -> None:
        """Repaint; :meth:`_committed_pixmap` decides what of its cache is still valid."""
        self.update()

    def _committed_pixmap(self) -> QPixmap:
        """The paper, guide, background and committed strokes, cached and updated incrementally.

        Strokes only appended since the cache was made (a pen-up) are painted onto it; strokes
        removed or replaced (an eraser pass, undo, redo) repaint only the rectangle they cover,
        unless that is most of the canvas; a new size, background or guide rebuilds it.
        """
        strokes = self.strokes()
        key = (self.width(), self.height(), self.background, self._show_guide)  # a layer compares by identity
        done = self._cache_strokes
        if self._cache is None or self._cache_key != key or done is None:
            self._cache = QPixmap(max(self.width(), 1), max(self.height(), 1))
            self._paint_committed(self._cache, strokes, None)
            self._cache_key, self._cache_strokes = key, strokes
            return self._cache
        if done is strokes:
            return self._cache
        if len(strokes) >= len(done) and all(a is b for a, b in zip(done, strokes)):
            p = QPainter(self._cache)  # appended: paint the new strokes on top
            try:
                p.setRenderHint(QPainter.RenderHint.Antialiasing, True)
                for st in strokes[len(done) :]:
                    paint_stroke(p, st, INK_COLOR, self._shape(st))
            finally:
                p.end()
        else:
            now = {id(st) for st in strokes}
            before = {id(st) for st in done}
            changed = [st for st in done if id(st) not in now] + [st for st in strokes if id(st) not in before]
            dirty = _strokes_rect(changed)
            if dirty is None or dirty.width() * dirty.height() > 0.5 * self.width() * self.height():
                dirty = None  # most of the canvas: a full repaint costs no more
            self._paint_committed(self._cache, strokes, dirty)
        self._cache_strokes = strokes
        return self._cache

    def _paint_committed(self, pm: QPixmap, strokes: tuple[Stroke, ...], clip: QRectF | None) -> None:
        """Paint paper, guide, background and ``strokes`` into ``pm`` (only inside ``clip``)."""
        p = QPainter(pm)
        try:
            if clip is not None:
                p.setClipRect(clip)
            p.fillRect(QRectF(pm.rect()) if clip is None else clip, PAPER_COLOR)
            p.setRenderHint(QPainter.RenderHint.Antialiasing, True)
            if self._show_guide:
                x, y, w, h = guide_rect(self.width(), self.height())
                p.setPen(QPen(GUIDE_COLOR, 1.0, Qt.PenStyle.DashLine))
                p.setBrush(Qt.BrushStyle.NoBrush)
                p.drawRect(QRectF(x, y, w, h))
            bg = self.background
            if bg is not None:
                x, y, _, _ = bg.rect
                p.drawImage(QPointF(round(x), round(y)), shown_background(bg, BACKGROUND_INK_COLOR))
            for st in strokes:
                if clip is None or _stroke_rect(st).intersects(clip):
                    paint_stroke(p, st, INK_COLOR, self._shape(st))
        finally:
            p.end()

    def _shape(self, stroke: Stroke) -> StrokeShape:
        """The committed stroke's :class:`StrokeShape`, built on its first paint and dropped with it."""
        shape = self._shapes.get(stroke)
        if shape is None:
            shape = self._shapes[stroke] = stroke_shape(stroke)
        return shape

    def paintEvent(self, event: QPaintEvent) -> None:  # noqa: N802 (Qt API)
        p = QPainter(self)
        try:
            p.drawPixmap(0, 0, self._committed_pixmap())
            p.setRenderHint(QPainter.RenderHint.Antialiasing, True)
            live = self._live_stroke()
            if live is not None:
                paint_stroke(p, live, INK_COLOR)
            if self._eraser_trail:
                x, y = self._eraser_trail[-1]
                r = self._eraser_width / 2.0
                p.setPen(QPen(ERASER_COLOR, 1.0))
                p.drawEllipse(QPointF(x, y), r, r)
        finally:
            p.end()

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802 (Qt API)
        self._cache_key = None
        super().resizeEvent(event)
