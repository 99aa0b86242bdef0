"""Sketch input: image files and canvas strokes -> the generator's framed 256x256 raster.

Every path into the generator goes through here, so the app (vector strokes) and the CLI
(image files) produce the same kind of raster (conventions in :mod:`engine.camera`):

* (256, 256) float32 in [0, 1], **1 = ink**, row 0 at the top;
* *framed*: the drawing's centre-line bounding box is centred and its longer side spans
  ``1 - 2 * FRAME_MARGIN`` of the image (the 2D counterpart of
  :func:`engine.camera.frame_camera`, which frames the projected vertices -- the contours
  that the data generator draws lie on them);
* *normalised stroke style*: every stroke is thinned to its centre line and redrawn,
  anti-aliased, at :data:`engine.contract.SKETCH_STROKE_WIDTH_PX` with
  :func:`draw_segments`. The data generator can draw its line drawings with the same
  function so the generator sees one style.

Image decoding refuses absurd sizes *before* decoding (the header is parsed here for PNG,
JPEG, BMP, WebP and TIFF), and every failure is an :class:`engine.errors.SketchInputError`
naming the file.
"""

from __future__ import annotations

import contextlib
import os
import struct
import tempfile
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path

import cv2
import numpy as np

from engine.camera import FRAME_MARGIN
from engine.contract import SKETCH_INK_THRESHOLD, SKETCH_SIZE, SKETCH_STROKE_WIDTH_PX
from engine.errors import EmptySketchError, SketchInputError
from engine.strokes import Stroke

MAX_IMAGE_PIXELS = 40_000_000
"""Largest image (width * height) decoded; a 8000 x 5000 scan is fine, a 50000 x 50000 header is refused."""

MAX_IMAGE_SIDE = 30_000
"""Largest width or height accepted."""

MAX_FILE_BYTES = 512 * 1024 * 1024
"""Largest sketch file read into memory."""

MIN_IMAGE_SIDE = 8
"""Smallest width or height of a sketch image; smaller images cannot hold a drawing."""

MAX_INK_FRACTION = 0.6
"""Largest fraction of ink pixels a line drawing may have; more means inverted polarity or a fill."""

MIN_CONTRAST = 0.1
"""Smallest luminance difference between paper and the strongest stroke for an image to count as drawn on."""

TRANSPARENT_ALPHA = 0.5
"""Alpha below which a border pixel counts as transparent (then alpha itself is the ink)."""

PIECE_LENGTH_PX = 2.0
""":func:`draw_segments` cuts segments into pieces this long; each is evaluated on a small pixel window."""

SUPPORTED_IMAGE_FORMATS = ("PNG", "JPEG", "BMP", "TIFF", "WebP")

_FRAMED_EXTENT_PX = (1.0 - 2.0 * FRAME_MARGIN) * SKETCH_SIZE  # 204.8 px at 256
_STDERR_LOCK = threading.Lock()


# ---------------------------------------------------------------------------------------------
# header sniffing


def _png_size(data: bytes) -> tuple[int, int] | None:
    if data[:8] != b"\x89PNG\r\n\x1a\n" or len(data) < 24 or data[12:16] != b"IHDR":
        return None
    w, h = struct.unpack(">II", data[16:24])
    return w, h


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    if data[:2] != b"\xff\xd8":
        return None
    i, n = 2, len(data)
    while i + 4 <= n:
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:  # markers without a length
            i += 2
            continue
        (length,) = struct.unpack(">H", data[i + 2 : i + 4])
        if length < 2:
            return None
        if marker in (0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF):
            if i + 9 > n:
                return None
            h, w = struct.unpack(">HH", data[i + 5 : i + 9])
            return w, h
        i += 2 + length
    return None


def _bmp_size(data: bytes) -> tuple[int, int] | None:
    if data[:2] != b"BM" or len(data) < 26:
        return None
    (header_size,) = struct.unpack("<I", data[14:18])
    if header_size == 12:  # OS/2 BITMAPCOREHEADER
        w, h = struct.unpack("<HH", data[18:22])
        return w, h
    w, h = struct.unpack("<ii", data[18:26])
    return abs(w), abs(h)


