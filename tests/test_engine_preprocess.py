"""Sketch input: decoding every format / bit depth / polarity / alpha case, framing, stroke style."""

from __future__ import annotations

import struct
import zlib

import cv2
import numpy as np
import pytest

from engine.camera import FRAME_MARGIN
from engine.contract import SKETCH_SIZE, SKETCH_STROKE_WIDTH_PX
from engine.errors import EmptySketchError, SketchInputError
from engine.preprocess import (
    MIN_IMAGE_SIDE,
    StrokeRasterizer,
    draw_segments,
    image_header_size,
    load_sketch_image,
    preprocess_raster,
    rasterize_strokes,
    sketch_raster_from_image,
)
from engine.strokes import Stroke

LOSSLESS_ATOL = 1e-6
"""Float rounding only: lossless formats must give back the drawn coverage exactly."""
LOSSY_MIN_IOU = 0.9
"""JPEG / WebP (lossy) must keep the binarised strokes (intersection over union)."""
FRAMED = (1.0 - 2.0 * FRAME_MARGIN) * SKETCH_SIZE  # 204.8 px: centre-line extent of a framed drawing
FRAME_TOL_PX = 1.5
"""Framing tolerance: resampling + thinning place the centre line within about a pixel."""


def _truth(h: int = 60, w: int = 90) -> np.ndarray:
    """(h, w) uint8 coverage, 255 = ink: an anti-aliased cross and a circle, non-square on purpose."""
    ink = np.zeros((h, w), np.uint8)
    cv2.line(ink, (5, 5), (w - 6, h - 8), 255, 3, cv2.LINE_AA)
    cv2.circle(ink, (w // 2, h // 2), min(h, w) // 4, 255, 2, cv2.LINE_AA)
    return ink


def _iou(a: np.ndarray, b: np.ndarray, thr: float = 0.5) -> float:
    a, b = a > thr, b > thr
    return float((a & b).sum() / max((a | b).sum(), 1))


def _encode_case(case: str, ink8: np.ndarray, bits: int) -> np.ndarray:
    """Pixels for one colour/polarity case, at 8 or 16 bits."""
    i = ink8.astype(np.float64) / 255.0
    full = 255 if bits == 8 else 65535
    dtype = np.uint8 if bits == 8 else np.uint16
    if case == "grey-dark-on-light":
        px = (1.0 - i) * full
    elif case == "grey-light-on-dark":
        px = i * full
    elif case == "rgb-blue-on-white":  # coloured strokes: BGR (0.8, 0.2, 0.0) over white, linear mix
        stroke = np.array([0.8, 0.2, 0.0])
        px = ((1.0 - i)[..., None] * 1.0 + i[..., None] * stroke) * full
    elif case == "rgba-transparent":  # black strokes whose alpha is the coverage, transparent paper
        px = np.zeros(i.shape + (4,))
        px[..., 3] = i * full
    elif case == "rgba-opaque-white":
        px = np.concatenate([np.repeat(((1.0 - i) * full)[..., None], 3, axis=2), np.full(i.shape + (1,), full)], axis=2)
    else:
        raise ValueError(case)
    return np.rint(px).astype(dtype)


CASES = ["grey-dark-on-light", "grey-light-on-dark", "rgb-blue-on-white", "rgba-transparent", "rgba-opaque-white"]
FORMATS = {  # suffix -> (lossless, bit depths cv2 writes, alpha support)
    ".png": (True, (8, 16), True),
    ".bmp": (True, (8,), False),
    ".tiff": (True, (8, 16), True),
    ".jpg": (False, (8,), False),
    ".webp": (False, (8,), True),
}


def _params():
    for suffix, (lossless, depths, alpha) in FORMATS.items():
        for bits in depths:
            for case in CASES:
                if case.startswith("rgba") and not alpha:
                    continue
                yield pytest.param(suffix, bits, case, lossless, id=f"{suffix[1:]}-{bits}-{case}")


@pytest.mark.parametrize("suffix, bits, case, lossless", list(_params()))
def test_load_every_format_depth_polarity_and_alpha(tmp_path, suffix, bits, case, lossless):
    truth = _truth()
    px = _encode_case(case, truth, bits)
    path = tmp_path / f"sketch{suffix}"
    params = [cv2.IMWRITE_WEBP_QUALITY, 101] if suffix == ".webp" and case.startswith("rgba") else []
    assert cv2.imwrite(str(path), px, params)
    if suffix == ".webp" and case.startswith("rgba"):
        lossless = True  # quality > 100 is WebP's lossless mode
    got = load_sketch_image(path)
    assert got.shape == truth.shape and got.dtype == np.float32
    expected = truth.astype(np.float32) / 255.0
    if lossless:
        err = np.abs(got - expected)
        assert err.max() <= LOSSLESS_ATOL + (1.0 / full_scale(bits)), f"max error {err.max()} at {np.unravel_index(err.argmax(), err.shape)}"
    else:
        assert _iou(got, expected) >= LOSSY_MIN_IOU


def full_scale(bits: int) -> float:
    return 255.0 if bits == 8 else 65535.0


def test_non_ascii_path_and_grey_alpha(tmp_path):
    truth = _truth()
    path = tmp_path / "скетч 草图.png"
    cv2.imwrite(str(path), 255 - truth)
    np.testing.assert_allclose(load_sketch_image(path), truth / 255.0, atol=LOSSLESS_ATOL)


@pytest.mark.parametrize("suffix", [".png", ".jpg", ".bmp", ".tiff", ".webp"])
def test_header_sniffing_matches_decoded_size(tmp_path, suffix):
    img = np.full((37, 81, 3), 200, np.uint8)
    ok, buf = cv2.imencode(suffix, img)
    assert ok
    fmt, w, h = image_header_size(buf.tobytes())
    assert (w, h) == (81, 37), fmt


def _png_header_only(width: int, height: int) -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))  # noqa: E731
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b"")


