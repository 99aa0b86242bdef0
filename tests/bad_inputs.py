"""Bad inputs shared by the sweeps (tests/test_bad_input_sweep.py, tests/test_app_bad_input.py).

:func:`write_images` writes every kind of sketch image a hostile user could hand over (truncated,
zero bytes, 1x1, a real 20000x20000 PNG, all ink, all paper, a text file named .png) and the
exotic but valid encodings of one drawing (16-bit, CMYK, palette, alpha-only);
:func:`write_meshes` writes mesh folders holding one broken mesh each.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def write_big_white_png(path: Path, width: int, height: int) -> Path:
    """A real, complete 8-bit grey PNG of ``width`` x ``height`` white pixels, streamed (no big array)."""
    row = b"\x00" + b"\xff" * width
    z = zlib.compressobj(1)
    idat = b"".join([z.compress(row) for _ in range(height)] + [z.flush()])
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + _png_chunk(b"IDAT", idat) + _png_chunk(b"IEND", b""))
    return path


def drawing(h: int = 240, w: int = 320) -> np.ndarray:
    """(h, w) uint8 dark lines on white: an ellipse and its axis (a mug seen from above)."""
    img = np.full((h, w), 255, np.uint8)
    cv2.ellipse(img, (w // 2, h // 2), (w // 3, h // 3), 0, 0, 360, 0, 3)
    cv2.line(img, (w // 5, h // 2), (4 * w // 5, h // 2), 0, 3)
    return img


def write_images(folder: Path) -> dict[str, Path]:
    """Every kind of sketch image, bad and exotic; keys name the kind."""
    from PIL import Image

    folder.mkdir(parents=True, exist_ok=True)
    ink = drawing()
    p = {}
    p["good"] = folder / "good.png"
    cv2.imwrite(str(p["good"]), ink)
    data = p["good"].read_bytes()
    p["truncated"] = folder / "truncated.png"
    p["truncated"].write_bytes(data[: len(data) // 2])
    p["zero-byte"] = folder / "zero.png"
    p["zero-byte"].write_bytes(b"")
    p["1x1"] = folder / "one.png"
    cv2.imwrite(str(p["1x1"]), np.zeros((1, 1), np.uint8))
    p["20000x20000"] = write_big_white_png(folder / "huge.png", 20000, 20000)
    p["all-ink"] = folder / "all_ink.png"
    cv2.imwrite(str(p["all-ink"]), np.zeros((240, 320), np.uint8))
    p["all-paper"] = folder / "all_paper.png"
    cv2.imwrite(str(p["all-paper"]), np.full((240, 320), 255, np.uint8))
    p["not-an-image"] = folder / "notes.png"
    p["not-an-image"].write_text("shopping list: milk, eggs\n")
    # exotic encodings of the good drawing: these must work, not fail
    p["16-bit"] = folder / "deep.png"
    cv2.imwrite(str(p["16-bit"]), ink.astype(np.uint16) * 257)
    p["cmyk"] = folder / "cmyk.jpg"
    Image.fromarray(ink).convert("CMYK").save(p["cmyk"], quality=95)
    p["palette"] = folder / "palette.png"
    Image.fromarray(ink).convert("P").save(p["palette"])
    p["alpha-only"] = folder / "alpha.png"
    rgba = np.zeros((*ink.shape, 4), np.uint8)
    rgba[..., 3] = 255 - ink  # black everywhere; the drawing lives in the alpha channel alone
    cv2.imwrite(str(p["alpha-only"]), rgba)
    return p


def write_meshes(folder: Path) -> dict[str, Path]:
    """Mesh folders for ``data --source meshes:DIR``, one bad mesh each (keys name the kind)."""
    out = {}
    cases = {
        "no-faces": ("flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"),
        "nan-vertices": ("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n"),
        "truncated": ("cut.ply", "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n"),
        "not-a-mesh": ("photo.stl", "\x00\x01garbage" * 3),
    }
    for kind, (name, text) in cases.items():
        d = folder / kind / "thing"
        d.mkdir(parents=True)
        (d / name).write_text(text)
        out[kind] = folder / kind
    return out