def _webp_size(data: bytes) -> tuple[int, int] | None:
    if data[:4] != b"RIFF" or data[8:12] != b"WEBP" or len(data) < 30:
        return None
    chunk = data[12:16]
    if chunk == b"VP8 ":
        w, h = struct.unpack("<HH", data[26:30])
        return w & 0x3FFF, h & 0x3FFF
    if chunk == b"VP8L":
        b = data[21:25]
        w = 1 + (((b[1] & 0x3F) << 8) | b[0])
        h = 1 + (((b[3] & 0x0F) << 10) | (b[2] << 2) | ((b[1] & 0xC0) >> 6))
        return w, h
    if chunk == b"VP8X":
        w = 1 + int.from_bytes(data[24:27], "little")
        h = 1 + int.from_bytes(data[27:30], "little")
        return w, h
    return None


def _tiff_size(data: bytes) -> tuple[int, int] | None:
    if data[:4] == b"II*\x00":
        end = "<"
    elif data[:4] == b"MM\x00*":
        end = ">"
    else:
        return None
    try:
        (offset,) = struct.unpack(end + "I", data[4:8])
        (count,) = struct.unpack(end + "H", data[offset : offset + 2])
        w = h = None
        for k in range(min(count, 4096)):  # IFD entries, first image only
            e = offset + 2 + 12 * k
            tag, typ = struct.unpack(end + "HH", data[e : e + 4])
            if typ == 3:
                (val,) = struct.unpack(end + "H", data[e + 8 : e + 10])
            else:
                (val,) = struct.unpack(end + "I", data[e + 8 : e + 12])
            if tag == 256:
                w = val
            elif tag == 257:
                h = val
        return (w, h) if w is not None and h is not None else None
    except struct.error:
        return None


_SNIFFERS = {"PNG": _png_size, "JPEG": _jpeg_size, "BMP": _bmp_size, "WebP": _webp_size, "TIFF": _tiff_size}


def image_header_size(data: bytes) -> tuple[str, int, int] | None:
    """Sniff an image's format and (width, height) from its header bytes, without decoding.

    Returns:
        (format name, width, height), or None when the bytes are none of
        :data:`SUPPORTED_IMAGE_FORMATS` or the header is unreadable.
    """
    for name, sniff in _SNIFFERS.items():
        try:
            size = sniff(data)
        except (struct.error, IndexError):
            size = None
        if size is not None:
            return name, int(size[0]), int(size[1])
    return None


def _looks_truncated(fmt: str, data: bytes) -> bool:
    if fmt == "PNG":
        return b"IEND" not in data[-32:]
    if fmt == "JPEG":
        return b"\xff\xd9" not in data[-64:]
    return False


@contextlib.contextmanager
def _captured_stderr() -> Iterator[list[str]]:
    """Capture what native decoders (libpng, libjpeg) print on file descriptor 2.

    Yields a list that holds the captured text after the block. The redirection covers the whole
    process for the few milliseconds of a decode; a lock serialises captures, so concurrent
    decodes (app worker + main thread) cannot restore each other's descriptors in the wrong order.
    """
    out: list[str] = []
    with _STDERR_LOCK:
        try:
            saved = os.dup(2)
        except OSError:  # no usable stderr: nothing to capture
            yield out
            return
        with tempfile.TemporaryFile() as tmp:
            os.dup2(tmp.fileno(), 2)
            try:
                yield out
            finally:
                os.dup2(saved, 2)
                os.close(saved)
                tmp.seek(0)
                out.append(tmp.read().decode("utf-8", "replace").strip())


def decode_image_bytes(data: bytes, name: str = "<bytes>") -> np.ndarray:
    """Decode image bytes with OpenCV after checking the header's size.

    Args:
        data: the file's bytes.
        name: the file name used in error messages.

    Returns:
        The decoded array as OpenCV gives it with IMREAD_UNCHANGED: (H, W) or (H, W, C) with
        C in {2, 3, 4} (BGR order), dtype uint8, uint16 or float32.

    Raises:
        SketchInputError: not a supported image, absurd or tiny dimensions, truncated or corrupt.
    """
    header = image_header_size(data)
    if header is None:
        raise SketchInputError(
            f"{name}: not a supported image (expected {', '.join(SUPPORTED_IMAGE_FORMATS)})"
        )
    fmt, w, h = header
    if w > MAX_IMAGE_SIDE or h > MAX_IMAGE_SIDE or w * h > MAX_IMAGE_PIXELS:
        raise SketchInputError(
            f"{name}: image is {w}x{h} pixels, larger than the limit of {MAX_IMAGE_PIXELS // 1_000_000} megapixels "
            f"({MAX_IMAGE_SIDE} px per side); scale it down"
        )
    if w < MIN_IMAGE_SIDE or h < MIN_IMAGE_SIDE:
        raise SketchInputError(f"{name}: image is {w}x{h} pixels, too small for a sketch (at least {MIN_IMAGE_SIDE}x{MIN_IMAGE_SIDE})")
    if _looks_truncated(fmt, data):
        raise SketchInputError(f"{name}: {fmt} file is truncated (no end marker)")
    try:
        with _captured_stderr() as messages:  # holds _STDERR_LOCK: the log level below is global too
            old_level = cv2.utils.logging.getLogLevel()
            cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
            try:
                # JPEG has no alpha: decode so that its EXIF orientation is applied (phone photos of
                # paper sketches); IMREAD_UNCHANGED would keep alpha but ignores the orientation.
                flags = cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH if fmt == "JPEG" else cv2.IMREAD_UNCHANGED
                img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), flags)
            finally:
                cv2.utils.logging.setLogLevel(old_level)
    except cv2.error as exc:
        raise SketchInputError(f"{name}: cannot decode {fmt} image ({str(exc).strip().splitlines()[-1]})") from None
    if img is None:
        detail = " ".join(" ".join(messages).split())
        raise SketchInputError(f"{name}: corrupt or truncated {fmt} image" + (f" ({detail[:200]})" if detail else ""))
    return img


