"""The ``.sketch.json`` document format, and crash-safe autosave of the current sketch.

Document (UTF-8 JSON)::

    {"format": "sketchmesh-sketch", "version": 1,
     "canvas": [width, height],                 # canvas pixels when saved
     "strokes": [Stroke.to_dict(), ...],        # engine.strokes
     "background": null | {"rect": [x, y, w, h], "png_base64": "..."}}  # ink as dark-on-white PNG

Writes are atomic (engine.fileio). The autosave file lives in ``QStandardPaths
AppDataLocation`` (or a folder given by the caller, as tests do) and is written a short
debounce after each change, removed when the user saves or discards, and offered for
restore on the next start when it is still there (a crash or a kill). A kill in the middle of
an autosave leaves the last complete file intact and a half-written temporary sibling
(``.autosave.sketch.json.XXXX.tmp``), which the next start deletes. Autosave writes and
removals run in order on a thread of their own (:class:`app.jobs.JobQueue`), never on the UI
thread; a background image is PNG-encoded once per layer, not once per autosave.
"""

from __future__ import annotations

import base64
import json
import os
import threading
import weakref
from pathlib import Path

import numpy as np
from PySide6.QtCore import QBuffer, QByteArray, QIODevice, QObject, QStandardPaths, QTimer, Signal
from PySide6.QtGui import QImage

from app.canvas import BackgroundLayer, ink_to_qimage, qimage_to_ink
from app.history import SketchState
from app.jobs import WAIT_MS, JobQueue
from engine.errors import SketchInputError
from engine.fileio import atomic_write_text, remove_stale_temporaries
from engine.strokes import Stroke

SKETCH_FORMAT = "sketchmesh-sketch"
SKETCH_VERSION = 1
SKETCH_SUFFIX = ".sketch.json"
AUTOSAVE_NAME = "autosave" + SKETCH_SUFFIX
AUTOSAVE_DEBOUNCE_MS = 400
MAX_SKETCH_FILE_BYTES = 64 * 1024 * 1024
"""Refuse absurdly large sketch files instead of hanging on them."""


_PNG_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_PNG_LOCK = threading.Lock()


def _layer_png_base64(layer: BackgroundLayer) -> str:
    """The layer's ink as base64 PNG, encoded once per (immutable) layer; any thread."""
    with _PNG_LOCK:
        hit = _PNG_CACHE.get(layer)
    if hit is None:
        hit = _png_base64(layer.ink)
        with _PNG_LOCK:
            _PNG_CACHE[layer] = hit
    return hit


def _png_base64(ink: np.ndarray) -> str:
    buf = QBuffer()
    buf.open(QIODevice.OpenModeFlag.WriteOnly)
    if not ink_to_qimage(ink).save(buf, "PNG"):
        raise OSError("could not encode the background image as PNG")
    return base64.b64encode(bytes(buf.data().data())).decode("ascii")


def _ink_from_png_base64(text: str) -> np.ndarray:
    img = QImage()
    if not img.loadFromData(QByteArray(base64.b64decode(text, validate=True)), "PNG") or img.isNull():
        raise SketchInputError("the background image in the sketch file is not a valid PNG")
    return qimage_to_ink(img)


def sketch_to_dict(state: SketchState, canvas_size: tuple[int, int]) -> dict:
    """JSON-ready document for a sketch state drawn on a ``(width, height)`` canvas."""
    bg = state.background
    return {
        "format": SKETCH_FORMAT,
        "version": SKETCH_VERSION,
        "canvas": [int(canvas_size[0]), int(canvas_size[1])],
        "strokes": [s.to_dict() for s in state.strokes],
        "background": None
        if not isinstance(bg, BackgroundLayer)
        else {"rect": list(bg.rect), "png_base64": _layer_png_base64(bg)},
    }