def _bmp_header_only(width: int, height: int) -> bytes:
    info = struct.pack("<IiiHHIIiiII", 40, width, height, 1, 8, 0, 0, 0, 0, 0, 0)
    return b"BM" + struct.pack("<IHHI", 14 + len(info), 0, 0, 14 + len(info)) + info


@pytest.mark.parametrize("data, needle", [
    (_png_header_only(50000, 50000), "larger than the limit"),
    (_bmp_header_only(60000, -60000), "larger than the limit"),
    (_png_header_only(1, 1), "too small"),
    (b"hello, I am a text file\n" * 10, "not a supported image"),
    (b"", "empty"),
])
def test_bad_files_give_one_clear_error_naming_the_file(tmp_path, data, needle):
    path = tmp_path / "bad.png"
    path.write_bytes(data)
    with pytest.raises(SketchInputError, match=needle) as info:
        load_sketch_image(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("suffix", [".png", ".jpg", ".webp"])
def test_truncated_files_are_refused(tmp_path, suffix, capfd):
    ok, buf = cv2.imencode(suffix, 255 - _truth(120, 160))
    data = buf.tobytes()
    path = tmp_path / f"cut{suffix}"
    path.write_bytes(data[: len(data) * 2 // 3])
    with pytest.raises(SketchInputError, match="truncated|corrupt"):
        load_sketch_image(path)
    assert capfd.readouterr().err == ""  # native decoder chatter is captured, not printed


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(SketchInputError, match="no such file"):
        load_sketch_image(tmp_path / "nope.png")
    with pytest.raises(SketchInputError, match="not a file"):
        load_sketch_image(tmp_path)


def test_one_pixel_raster_and_blank_images(tmp_path):
    with pytest.raises(SketchInputError, match="too small"):
        preprocess_raster(np.ones((1, 1), np.float32))
    for value in (255, 0, 128):  # white, black and grey paper: no contrast, no ink
        path = tmp_path / f"blank{value}.png"
        cv2.imwrite(str(path), np.full((64, 64), value, np.uint8))
        assert load_sketch_image(path).max() == 0.0
        with pytest.raises(EmptySketchError, match="blank"):
            sketch_raster_from_image(path)


def test_preprocess_rejects_bad_rasters():
    with pytest.raises(SketchInputError, match="NaN"):
        preprocess_raster(np.full((32, 32), np.nan))
    with pytest.raises(SketchInputError, match=r"\(H, W\)"):
        preprocess_raster(np.zeros((32, 32, 3)))
    with pytest.raises(EmptySketchError):
        preprocess_raster(np.zeros((32, 32)))
    assert MIN_IMAGE_SIDE > 1


def _ink_bbox(r: np.ndarray) -> tuple[float, float, float, float]:
    """(row centre, col centre, height, width) of pixels above half coverage, in continuous pixel units."""
    rows, cols = np.nonzero(r > 0.5)
    return (rows.min() + rows.max() + 1) / 2, (cols.min() + cols.max() + 1) / 2, rows.max() + 1 - rows.min(), cols.max() + 1 - cols.min()


@pytest.mark.parametrize("shape, box, thickness", [
    ((300, 500), (40, 60, 240, 420), 3),  # wide drawing, off-centre (rows 40..240, cols 60..420)
    ((900, 400), (100, 150, 700, 300), 9),  # tall, thick strokes
    ((64, 48), (10, 12, 50, 30), 1),  # small image: upscaled
])
def test_framing_centres_and_scales_the_centre_line(shape, box, thickness):
    r0, c0, r1, c1 = box
    ink = np.zeros(shape, np.uint8)
    cv2.rectangle(ink, (c0, r0), (c1, r1), 255, thickness)
    out = preprocess_raster(ink / 255.0)
    assert out.shape == (SKETCH_SIZE, SKETCH_SIZE) and out.dtype == np.float32
    cr, cc, h, w = _ink_bbox(out)
    # centre line spans FRAMED on the longer side; the redrawn stroke adds its width
    long_, short_ = max(r1 - r0, c1 - c0), min(r1 - r0, c1 - c0)
    expected_long = FRAMED + SKETCH_STROKE_WIDTH_PX
    expected_short = FRAMED * short_ / long_ + SKETCH_STROKE_WIDTH_PX
    got_long, got_short = (h, w) if r1 - r0 > c1 - c0 else (w, h)
    assert abs(cr - SKETCH_SIZE / 2) <= FRAME_TOL_PX and abs(cc - SKETCH_SIZE / 2) <= FRAME_TOL_PX
    assert abs(got_long - expected_long) <= 2 * FRAME_TOL_PX, (got_long, expected_long)
    assert abs(got_short - expected_short) <= 2 * FRAME_TOL_PX + 2, (got_short, expected_short)


def test_stroke_width_is_normalised_whatever_the_input_width():
    """A 1-px and a 15-px line come out alike: one centre line redrawn at SKETCH_STROKE_WIDTH_PX."""
    outs = []
    for thickness in (1, 15):
        ink = np.zeros((200, 300), np.uint8)
        cv2.line(ink, (20, 100), (280, 100), 255, thickness)
        outs.append(preprocess_raster(ink / 255.0))
    # a horizontal framed line: length FRAMED, round caps -> ink = width * length + pi * (width / 2)^2
    expected = SKETCH_STROKE_WIDTH_PX * FRAMED + np.pi * (SKETCH_STROKE_WIDTH_PX / 2) ** 2
    for out in outs:
        assert abs(out.sum() - expected) / expected < 0.03
    assert _iou(outs[0], outs[1]) > 0.95


def test_thin_lines_survive_heavy_downscaling():
    ink = np.zeros((3000, 4000), np.float32)
    cv2.line(ink, (100, 1500), (3900, 1600), 1.0, 1)
    cv2.line(ink, (2000, 200), (2000, 2800), 1.0, 1)
    out = preprocess_raster(ink)
    # two lines of centre-line lengths ~FRAMED and ~FRAMED * 2600 / 3800 at width 2
    expected = SKETCH_STROKE_WIDTH_PX * FRAMED * (1 + 2600 / 3801)
    assert abs(out.sum() - expected) / expected < 0.08


def test_draw_segments_profile_matches_hand_computation():
    """Coverage = clip(w/2 + 0.5 - d, 0, 1): hand-computed for a horizontal line at y = 64.25."""
    out = draw_segments(np.array([[[10.0, 64.25], [100.0, 64.25]]]), size=128, width=2.0)
    # pixel centres (row + 0.5) at distances: row 62 -> 1.75, 63 -> 0.75, 64 -> 0.25, 65 -> 1.25, 66 -> 2.25
    np.testing.assert_allclose(out[62:67, 50], [0.0, 0.75, 1.0, 0.25, 0.0], atol=1e-3)
    np.testing.assert_allclose(out[:, 20:90].sum(axis=0), 2.0, atol=1e-3)  # exact width away from the caps
    dot = draw_segments(np.array([[[5.5, 5.5], [5.5, 5.5]]]), size=12, width=2.0)
    assert dot[5, 5] == 1.0 and dot[5, 6] == pytest.approx(0.5) and dot[7, 5] == 0.0
    assert draw_segments(np.zeros((0, 2, 2))).sum() == 0.0
    with pytest.raises(SketchInputError):
        draw_segments(np.array([[[0.0, np.nan], [1.0, 1.0]]]))


def test_draw_segments_matches_brute_force_across_the_border():
    """Every pixel against clip(w/2 + 0.5 - d, 0, 1) with d its exact distance to the nearest segment, for segments
    that cross the image's edges, lie outside it, run along it, or are dots on a corner."""
    segs = np.array([[[-30.0, 5.2], [70.0, 5.2]], [[3.3, -10.0], [40.0, 90.0]], [[63.4, 10.0], [63.4, 50.0]],
                     [[-20.0, -20.0], [-5.0, -3.0]], [[64.0, 64.0], [64.0, 64.0]], [[10.0, 70.0], [50.0, 62.6]],
                     [[-1.0, 30.0], [-1.0, 30.0]], [[20.0, 20.0], [21.5, 21.0]]])
    size, width = 64, 3.0
    c = np.stack(np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5), axis=-1).reshape(-1, 1, 2)  # (x, y)
    a, b = segs[None, :, 0], segs[None, :, 1]
    ab = b - a
    t = np.clip(((c - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0.0, 1.0)
    dist = np.linalg.norm(c - (a + t[..., None] * ab), axis=-1).min(axis=1)
    expected = np.clip(width / 2 + 0.5 - dist, 0.0, 1.0).reshape(size, size)
    np.testing.assert_allclose(draw_segments(segs, size=size, width=width), expected, atol=1e-6)
    assert draw_segments(segs[3:4], size=size, width=width).sum() == 0.0  # wholly outside


def _canvas_png(strokes: list[Stroke], path, size=(420, 560), pen=5):
    """A canvas-like rasteriser: dark anti-aliased polylines of the pen width on white paper."""
    img = np.full(size, 255, np.uint8)
    for s in strokes:
        p = np.round(s.points * 16).astype(np.int32)
        if len(p) == 1:
            p = np.concatenate([p, p])
        cv2.polylines(img, [p], False, 0, pen, cv2.LINE_AA, shift=4)
    cv2.imwrite(str(path), img)


def _mean_chamfer(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric mean distance (px) between the ink pixels of two rasters."""
    out = []
    for x, y in ((a, b), (b, a)):
        dist = cv2.distanceTransform((y <= 0.5).astype(np.uint8), cv2.DIST_L2, 5)
        out.append(dist[x > 0.5].mean())
    return float(np.mean(out))


def _drawings():
    t = np.linspace(0, 2 * np.pi, 80)
    mug = [Stroke(np.stack([280 + 120 * np.cos(t), 200 + 90 * np.sin(t)], 1)),
           Stroke([[160, 200], [170, 330], [390, 330], [400, 200]]),
           Stroke([[400, 230], [450, 250], [450, 300], [395, 310]])]
    zigzag = [Stroke([[60, 300], [120, 80], [180, 300], [240, 80], [300, 300]], width=9.0), Stroke([[100, 350]])]
    return {"mug": mug, "zigzag": zigzag}


@pytest.mark.parametrize("name", ["mug", "zigzag"])
def test_strokes_and_their_png_give_the_same_raster(tmp_path, name):
    strokes = _drawings()[name]
    vec = rasterize_strokes(strokes)
    path = tmp_path / f"{name}.png"
    _canvas_png(strokes, path)
    img = sketch_raster_from_image(path)
    assert _mean_chamfer(vec, img) < 0.8
    assert _iou(vec, img) > 0.6  # 2-px lines: a half-pixel shift already costs a third of the IoU
    blur = lambda r: cv2.GaussianBlur(r, (0, 0), 1.0)  # noqa: E731
    assert np.minimum(blur(vec), blur(img)).sum() / np.maximum(blur(vec), blur(img)).sum() > 0.8


def test_rasterize_strokes_frames_on_the_points():
    s = Stroke([[10.0, 20.0], [110.0, 20.0], [110.0, 70.0]])  # 100 x 50 canvas px
    out = rasterize_strokes([s])
    cr, cc, h, w = _ink_bbox(out)
    assert abs(w - (FRAMED + SKETCH_STROKE_WIDTH_PX)) <= 1.0
    assert abs(h - (FRAMED / 2 + SKETCH_STROKE_WIDTH_PX)) <= 1.0
    assert abs(cr - 128) <= 0.5 and abs(cc - 128) <= 0.5
    # translation and scale of the canvas coordinates do not change the raster
    moved = rasterize_strokes([Stroke(s.points * 3.0 + 500.0)])
    np.testing.assert_allclose(moved, out, atol=1e-5)


def test_rasterize_strokes_bad_input():
    with pytest.raises(EmptySketchError):
        rasterize_strokes([])
    with pytest.raises(SketchInputError):
        rasterize_strokes([np.zeros((3, 2))])
    with pytest.raises(SketchInputError):
        rasterize_strokes([Stroke([[0.0, np.nan]])])
    dot = rasterize_strokes([Stroke([[5.0, 5.0]])])  # one dot at (128, 128): 4 pixel centres at sqrt(0.5)
    np.testing.assert_allclose(dot[127:129, 127:129], 1.5 - np.sqrt(0.5), atol=1e-3)
    assert dot.sum() == pytest.approx(4 * (1.5 - np.sqrt(0.5)), abs=1e-3)


def _arc(rng, n=40):
    t = np.linspace(0.0, 1.0, n)
    c, r = rng.uniform(100.0, 500.0, 2), rng.uniform(20.0, 150.0)
    return np.stack([c[0] + r * np.cos(5.0 * t), c[1] + r * np.sin(5.0 * t)], axis=1)


def test_stroke_rasterizer_matches_a_full_redraw_through_a_session():
    """Live updates, pen-ups, strokes past the edge, undo, an erased stroke split in two, a dot: after each, the
    remembering rasterizer gives exactly (bit for bit) the raster drawn from scratch."""
    rng = np.random.default_rng(3)
    draw = StrokeRasterizer()
    committed: list[Stroke] = []

    def check(strokes):
        np.testing.assert_array_equal(draw(strokes), rasterize_strokes(strokes))

    for _ in range(6):
        pts = _arc(rng)
        for m in (1, 2, 10, 25, 40):  # the stroke under the pen, a new object each update
            check(committed + [Stroke(pts[:m])])
        committed.append(Stroke(pts))
        check(committed)  # pen-up
    check(committed + [Stroke([[900.0, 900.0], [950.0, 960.0]])])  # past the drawing's edge: a new frame
    check(committed[:-1])  # undo
    a, b = committed[2].points[:15], committed[2].points[20:]  # the eraser splits a stroke
    check(committed[:2] + [Stroke(a), Stroke(b)] + committed[3:])
    check(committed + [Stroke([[300.0, 300.0]])])  # a dot
    assert np.array_equal(draw(committed), rasterize_strokes(committed))


def test_stroke_rasterizer_draws_only_what_changed():
    """Work scales with the changed strokes: inside the drawing's bounding box only the stroke under the pen is drawn;
    a point outside it reframes and so redraws everything; the same strokes again draw nothing."""
    rng = np.random.default_rng(4)
    outline = Stroke([[-100.0, -100.0], [700.0, -100.0], [700.0, 700.0], [-100.0, 700.0], [-100.0, -100.0]])  # holds every arc
    inner = [Stroke(_arc(rng)) for _ in range(5)]
    draw = StrokeRasterizer()
    draw([outline, *inner])
    assert draw.last_drawn_segments == 4 + 5 * 39  # first call: everything
    live = Stroke(_arc(rng, 12))
    draw([outline, *inner, live])
    assert draw.last_drawn_segments == 39 + 11  # the kept raster was of all but the last stroke
    longer = Stroke(np.concatenate([live.points, [[300.0, 300.0]]]))
    draw([outline, *inner, longer])
    assert draw.last_drawn_segments == 12  # the stroke under the pen only
    draw([outline, *inner, longer])
    assert draw.last_drawn_segments == 0
    past = Stroke([[300.0, 300.0], [800.0, 800.0]])
    draw([outline, *inner, past])
    assert draw.last_drawn_segments == 4 + 5 * 39 + 1
    with pytest.raises(EmptySketchError):
        draw([])
    with pytest.raises(SketchInputError):
        draw([outline, np.zeros((3, 2))])


def test_jpeg_exif_orientation_is_applied(tmp_path):
    """A phone photo stored landscape with EXIF orientation 6 (rotate 90 degrees clockwise) loads upright."""
    img = np.full((40, 80), 255, np.uint8)
    cv2.line(img, (5, 5), (70, 10), 0, 3)
    ok, buf = cv2.imencode(".jpg", img)
    data = buf.tobytes()
    tiff = b"MM\x00*" + struct.pack(">I", 8) + struct.pack(">H", 1) + struct.pack(">HHII", 0x0112, 3, 1, 6 << 16) + struct.pack(">I", 0)
    app1 = b"\xff\xe1" + struct.pack(">H", 2 + 6 + len(tiff)) + b"Exif\x00\x00" + tiff
    path = tmp_path / "photo.jpg"
    path.write_bytes(data[:2] + app1 + data[2:])
    got = load_sketch_image(path)
    assert got.shape == (80, 40)
    expected = np.rot90(1.0 - img / 255.0, k=-1)  # clockwise
    assert _iou(got, expected) >= LOSSY_MIN_IOU


def test_mostly_ink_is_not_a_line_drawing():
    with pytest.raises(SketchInputError, match="not a line drawing"):
        preprocess_raster(np.ones((300, 300), np.float32))


@pytest.mark.parametrize("points", [
    [[1e12, 1e12], [1e12 + 5, 1e12 + 3]],  # far from the origin
    [[0.0, 0.0], [1e15, 1.0]],  # huge extent
    [[1.0, 1.0], [1.0 + 1e-12, 1.0]],  # sub-nanometre extent: a dot
])
def test_extreme_stroke_coordinates_stay_finite(points):
    out = rasterize_strokes([Stroke(points)])
    assert np.all(np.isfinite(out)) and 0 < out.sum() and out.max() <= 1.0


def test_concurrent_decoding_keeps_stderr_intact(tmp_path, monkeypatch):
    """Decoders capture fd 2 briefly; concurrent loads must leave fd 2 pointing where it did."""
    import os
    import threading
    import time

    original = cv2.imdecode

    def slow_decode(*args):  # widen the capture window so the threads really overlap
        time.sleep(0.005)
        return original(*args)

    monkeypatch.setattr(cv2, "imdecode", slow_decode)

    good = tmp_path / "good.png"
    cv2.imwrite(str(good), 255 - _truth())
    ok, buf = cv2.imencode(".png", 255 - _truth())
    bad = tmp_path / "bad.png"
    bad.write_bytes(buf.tobytes()[:-20] + b"\x00" * 8 + b"IEND\xaeB`\x82")  # corrupt body, intact end marker
    before = os.fstat(2)
    errors = []

    def work(path):
        for _ in range(10):
            try:
                load_sketch_image(path)
            except SketchInputError:
                pass
            except Exception as exc:  # pragma: no cover - reported below
                errors.append(exc)

    threads = [threading.Thread(target=work, args=(p,)) for p in (good, bad, good, bad)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    after = os.fstat(2)
    assert not errors and (before.st_dev, before.st_ino) == (after.st_dev, after.st_ino)