def _to_unit_float(img: np.ndarray) -> np.ndarray:
    if img.dtype == np.uint8:
        return img.astype(np.float32) / 255.0
    if img.dtype == np.uint16:
        return img.astype(np.float32) / 65535.0
    if img.dtype in (np.float32, np.float64):
        out = np.nan_to_num(img.astype(np.float32), nan=0.0, posinf=1.0, neginf=0.0)
        return np.clip(out, 0.0, 1.0)
    raise SketchInputError(f"unsupported pixel type {img.dtype}")


def _border(a: np.ndarray) -> np.ndarray:
    """Pixels of the 1-pixel frame of a (H, W) array, as a flat array."""
    return np.concatenate([a[0], a[-1], a[1:-1, 0], a[1:-1, -1]])


def ink_from_pixels(img: np.ndarray) -> np.ndarray:
    """Turn decoded pixels into ink coverage (1 = ink), whatever the polarity and alpha.

    Rules (in order):

    1. Alpha (4 or 2 channels): if the image's border is mostly transparent, the paper is the
       transparent part and the ink is the alpha channel weighted by the strokes' contrast
       against the paper. Otherwise the image is composited over white.
    2. Luminance (Rec. 601 weights on BGR). The paper is the median of the border pixels:
       light paper -> ink = (paper - lum) / (paper - darkest), dark paper -> ink = (lum - paper)
       / (lightest - paper), clipped to [0, 1]. An image with less than :data:`MIN_CONTRAST`
       between paper and its strongest stroke has no ink (all zeros).

    Args:
        img: (H, W) grey, (H, W, 2) grey+alpha, (H, W, 3) BGR or (H, W, 4) BGRA; uint8, uint16 or float.

    Returns:
        (H, W) float32 ink coverage in [0, 1].
    """
    a = _to_unit_float(np.asarray(img))
    if a.ndim == 2:
        grey, alpha = a, None
    elif a.ndim == 3 and a.shape[2] in (1, 2, 3, 4):
        c = a.shape[2]
        colour = a[..., : 1 if c <= 2 else 3]
        alpha = a[..., -1] if c in (2, 4) else None
        grey = colour[..., 0] if colour.shape[2] == 1 else colour @ np.array([0.114, 0.587, 0.299], np.float32)
    else:
        raise SketchInputError(f"image must be (H, W) or (H, W, C) with C in 1..4, got {a.shape}")
    if alpha is not None and np.median(_border(alpha)) < TRANSPARENT_ALPHA:
        # ink lives in alpha; strokes that have the same colour as nothing are still strokes
        return np.clip(alpha, 0.0, 1.0).astype(np.float32)
    if alpha is not None:
        grey = grey * alpha + (1.0 - alpha)  # composite over white paper
    paper = float(np.median(_border(grey)))
    if paper >= 0.5:
        strongest = float(grey.min())
        contrast = paper - strongest
        ink = (paper - grey) / max(contrast, 1e-6)
    else:
        strongest = float(grey.max())
        contrast = strongest - paper
        ink = (grey - paper) / max(contrast, 1e-6)
    if contrast < MIN_CONTRAST:
        return np.zeros(grey.shape, np.float32)
    return np.clip(ink, 0.0, 1.0).astype(np.float32)