def sketch_from_dict(doc: object) -> tuple[SketchState, tuple[int, int]]:
    """Inverse of :func:`sketch_to_dict`; raises SketchInputError naming what is wrong."""
    if not isinstance(doc, dict) or doc.get("format") != SKETCH_FORMAT:
        raise SketchInputError(f"not a Sketchmesh sketch (expected \"format\": \"{SKETCH_FORMAT}\")")
    version = doc.get("version")
    if version != SKETCH_VERSION:
        raise SketchInputError(f"unsupported sketch file version {version!r} (this app reads {SKETCH_VERSION})")
    try:
        w, h = (int(v) for v in doc.get("canvas", [512, 512]))
    except (TypeError, ValueError):
        raise SketchInputError(f"malformed canvas size {doc.get('canvas')!r}") from None
    raw = doc.get("strokes", [])
    if not isinstance(raw, list):
        raise SketchInputError("malformed sketch file: \"strokes\" must be a list")
    strokes = tuple(Stroke.from_dict(d) if isinstance(d, dict) else _bad_stroke(i) for i, d in enumerate(raw))
    bg = None
    raw_bg = doc.get("background")
    if raw_bg is not None:
        try:
            bg = BackgroundLayer(_ink_from_png_base64(raw_bg["png_base64"]), tuple(raw_bg["rect"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise SketchInputError(f"malformed background in sketch file: {exc}") from None
    return SketchState(strokes, bg, "Open sketch"), (max(w, 1), max(h, 1))


def _bad_stroke(i: int) -> Stroke:
    raise SketchInputError(f"malformed sketch file: stroke {i} is not an object")


def write_sketch_file(path: str | os.PathLike, state: SketchState, canvas_size: tuple[int, int]) -> None:
    """Write a ``.sketch.json`` document atomically."""
    atomic_write_text(path, json.dumps(sketch_to_dict(state, canvas_size), separators=(",", ":")))


def read_sketch_file(path: str | os.PathLike) -> tuple[SketchState, tuple[int, int]]:
    """Read a ``.sketch.json`` document; raises SketchInputError for a missing/corrupt file."""
    p = Path(path)
    try:
        size = p.stat().st_size
        if size > MAX_SKETCH_FILE_BYTES:
            raise SketchInputError(f"{p}: sketch file too large ({size} bytes)")
        doc = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SketchInputError(f"{p}: no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SketchInputError(f"{p}: cannot read sketch file ({exc})") from None
    try:
        return sketch_from_dict(doc)
    except SketchInputError as exc:
        raise SketchInputError(f"{p}: {exc}") from None


def default_autosave_dir() -> Path:
    """``QStandardPaths.AppDataLocation`` (falls back to ~/.local/share/sketchmesh)."""
    loc = QStandardPaths.writableLocation(QStandardPaths.StandardLocation.AppDataLocation)
    return Path(loc) if loc else Path.home() / ".local" / "share" / "sketchmesh"


class Autosaver(QObject):
    """Debounced atomic autosave of a sketch state into ``folder / AUTOSAVE_NAME``.

    On creation it deletes the temporary files an earlier, killed session's autosave left in
    ``folder`` (only the autosave's own, ``.autosave.sketch.json.*.tmp``), on its writer thread
    before any write of its own.

    Signals:
        saved(str): the path written.
        failed(str): a one-line message (the app shows it; drawing goes on).
    """

    saved = Signal(str)
    failed = Signal(str)

    def __init__(self, folder: str | os.PathLike, delay_ms: int = AUTOSAVE_DEBOUNCE_MS, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.folder = Path(folder)
        self.path = self.folder / AUTOSAVE_NAME
        self._pending: tuple[SketchState, tuple[int, int]] | None = None
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(int(delay_ms))
        self._timer.timeout.connect(self.flush)
        self._jobs = JobQueue("sketchmesh-autosave", self)
        self._generation = 0  # bumped by discard(): writes queued before it are skipped
        self.write_count = 0
        self.stale_removed: list[Path] = []
        """Temporary files of a killed session's autosave deleted at start (filled in once that job is done)."""
        self._jobs.submit(lambda: remove_stale_temporaries(self.folder, AUTOSAVE_NAME), self.stale_removed.extend,
                          lambda msg: self.failed.emit(f"Could not remove a stale autosave file: {msg}"))

    def schedule(self, state: SketchState, canvas_size: tuple[int, int]) -> None:
        """Remember the latest state; write it after the debounce delay."""
        self._pending = (state, canvas_size)
        self._timer.start()

    @property
    def pending(self) -> bool:
        """A change not yet handed to the writer thread."""
        return self._pending is not None

    def flush(self) -> None:
        """Hand the pending state to the writer thread now (an empty sketch removes the file).

        ``saved`` or ``failed`` follow when it is done; :meth:`wait` blocks until then.
        """
        self._timer.stop()
        if self._pending is None:
            return
        state, size = self._pending
        self._pending = None
        generation, path = self._generation, self.path

        def write() -> bool | None:
            if generation != self._generation:
                return None  # discarded while queued
            if state.is_empty:
                path.unlink(missing_ok=True)
                return False
            write_sketch_file(path, state, size)
            return True

        self._jobs.submit(write, self._on_written, lambda msg: self.failed.emit(f"Autosave failed: {msg}"))

    def _on_written(self, wrote: bool | None) -> None:
        if wrote is None:
            return
        if wrote:
            self.write_count += 1
        self.saved.emit(str(self.path))

    def discard(self) -> None:
        """Cancel any pending write and delete the autosave file (work saved or discarded).

        The deletion runs after any write already queued (:meth:`wait` blocks until done).
        """
        self._timer.stop()
        self._pending = None
        self._generation += 1
        path = self.path
        self._jobs.submit(lambda: path.unlink(missing_ok=True), None,
                          lambda msg: self.failed.emit(f"Could not remove the autosave file: {msg}"))

    def wait(self, timeout_ms: int = WAIT_MS) -> bool:
        """Block until every queued write and removal has run."""
        return self._jobs.wait(timeout_ms)

    def has_recovery(self) -> bool:
        """True when an autosave file from an earlier session exists."""
        return self.path.is_file()

    def load_recovery(self) -> tuple[SketchState, tuple[int, int]]:
        """Read the autosave file; raises SketchInputError if it is corrupt."""
        return read_sketch_file(self.path)