def load_sketch_image(path: str | os.PathLike) -> np.ndarray:
    """Read a sketch image file into ink coverage.

    PNG, JPEG, BMP, TIFF and WebP; grey, RGB or RGBA; 8 or 16 bit (float TIFF too); dark strokes
    on light paper or light on dark (detected from the border); a transparent background counts
    as paper. Non-ASCII paths work (the bytes are decoded in memory).

    Args:
        path: the image file.

    Returns:
        (H, W) float32 ink coverage in [0, 1], 1 = ink (not yet framed: see :func:`preprocess_raster`).

    Raises:
        SketchInputError: missing/unreadable file, not an image, truncated, absurd or tiny size.
    """
    p = Path(path)
    try:
        size = p.stat().st_size
        if not p.is_file():
            raise SketchInputError(f"{p}: not a file")
        if size > MAX_FILE_BYTES:
            raise SketchInputError(f"{p}: file is {size / 2**20:.0f} MiB, larger than the {MAX_FILE_BYTES // 2**20} MiB limit")
        data = p.read_bytes()
    except FileNotFoundError:
        raise SketchInputError(f"{p}: no such file") from None
    except OSError as exc:
        raise SketchInputError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if not data:
        raise SketchInputError(f"{p}: file is empty")
    img = decode_image_bytes(data, str(p))
    try:
        return ink_from_pixels(img)
    except SketchInputError as exc:
        raise SketchInputError(f"{p}: {exc}") from None


# ---------------------------------------------------------------------------------------------
# drawing


def draw_segments(segments: np.ndarray, size: int = SKETCH_SIZE, width: float = SKETCH_STROKE_WIDTH_PX) -> np.ndarray:
    """Anti-aliased rendering of line segments with round caps, at an exact width.

    Each pixel's coverage is ``clip(width / 2 + 0.5 - d, 0, 1)`` where d is the exact distance
    from the pixel centre to the nearest segment, so a straight stroke integrates to ``width``
    ink per unit length. Segments are cut into pieces of at most :data:`PIECE_LENGTH_PX` and
    each piece is evaluated only on the small window of pixels it can reach, so the work scales
    with the drawn length, not the image area.

    Args:
        segments: (S, 2, 2) float endpoints in continuous pixel coordinates (x = column, y = row,
            pixel (i, j)'s centre at (j + 0.5, i + 0.5), see :mod:`engine.camera`). A segment
            whose endpoints coincide draws a dot.
        size: output side in pixels.
        width: stroke width in pixels (> 0).

    Returns:
        (size, size) float32 coverage in [0, 1].
    """
    seg = np.asarray(segments, dtype=np.float64)
    if seg.ndim != 3 or seg.shape[1:] != (2, 2):
        raise ValueError(f"segments must be (S, 2, 2), got {seg.shape}")
    if not (np.isfinite(width) and width > 0):
        raise ValueError(f"width must be finite and > 0, got {width}")
    if not np.all(np.isfinite(seg)):
        raise SketchInputError("stroke coordinates contain NaN or inf")
    radius = width / 2.0 + 0.5
    # drop segments that cannot touch the image
    lo, hi = seg.min(axis=1), seg.max(axis=1)
    seg = seg[np.all((hi > -radius) & (lo < size + radius), axis=1)]
    if len(seg) == 0:
        return np.zeros((size, size), np.float32)
    # cut into pieces of length <= PIECE_LENGTH_PX
    d = seg[:, 1] - seg[:, 0]
    n = np.maximum(np.ceil(np.linalg.norm(d, axis=1) / PIECE_LENGTH_PX).astype(np.int64), 1)
    sid = np.repeat(np.arange(len(seg)), n)
    k = np.arange(len(sid)) - np.repeat(np.cumsum(n) - n, n)
    p0 = seg[sid, 0] + (k / n[sid])[:, None] * d[sid]
    p1 = seg[sid, 0] + ((k + 1) / n[sid])[:, None] * d[sid]
    # each piece's pixel window: a fixed K x K block from the floor of its padded box; pieces whose window misses the
    # image are dropped, and the rest are written into the image padded by K on every side, so no pixel needs a test
    K = int(np.ceil(PIECE_LENGTH_PX + 2 * radius)) + 1
    corner = np.floor(np.minimum(p0, p1) - radius).astype(np.int64)  # (P, 2) (col, row)
    inside = np.all((corner + K > 0) & (corner < size), axis=1)
    p0, p1, corner = p0[inside], p1[inside], corner[inside]
    o = np.arange(K)
    col = corner[:, 0:1, None] + o[None, None, :]  # (P, 1, K)
    row = corner[:, 1:2, None] + o[None, :, None]  # (P, K, 1)
    dv = p1 - p0
    dx, dy = dv[:, 0, None, None], dv[:, 1, None, None]
    len2 = dx * dx + dy * dy
    ax, ay = (col + 0.5) - p0[:, 0, None, None], (row + 0.5) - p0[:, 1, None, None]  # pixel centre - p0
    t = ax * dx + ay * dy  # (P, K, K), then in place: the nearest point's parameter, the distance, the coverage
    t /= np.where(len2 > 0, len2, 1.0)
    np.clip(t, 0.0, 1.0, out=t)
    ex, ey = ax - t * dx, ay - t * dy
    ex *= ex
    ey *= ey
    ex += ey
    cov = np.sqrt(ex, out=ex)
    np.subtract(radius, cov, out=cov)
    np.clip(cov, 0.0, 1.0, out=cov)
    side = size + 2 * K
    keep = cov > 0
    out = np.zeros(side * side, np.float32)
    np.maximum.at(out, ((row + K) * side + (col + K))[keep], cov[keep].astype(np.float32))
    return out.reshape(side, side)[K : K + size, K : K + size].copy()


def _frame_transform(lo: np.ndarray, hi: np.ndarray, size: int = SKETCH_SIZE) -> tuple[float, np.ndarray]:
    """Scale and offset mapping a bounding box [lo, hi] (x, y) onto the framed square.

    Returns (s, offset) with ``p_out = s * p + offset``. A zero-size box (one dot) is centred at scale 1.
    """
    extent = float(np.max(hi - lo))
    s = _FRAMED_EXTENT_PX * size / SKETCH_SIZE / extent if extent > 1e-9 else 1.0
    centre = (lo + hi) / 2.0
    return s, size / 2.0 - s * centre


def _checked_strokes(strokes: Sequence[Stroke] | None) -> tuple[list[Stroke], tuple[float, float, float]]:
    """The strokes as a list, checked, and the frame they are drawn in: ``(scale, x offset, y offset)``
    (:func:`_frame_transform` of every point's bounding box)."""
    strokes = list(strokes) if strokes is not None else []
    if not strokes:
        raise EmptySketchError("the sketch has no strokes")
    for k, s in enumerate(strokes):
        if not isinstance(s, Stroke):
            raise SketchInputError(f"stroke {k} must be an engine.strokes.Stroke, got {type(s).__name__}")
    all_pts = np.concatenate([s.points for s in strokes])
    if not np.all(np.isfinite(all_pts)):
        raise SketchInputError("stroke points contain NaN or inf")
    scale, offset = _frame_transform(all_pts.min(axis=0), all_pts.max(axis=0))
    return strokes, (float(scale), float(offset[0]), float(offset[1]))


def _stroke_segments(strokes: Sequence[Stroke], frame: tuple[float, float, float]) -> np.ndarray:
    """(S, 2, 2) segments of the strokes' polylines in the frame ``(scale, x offset, y offset)``; a
    single-point stroke is a zero-length segment (a dot)."""
    scale, offset = frame[0], np.array(frame[1:])
    segs = []
    for s in strokes:  # one vectorised block per stroke (strokes, not points)
        p = s.points * scale + offset
        segs.append(np.stack([p[:-1], p[1:]], axis=1) if len(p) > 1 else np.stack([p, p], axis=1))
    return np.concatenate(segs) if segs else np.zeros((0, 2, 2))


def rasterize_strokes(strokes: Sequence[Stroke]) -> np.ndarray:
    """Rasterise canvas strokes into the generator's framed, style-normalised input.

    The strokes' points (canvas pixels, x right, y down) are framed on their bounding box (centre
    lines, like :func:`preprocess_raster` frames the thinned drawing) and each stroke is drawn as
    a polyline at :data:`SKETCH_STROKE_WIDTH_PX`; pen width and pressure are ignored (the style
    is normalised). A single-point stroke is a dot. :class:`StrokeRasterizer` gives the same
    raster drawing only what changed since its last call.

    Args:
        strokes: non-empty sequence of :class:`engine.strokes.Stroke`.

    Returns:
        (256, 256) float32 in [0, 1], 1 = ink.

    Raises:
        EmptySketchError: no strokes.
        SketchInputError: something that is not a Stroke, or non-finite coordinates.
    """
    strokes, frame = _checked_strokes(strokes)
    return draw_segments(_stroke_segments(strokes, frame))


class StrokeRasterizer:
    """:func:`rasterize_strokes` that draws only the strokes added since its last call.

    A drawing grows one stroke at a time (the canvas sends its committed strokes, the same
    :class:`engine.strokes.Stroke` objects every time, and the stroke under the pen, a new object
    every update), so the raster of all strokes but the last is kept with the frame it was drawn
    in. When the next call's strokes start with the kept ones (the same objects, in order) and the
    frame is unchanged (no new point outside the bounding box), only the strokes after them are
    drawn, and combined by the per-pixel maximum that :func:`draw_segments` itself combines pieces
    with: the result is bit-identical to :func:`rasterize_strokes`. Anything else (a stroke past
    the drawing's edge, undo, the eraser) draws everything again. A call with exactly the last
    call's strokes returns its raster again. Safe to call from several threads.

    Attributes:
        last_drawn_segments: segments drawn by the last call (0 when it repeated the one before).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._base: tuple[Stroke, ...] = ()  # strokes whose raster is kept
        self._base_frame: tuple[float, float, float] | None = None
        self._base_raster: np.ndarray | None = None
        self._last: tuple[tuple[Stroke, ...], np.ndarray] | None = None  # the last call's strokes and raster
        self.last_drawn_segments = 0

    @staticmethod
    def _starts_with(strokes: Sequence[Stroke], kept: tuple[Stroke, ...]) -> bool:
        return len(kept) <= len(strokes) and all(a is b for a, b in zip(kept, strokes))

    def __call__(self, strokes: Sequence[Stroke]) -> np.ndarray:
        """The framed raster of ``strokes``, as :func:`rasterize_strokes` (same arguments, result and errors)."""
        strokes, frame = _checked_strokes(strokes)
        with self._lock:
            last = self._last
            if last is not None and len(last[0]) == len(strokes) and self._starts_with(strokes, last[0]):
                self.last_drawn_segments = 0
                return last[1].copy()
            base, base_frame, base_raster = self._base, self._base_frame, self._base_raster
        drawn = 0
        head = strokes[:-1]
        if base_raster is not None and base_frame == frame and self._starts_with(head, base):
            new = head[len(base):]
            raster = base_raster
        else:
            new, raster = head, np.zeros((SKETCH_SIZE, SKETCH_SIZE), np.float32)
        if new:
            segs = _stroke_segments(new, frame)
            raster = np.maximum(raster, draw_segments(segs))
            drawn += len(segs)
        raster.setflags(write=False)
        segs = _stroke_segments(strokes[-1:], frame)
        out = np.maximum(raster, draw_segments(segs))
        drawn += len(segs)
        with self._lock:
            self._base, self._base_frame, self._base_raster = tuple(head), frame, raster
            self._last = (tuple(strokes), out.copy())
            self.last_drawn_segments = drawn
        return out


def _skeleton_segments(skel: np.ndarray) -> np.ndarray:
    """8-connected skeleton pixels -> (S, 2, 2) segments between neighbours (x, y centres).

    Isolated pixels become zero-length segments (dots).
    """
    sk = skel.astype(bool)
    H, W = sk.shape
    padded = np.pad(sk, 1)
    segs = []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        nb_on = sk & padded[1 + dr : H + 1 + dr, 1 + dc : W + 1 + dc]
        if dr and dc:  # a diagonal step that an orthogonal two-step path already covers adds only a corner blob
            nb_on &= ~(padded[1:H + 1, 1 + dc : W + 1 + dc] | padded[2 : H + 2, 1 : W + 1])
        r, c = np.nonzero(nb_on)
        p0 = np.stack([c + 0.5, r + 0.5], axis=1).astype(np.float64)
        segs.append(np.stack([p0, p0 + np.array([dc, dr], np.float64)], axis=1))
    # isolated pixels: no neighbour in 8-connectivity
    nb = cv2.filter2D(sk.astype(np.uint8), -1, np.ones((3, 3), np.float32), borderType=cv2.BORDER_CONSTANT)
    r, c = np.nonzero(sk & (nb == 1))
    p0 = np.stack([c + 0.5, r + 0.5], axis=1).astype(np.float64)
    segs.append(np.stack([p0, p0], axis=1))
    return np.concatenate(segs).astype(np.float64)


def preprocess_raster(ink: np.ndarray) -> np.ndarray:
    """Frame and style-normalise an ink raster of any size into the generator's input.

    Steps: binarise at :data:`SKETCH_INK_THRESHOLD`; crop to the ink's bounding box; resample
    the crop so its longer side spans about ``1 - 2 * FRAME_MARGIN`` of 256 (downscaling keeps
    any pixel that holds ink, so thin lines survive); thin to a one-pixel centre line
    (``cv2.ximgproc.thinning``), restoring the length thinning removes at line ends; reframe
    on the centre lines' box (the ink box shrunk by the median stroke half-width, see
    :func:`_centre_line_box`), as :func:`rasterize_strokes` frames the stroke points; redraw at
    :data:`SKETCH_STROKE_WIDTH_PX` with :func:`draw_segments`.

    Args:
        ink: (H, W) float ink coverage in [0, 1], 1 = ink (e.g. from :func:`load_sketch_image`).

    Returns:
        (256, 256) float32 in [0, 1], 1 = ink.

    Raises:
        EmptySketchError: no pixel above the ink threshold.
        SketchInputError: wrong shape, non-finite values, an image smaller than MIN_IMAGE_SIDE, or
            more than MAX_INK_FRACTION ink (not a line drawing).
    """
    a = np.asarray(ink)
    if a.ndim != 2:
        raise SketchInputError(f"sketch raster must be (H, W), got shape {a.shape}")
    if min(a.shape) < MIN_IMAGE_SIDE:
        raise SketchInputError(f"sketch raster is {a.shape[1]}x{a.shape[0]} pixels, too small (at least {MIN_IMAGE_SIDE} per side)")
    if not np.issubdtype(a.dtype, np.number):
        raise SketchInputError(f"sketch raster must be numeric, got {a.dtype}")
    if not np.all(np.isfinite(a)):
        raise SketchInputError("sketch raster contains NaN or inf")
    binary = a > SKETCH_INK_THRESHOLD
    fraction = float(binary.mean())
    if fraction > MAX_INK_FRACTION:
        raise SketchInputError(
            f"{fraction:.0%} of the image is ink: not a line drawing (inverted colours, or a filled or photographed background?)"
        )
    rows = np.nonzero(binary.any(axis=1))[0]
    cols = np.nonzero(binary.any(axis=0))[0]
    if len(rows) == 0:
        raise EmptySketchError("the sketch is blank: no ink found (draw darker strokes, or check the image)")
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    crop = binary[r0:r1, c0:c1].astype(np.float32)
    h, w = crop.shape
    s0 = _FRAMED_EXTENT_PX / max(h, w)
    nw, nh = max(1, int(round(w * s0))), max(1, int(round(h * s0)))
    if s0 < 1.0:
        small = cv2.resize(crop, (nw, nh), interpolation=cv2.INTER_AREA)
        work = small > 0.0  # any ink in the footprint (area averages of zeros are exactly 0): thin lines survive
    else:
        big = cv2.resize(crop, (nw, nh), interpolation=cv2.INTER_LINEAR)
        work = big > 0.5
        if not work.any():
            work = cv2.resize(crop, (nw, nh), interpolation=cv2.INTER_NEAREST) > 0.5
    pad = 2
    canvas = np.zeros((nh + 2 * pad, nw + 2 * pad), np.uint8)
    canvas[pad : pad + nh, pad : pad + nw] = work.astype(np.uint8) * 255
    binary_work = canvas > 0
    skel = cv2.ximgproc.thinning(canvas, thinningType=cv2.ximgproc.THINNING_ZHANGSUEN) > 0
    skel = _keep_vanished_blobs(binary_work, skel)
    dist = cv2.distanceTransform(canvas, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    segs = np.concatenate([_skeleton_segments(skel), _end_extensions(skel, dist)])
    lo, hi = _centre_line_box(binary_work, skel, dist)
    scale, offset = _frame_transform(lo, hi)
    return draw_segments(segs * scale + offset)


END_SEARCH_RADIUS_PX = 4.0
"""Skeleton pixels within this distance of a line end give the end's direction."""
END_DT_TOLERANCE_PX = 0.5
"""A line end is extended while the distance transform stays within this of its value at the end."""


def _keep_vanished_blobs(binary: np.ndarray, skel: np.ndarray) -> np.ndarray:
    """Thinning can erase a small filled blob (a dot) entirely: put its centroid pixel back."""
    n, labels, _, centroids = cv2.connectedComponentsWithStats(binary.astype(np.uint8), connectivity=8)
    has = np.bincount(labels[skel], minlength=n) > 0
    lost = np.flatnonzero(~has)
    lost = lost[lost > 0]  # label 0 is the background
    if len(lost) == 0:
        return skel
    skel = skel.copy()
    c = np.clip(np.rint(centroids[lost]).astype(np.int64), 0, np.array(skel.shape[::-1]) - 1)
    skel[c[:, 1], c[:, 0]] = True
    return skel


def _end_extensions(skel: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Segments that restore the length thinning removes at line ends.

    Zhang-Suen thinning retracts each free end of a line by up to its half-width. From each end
    pixel (one 8-neighbour) we march outwards, along the direction from the nearby skeleton
    pixels to the end, while the distance transform keeps its value at the end (inside the
    stroke's body, before its round cap starts to narrow).

    Returns:
        (K, 2, 2) segments (x, y continuous pixel coordinates), one per line end.
    """
    nb = cv2.filter2D(skel.astype(np.uint8), -1, np.ones((3, 3), np.float32), borderType=cv2.BORDER_CONSTANT)
    er, ec = np.nonzero(skel & (nb == 2))
    if len(er) == 0:
        return np.zeros((0, 2, 2))
    # direction: from the mean of the skeleton pixels within END_SEARCH_RADIUS_PX to the end
    R = int(np.ceil(END_SEARCH_RADIUS_PX))
    oy, ox = np.mgrid[-R : R + 1, -R : R + 1]
    within = (ox * ox + oy * oy <= END_SEARCH_RADIUS_PX**2).ravel()
    ox, oy = ox.ravel()[within], oy.ravel()[within]
    rr, cc = er[:, None] + oy[None, :], ec[:, None] + ox[None, :]  # (K, W)
    inside_img = (rr >= 0) & (rr < skel.shape[0]) & (cc >= 0) & (cc < skel.shape[1])
    on = inside_img & skel[np.clip(rr, 0, skel.shape[0] - 1), np.clip(cc, 0, skel.shape[1] - 1)]
    count = np.maximum(on.sum(axis=1), 1)
    mean = np.stack([(on * cc).sum(axis=1) / count, (on * rr).sum(axis=1) / count], axis=1)
    ends = np.stack([ec, er], axis=1).astype(np.float64)
    direction = ends - mean
    norm = np.linalg.norm(direction, axis=1, keepdims=True)
    direction = np.where(norm > 1e-9, direction / np.maximum(norm, 1e-9), 0.0)
    d_end = dist[er, ec]
    steps = np.arange(1, int(np.ceil(2 * d_end.max())) + 2) * 0.5  # (T,) march in half pixels
    q = ends[:, None, :] + steps[None, :, None] * direction[:, None, :]  # (K, T, 2)
    qi = np.clip(np.rint(q).astype(np.int64), 0, np.array(skel.shape[::-1]) - 1)
    inside = dist[qi[..., 1], qi[..., 0]] >= d_end[:, None] - END_DT_TOLERANCE_PX
    run = np.cumprod(inside, axis=1).sum(axis=1)  # steps before the first failure
    length = np.where(run > 0, steps[np.maximum(run - 1, 0)], 0.0)
    start = ends + 0.5
    return np.stack([start, start + length[:, None] * direction], axis=1)


def _centre_line_box(binary: np.ndarray, skel: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box (x, y) of a drawing's centre lines, from its ink box shrunk by the stroke radius.

    Thinning retracts line ends and apexes by up to a stroke width, so the skeleton's own box
    under-estimates the drawing; the ink box minus the median stroke half-width (the distance
    transform sampled on the skeleton) matches the box of the points the strokes were drawn
    through (round caps and joins), which is how :func:`rasterize_strokes` frames.
    """
    rows, cols = np.nonzero(binary)
    ink_lo = np.array([cols.min(), rows.min()], np.float64)  # continuous coords of the ink's outer edges
    ink_hi = np.array([cols.max() + 1, rows.max() + 1], np.float64)
    radius = max(float(np.median(dist[skel])) - 0.5, 0.0)
    lo, hi = ink_lo + radius, ink_hi - radius
    if np.any(hi < lo):  # a blob or dot: centre on its skeleton
        r, c = np.nonzero(skel)
        centre = np.array([c.mean() + 0.5, r.mean() + 0.5])
        lo = hi = centre
    return lo, hi


def sketch_raster_from_image(path: str | os.PathLike) -> np.ndarray:
    """:func:`load_sketch_image` then :func:`preprocess_raster`, with errors naming the file.

    Returns:
        (256, 256) float32 in [0, 1], 1 = ink.
    """
    ink = load_sketch_image(path)
    try:
        return preprocess_raster(ink)
    except EmptySketchError as exc:
        raise EmptySketchError(f"{path}: {exc}") from None
    except SketchInputError as exc:
        raise SketchInputError(f"{path}: {exc}") from None
