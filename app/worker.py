"""Live inference off the UI thread: debounce -> worker QThread -> request ids -> stale results dropped.

Pattern (as superqt's thread workers): one long-lived :class:`InferenceWorker` QObject is
moved to a QThread owned by the :class:`InferenceController`, which lives on the GUI thread.
The controller debounces sketch changes with a single-shot QTimer (the first change after a
pause goes at once, the rest of a burst waits for the last), tags each request with
an increasing id and sends it through a queued signal. The worker skips requests already
superseded when it reaches them (so a burst of edits costs one inference, not one per edit)
and answers with ``resultReady(request_id, Prediction)`` or ``errorOccurred(request_id,
message)``; the controller forwards only the answer to the newest request. The GUI thread
never calls ``engine.predict``, and never converts pixels for a result either: a canvas
composite (:class:`app.canvas.CanvasComposite`) is rendered and framed on the worker, and the
worker makes the two thumbnails the window shows (:class:`Thumbnails`, fetched with
:meth:`InferenceController.take_thumbnails`).

With the engine's outline refinement on (``refine_steps`` > 0), the worker first answers with the networks' own mesh,
``previewReady(request_id, ...)``, then refines it (the engine's cache holds the networks' result, so only the
refinement runs again) and answers with ``resultReady``: the artist sees a mesh as soon as the networks are done, and
a drawing superseded meanwhile is not refined at all.

A new model folder is loaded the same way: :meth:`InferenceController.load_engine` hands a
candidate engine to the worker, which creates and validates its ONNX Runtime sessions there
(queued behind the requests already sent, never skipped as stale); the engine in use keeps
answering until the caller switches with :meth:`InferenceController.set_engine` on
``engineLoaded``, and stays in use on ``engineLoadFailed``.

:class:`EventLoopLatencyProbe` measures how late a short repeating QTimer fires on the GUI
thread: the UI's responsiveness while inference runs (a debug figure, and a test).
"""

from __future__ import annotations

import atexit
import os
import sys
import threading
import time
import weakref
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import shiboken6
from PySide6.QtCore import QElapsedTimer, QObject, Qt, QThread, QTimer, Signal, Slot
from PySide6.QtGui import QImage

from engine.cliutil import int_from_env
from engine.errors import SketchmeshError

DEFAULT_DEBOUNCE_MS = 100
"""Quiet time after the last change before a request is sent (80-150 ms feels live)."""

LIVE_WHILE_DRAWING_MAX_MS = 120.0
"""Send requests while a stroke is still being drawn only if the last inference took less."""

MAX_NICE = 19
"""The largest nice value Linux has (the lowest priority)."""


def nice_from_env(name: str, default: int) -> int:
    """The nice value environment variable ``name`` sets (0 to MAX_NICE; 0 leaves the thread as it is), else ``default``.

    Raises:
        SketchmeshError: ``name`` is set but not a whole number from 0 to MAX_NICE.
    """
    chosen = int_from_env(name, 0, MAX_NICE, " (0 leaves the priority as it is)")
    return default if chosen is None else chosen


WORKER_NICE_ENV = "SKETCHMESH_WORKER_NICE"
WORKER_NICE = nice_from_env(WORKER_NICE_ENV, 0)
"""Nice value of the inference thread (Linux), inherited by the ONNX Runtime threads it starts;
0 (the default) leaves it at the app's priority. A higher value was the default until 2026-11-27
(10, meant to let the UI and render threads win the CPU): it gave inference away to every other
process on a busy machine (the engine 1,256 ms p50 per stroke against 178 at 0 with both cores of
a 2-core machine busy) and made the UI stall longer, not shorter (max lag 112 ms against 33), as
the worker holds Python's GIL between the engine's calls: ``reproduce_models.sh session-nice``."""

SHUTDOWN_WAIT_MS = 10_000
"""How long closing waits for an inference in progress to finish."""

COMPOSITE_TIMES_KEPT = 10_000
"""Canvas-composite render times the worker keeps for the session report (the newest; a long app run stays small)."""

SketchInput = object  # list[Stroke] | (256, 256) float32 raster | CanvasRaster | CanvasComposite | path


@dataclass(frozen=True, eq=False)
class CanvasRaster:
    """A canvas composite (background image + strokes) that still needs framing.

    The worker runs ``engine.preprocess.preprocess_raster`` on it (thinning and framing cost
    a few milliseconds, so they stay off the GUI thread) before ``engine.predict``.

    Attributes:
        ink: (H, W) float32 in [0, 1], 1 = ink, canvas resolution, read-only.
    """

    ink: np.ndarray

    def __post_init__(self) -> None:
        a = np.asarray(self.ink)
        if a.dtype != np.float32 or a.flags.writeable:
            a = np.array(a, dtype=np.float32)  # a private copy crosses the thread (read-only ones are shared)
        if a.ndim != 2:
            raise ValueError(f"CanvasRaster ink must be (H, W), got {a.shape}")
        a.setflags(write=False)
        object.__setattr__(self, "ink", a)


@dataclass(frozen=True, eq=False)
class Thumbnails:
    """The window's two result thumbnails, made on the worker thread.

    Attributes:
        sketch: the generator's input, dark on white, Grayscale8, fitted into ``size``.
        normals: the normal image, RGB888, fitted into ``size`` (None when not predicted).
    """

    sketch: QImage | None
    normals: QImage | None


def make_thumbnails(prediction: object, size: int) -> Thumbnails:
    """Thumbnails of a prediction's ``sketch`` and ``normals`` (any thread: QImage only)."""
    from app.canvas import ink_to_qimage  # noqa: PLC0415

    def fit(img: QImage) -> QImage:
        return img.scaled(size, size, Qt.AspectRatioMode.KeepAspectRatio, Qt.TransformationMode.SmoothTransformation)

    sketch = getattr(prediction, "sketch", None)
    normals = getattr(prediction, "normals", None)
    return Thumbnails(
        None if sketch is None else fit(ink_to_qimage(np.asarray(sketch))),
        None if normals is None else fit(rgb_to_qimage(np.asarray(normals))),
    )


def rgb_to_qimage(rgb: np.ndarray) -> QImage:
    """(H, W, 3) float in [0, 1] or uint8 -> RGB888 QImage (a copy)."""
    a = np.asarray(rgb)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"image must be (H, W, 3), got {a.shape}")
    if a.dtype != np.uint8:
        a = np.round(np.clip(np.nan_to_num(a.astype(np.float32)), 0.0, 1.0) * 255.0).astype(np.uint8)
    a = np.ascontiguousarray(a)
    h, w, _ = a.shape
    return QImage(a.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy()


def warm_imports() -> None:
    """Import what later steps import lazily (mesh export), so no first use pays for it: an
    import on any thread holds the interpreter lock for tens of milliseconds at a time."""
    import trimesh  # noqa: F401, PLC0415
    import trimesh.exchange.gltf  # noqa: F401, PLC0415

    import engine.export  # noqa: F401, PLC0415


def lower_thread_priority(nice: int | None = None) -> bool:
    """Raise the calling thread's nice value to ``nice`` (default WORKER_NICE, read when called;
    Linux: per thread; threads it starts inherit it). Returns False where nothing changed: a value of
    0, other systems, or refused."""
    if nice is None:
        nice = WORKER_NICE
    if nice <= 0 or not sys.platform.startswith("linux") or not hasattr(os, "setpriority"):
        return False
    try:
        tid = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, tid, max(os.getpriority(os.PRIO_PROCESS, tid), nice))
    except OSError:
        return False
    return True


PRELOAD = object()
"""Request payload that makes the worker load the engine's models (``engine.load()``) so the
first stroke does not pay for creating the ONNX Runtime sessions, and broken models are
reported at once."""

_ORPHANS: list[tuple[QThread, QObject]] = []
"""Worker threads still finishing an inference after their controller shut down."""


def load_engine_models(engine: object) -> str | None:
    """Load ``engine``'s models (``engine.load()``, when it has one) and warm the lazy imports;
    the one-line reason on failure, None on success. Any thread; never raises."""
    try:
        load = getattr(engine, "load", None)
        if load is not None:
            load()
        warm_imports()
    except SketchmeshError as exc:
        return str(exc)
    except MemoryError:
        return "out of memory while loading the models"
    except Exception as exc:  # a broken model must not kill the worker
        return f"{type(exc).__name__}: {exc}"
    return None


_LIVE: weakref.WeakSet[InferenceController] = weakref.WeakSet()
"""Controllers not shut down yet: shut down at interpreter exit (:func:`_shutdown_all`)."""


def _release_orphan(thread: QThread) -> None:
    _ORPHANS[:] = [(t, w) for t, w in _ORPHANS if t is not thread]


@atexit.register
def _shutdown_all() -> None:
    """Interpreter exit with a controller never shut down (a script that left its window
    open): stop its thread first, since Qt aborts the process when a running QThread is
    destroyed, and Python destroys the wrappers in no particular order."""
    for controller in list(_LIVE):
        if shiboken6.isValid(controller):  # a controller whose C++ side is gone has no thread to stop
            controller.shutdown()


class InferenceWorker(QObject):
    """Runs ``engine.predict`` on its own thread; one request at a time, stale ones skipped.

    Signals:
        resultReady(int, object): (request_id, (engine.pipeline.Prediction, Thumbnails | None)).
        previewReady(int, object): the same for the unrefined mesh of a request the engine then refines (module doc).
        errorOccurred(int, str): (request_id, one-line message).
        skipped(int): a request superseded before it started.
        loaded(int): a preload request (:data:`PRELOAD`) finished without error.
        engineLoaded(int, object): (token, engine) a candidate engine's models loaded (:meth:`load_engine`).
        engineFailed(int, str): (token, one-line message) they did not.
    """

    resultReady = Signal(int, object)
    previewReady = Signal(int, object)
    errorOccurred = Signal(int, str)
    skipped = Signal(int)
    loaded = Signal(int)
    engineLoaded = Signal(int, object)
    engineFailed = Signal(int, str)

    def __init__(self) -> None:
        super().__init__()
        self._latest = 0
        self._lock = threading.Lock()
        self._stopping = False
        self.thumbnail_size: int | None = None
        """When set, each result carries :class:`Thumbnails` of this side (set before starting)."""
        self.thread_ids: set[int] = set()
        """Threads ``predict`` ran on (tests check it never is the GUI thread)."""
        self.composite_ms: deque[float] = deque(maxlen=COMPOSITE_TIMES_KEPT)
        """Wall time of the latest canvas composites rendered here (a background layer under the strokes), for the
        session report; appended on this thread, read after the session."""

    def note_latest(self, request_id: int) -> None:
        """Called from the GUI thread: requests older than this are stale."""
        with self._lock:
            self._latest = max(self._latest, request_id)

    def stop(self) -> None:
        """Cooperative shutdown: skip every request not yet started."""
        with self._lock:
            self._stopping = True

    def _stale(self, request_id: int) -> bool:
        """Whether ``request_id`` has been superseded (or the worker is stopping)."""
        with self._lock:
            return self._stopping or request_id < self._latest

    @Slot(int, object, object)
    def process(self, request_id: int, engine: object, sketch: SketchInput) -> None:
        if self._stale(request_id):
            self.skipped.emit(request_id)
            return
        self.thread_ids.add(threading.get_ident())
        if sketch is PRELOAD:
            problem = load_engine_models(engine)
            if problem is None:
                self.loaded.emit(request_id)
            else:
                self.errorOccurred.emit(request_id, problem)
            return
        try:
            from app.canvas import CanvasComposite  # noqa: PLC0415

            if isinstance(sketch, (CanvasRaster, CanvasComposite)):
                from engine.preprocess import preprocess_raster  # noqa: PLC0415

                if isinstance(sketch, CanvasComposite):
                    t0 = time.perf_counter()
                    ink = sketch.render()
                    self.composite_ms.append((time.perf_counter() - t0) * 1e3)
                else:
                    ink = sketch.ink
                sketch = preprocess_raster(ink)
            answer = self._predict(request_id, engine, sketch)
            if answer is None:  # superseded after its preview: not refined
                self.skipped.emit(request_id)
                return
            prediction, thumbs = answer
        except SketchmeshError as exc:
            self.errorOccurred.emit(request_id, str(exc))
        except MemoryError:
            self.errorOccurred.emit(request_id, "out of memory during inference")
        except Exception as exc:  # never let a worker exception kill the thread or the app
            self.errorOccurred.emit(request_id, f"{type(exc).__name__}: {exc}")
        else:
            self.resultReady.emit(request_id, (prediction, thumbs))

    def _predict(self, request_id: int, engine: object, sketch: object) -> tuple[object, Thumbnails | None] | None:
        """(``engine.predict``'s Prediction, its thumbnails); with the refinement on, the unrefined mesh is sent first
        as a preview (module doc). None when the request was superseded after its preview."""
        steps = getattr(engine, "refine_steps", 0)
        first = engine.predict(sketch, want_normals=True, **({"refine": 0} if steps else {}))
        thumbs = None if self.thumbnail_size is None else make_thumbnails(first, self.thumbnail_size)
        if not steps:
            return first, thumbs
        self.previewReady.emit(request_id, (first, thumbs))
        if self._stale(request_id):
            return None
        refined = engine.predict(sketch, want_normals=True, refine=steps)  # the networks' result from the cache
        # the networks' stages as they ran for the preview, the refinement's and the repair's from this call; the
        # thumbnails are the preview's (the refinement moves the mesh only, not the drawing or the normal image)
        timings = {**first.timings_ms, **{k: v for k, v in refined.timings_ms.items() if k in ("refine", "repair")}}
        return replace(refined, timings_ms=timings, cached=first.cached), thumbs

    @Slot(int, object)
    def load_engine(self, token: int, engine: object) -> None:
        """Load a candidate engine's models here, off the GUI thread; never skipped as stale
        (only by :meth:`stop`), since a stroke drawn meanwhile must not cancel a model load."""
        with self._lock:
            stopping = self._stopping
        if stopping:
            return
        self.thread_ids.add(threading.get_ident())
        problem = load_engine_models(engine)
        if problem is None:
            self.engineLoaded.emit(token, engine)
        else:
            self.engineFailed.emit(token, problem)


class InferenceController(QObject):
    """GUI-thread side: debounce, request ids, stale dropping, worker thread lifetime.

    Signals:
        predictionReady(int, object): the newest request's Prediction.
        previewReady(int, object): the newest request's unrefined Prediction, while it is being refined.
        predictionFailed(int, str): the newest request's error message.
        cleared(): the sketch became empty (the viewport should show nothing).
        busyChanged(bool): whether a request or a model load is outstanding.
        engineLoaded(int, object): (token, engine) the newest :meth:`load_engine` succeeded.
        engineLoadFailed(int, str): (token, one-line message) the newest :meth:`load_engine` failed.
    """

    predictionReady = Signal(int, object)
    previewReady = Signal(int, object)
    predictionFailed = Signal(int, str)
    cleared = Signal()
    busyChanged = Signal(bool)
    engineLoaded = Signal(int, object)
    engineLoadFailed = Signal(int, str)
    _request = Signal(int, object, object)
    _loadRequest = Signal(int, object)

    def __init__(
        self,
        engine: object | None = None,
        debounce_ms: int = DEFAULT_DEBOUNCE_MS,
        parent: QObject | None = None,
        *,
        thumbnail_size: int | None = None,
    ) -> None:
        super().__init__(parent)
        self._thumbs: dict[int, Thumbnails] = {}
        self._engine = engine
        self._next_id = 0
        self._latest_id = 0
        self._outstanding: set[int] = set()
        self._loading: set[int] = set()
        self._load_token = 0
        self._provider: Callable[[], SketchInput | None] | None = None
        self.dropped_count = 0
        """Results that arrived for a superseded request and were dropped."""
        self.skipped_count = 0
        """Requests the worker skipped because they were superseded before starting."""
        self.last_roundtrip_ms: float | None = None
        """Wall time from send to answer of the last fresh result (includes queueing)."""
        self._sent_at: dict[int, float] = {}
        self._debounce = QTimer(self)
        self._debounce.setSingleShot(True)
        # precise: never early (a coarse timer may fire up to 5 % early), so the last change of a
        # burst is sent the full delay after it, and schedule()'s "quiet" test agrees with the timer
        self._debounce.setTimerType(Qt.TimerType.PreciseTimer)
        self._debounce.setInterval(int(debounce_ms))
        self._debounce.timeout.connect(self._fire)
        self._last_schedule = -float("inf")  # perf_counter() of the last schedule()
        self._thread = QThread()
        self._thread.setObjectName("sketchmesh-inference")
        self._thread.started.connect(lower_thread_priority, Qt.ConnectionType.DirectConnection)  # runs on the new thread
        self._worker = InferenceWorker()
        self._worker.thumbnail_size = thumbnail_size
        self._worker.moveToThread(self._thread)
        self._request.connect(self._worker.process, Qt.ConnectionType.QueuedConnection)
        self._worker.resultReady.connect(self._on_result, Qt.ConnectionType.QueuedConnection)
        self._worker.previewReady.connect(self._on_preview, Qt.ConnectionType.QueuedConnection)
        self._worker.errorOccurred.connect(self._on_error, Qt.ConnectionType.QueuedConnection)
        self._worker.skipped.connect(self._on_skipped, Qt.ConnectionType.QueuedConnection)
        self._worker.loaded.connect(self._on_loaded, Qt.ConnectionType.QueuedConnection)
        self._loadRequest.connect(self._worker.load_engine, Qt.ConnectionType.QueuedConnection)
        self._worker.engineLoaded.connect(self._on_engine_loaded, Qt.ConnectionType.QueuedConnection)
        self._worker.engineFailed.connect(self._on_engine_failed, Qt.ConnectionType.QueuedConnection)
        self._thread.start()
        self._shut_down = False
        _LIVE.add(self)

    # ---- configuration ----------------------------------------------------------------
    @property
    def engine(self) -> object | None:
        return self._engine

    def set_engine(self, engine: object | None) -> None:
        """Use ``engine`` for the next requests (in-flight answers from the old one are dropped)."""
        self._engine = engine
        self._invalidate()

    @property
    def worker(self) -> InferenceWorker:
        return self._worker

    @property
    def latest_id(self) -> int:
        return self._latest_id

    @property
    def busy(self) -> bool:
        return bool(self._outstanding) or bool(self._loading) or self._debounce.isActive()

    @property
    def loading(self) -> bool:
        """A :meth:`load_engine` is still running (or queued) on the worker."""
        return bool(self._loading)

    def set_debounce_ms(self, ms: int) -> None:
        self._debounce.setInterval(int(ms))

    # ---- requests ------------------------------------------------------------------------
    def schedule(self, provider: Callable[[], SketchInput | None]) -> None:
        """Ask for inference: at once when the sketch had been quiet for the debounce delay, else
        after the delay; ``provider()`` builds the input then.

        The first change after a pause (a pen-up after drawing, a single undo) is sent at once,
        so its mesh comes a debounce sooner; a change within the delay of the one before restarts
        the delay, so a burst of changes makes at most two requests, its first and its last.
        Answers to requests sent before this call are dropped from now on (they describe an
        older drawing). ``provider`` returning None means an empty sketch (the viewport is cleared).
        """
        if self._shut_down:
            return
        now = time.perf_counter()
        quiet = (now - self._last_schedule) * 1e3 >= self._debounce.interval()
        self._last_schedule = now
        if self._provider is None:
            # the sketch changed: whatever is in flight now describes an older drawing
            self._invalidate()
        self._provider = provider
        if quiet and not self._debounce.isActive():
            self._fire()
        else:
            self._debounce.start()

    def flush(self) -> int | None:
        """Send a scheduled request now (no waiting for the debounce); returns its id."""
        if self._debounce.isActive():
            self._debounce.stop()
            return self._fire()
        return None

    def _fire(self) -> int | None:
        provider, self._provider = self._provider, None
        if provider is None:
            return None
        try:
            sketch = provider()
        except SketchmeshError as exc:
            rid = self._invalidate()
            self.predictionFailed.emit(rid, str(exc))
            return rid
        return self.submit(sketch)

    def submit(self, sketch: SketchInput | None) -> int:
        """Send ``sketch`` to the worker now; returns the request id. None clears the result."""
        if self._shut_down:
            raise RuntimeError("the inference controller has been shut down")
        if sketch is None or (isinstance(sketch, (list, tuple)) and len(sketch) == 0):
            rid = self._invalidate()
            self.cleared.emit()
            return rid
        if isinstance(sketch, np.ndarray):
            sketch = np.array(sketch, dtype=np.float32)  # private copy crosses the thread
            sketch.setflags(write=False)
        if self._engine is None:
            rid = self._invalidate()
            self.predictionFailed.emit(rid, "No model folder is set: choose one (File > Load models...)")
            return rid
        rid = self._invalidate()
        self._outstanding.add(rid)
        self._sent_at[rid] = time.perf_counter()
        self.busyChanged.emit(True)
        self._request.emit(rid, self._engine, sketch)
        return rid

    def preload(self) -> int | None:
        """Load the engine's models on the worker now (errors arrive as predictionFailed)."""
        if self._shut_down or self._engine is None:
            return None
        rid = self._invalidate()
        self._outstanding.add(rid)
        self.busyChanged.emit(True)
        self._request.emit(rid, self._engine, PRELOAD)
        return rid

    def load_engine(self, engine: object) -> int | None:
        """Load ``engine``'s models on the worker without using it yet; returns a token.

        The engine in use keeps answering requests meanwhile (those sent before this call are
        answered first; later ones wait for the load). ``engineLoaded(token, engine)`` or
        ``engineLoadFailed(token, message)`` follows, only for the newest call (an older load's
        answer is dropped); switch with :meth:`set_engine`. None once shut down.
        """
        if self._shut_down:
            return None
        self._load_token += 1
        token = self._load_token
        self._loading.add(token)
        self.busyChanged.emit(True)
        self._loadRequest.emit(token, engine)
        return token

    def _invalidate(self) -> int:
        self._next_id += 1
        self._latest_id = self._next_id
        self._worker.note_latest(self._latest_id)
        return self._latest_id

    def _finish(self, request_id: int) -> bool:
        """Bookkeeping for an answer; returns True when it is the newest request's."""
        self._outstanding.discard(request_id)
        sent = self._sent_at.pop(request_id, None)
        fresh = request_id == self._latest_id
        if fresh and sent is not None:
            self.last_roundtrip_ms = (time.perf_counter() - sent) * 1e3
        if not self._outstanding and not self._loading:
            self.busyChanged.emit(False)
        return fresh

    @Slot(int, object)
    def _on_result(self, request_id: int, result: object) -> None:
        prediction, thumbs = result
        if self._finish(request_id):
            if thumbs is not None:
                self._thumbs = {request_id: thumbs}  # only the newest is ever asked for
            self.predictionReady.emit(request_id, prediction)
        else:
            self.dropped_count += 1

    @Slot(int, object)
    def _on_preview(self, request_id: int, result: object) -> None:
        prediction, thumbs = result
        if request_id == self._latest_id and request_id in self._outstanding:  # the request itself is not finished
            if thumbs is not None:
                self._thumbs = {request_id: thumbs}
            self.previewReady.emit(request_id, prediction)

    def take_thumbnails(self, request_id: int) -> Thumbnails | None:
        """The worker-made thumbnails of a result (once; None without ``thumbnail_size``)."""
        return self._thumbs.pop(request_id, None)

    @Slot(int, str)
    def _on_error(self, request_id: int, message: str) -> None:
        if self._finish(request_id):
            self.predictionFailed.emit(request_id, message)
        else:
            self.dropped_count += 1

    @Slot(int)
    def _on_loaded(self, request_id: int) -> None:
        self._finish(request_id)
        self.last_roundtrip_ms = None  # a load is not an inference: no live-drawing estimate from it

    def _finish_load(self, token: int) -> bool:
        """Bookkeeping for a load's answer; returns True when it is the newest load's."""
        self._loading.discard(token)
        if not self._outstanding and not self._loading:
            self.busyChanged.emit(False)
        return token == self._load_token and not self._shut_down

    @Slot(int, object)
    def _on_engine_loaded(self, token: int, engine: object) -> None:
        if self._finish_load(token):
            self.engineLoaded.emit(token, engine)

    @Slot(int, str)
    def _on_engine_failed(self, token: int, message: str) -> None:
        if self._finish_load(token):
            self.engineLoadFailed.emit(token, message)

    @Slot(int)
    def _on_skipped(self, request_id: int) -> None:
        self.skipped_count += 1
        self._finish(request_id)

    # ---- lifetime ------------------------------------------------------------------------
    def shutdown(self, wait_ms: int = SHUTDOWN_WAIT_MS) -> bool:
        """Stop the worker cooperatively: pending requests are skipped, the running one
        finishes, the thread quits. Returns False if it did not stop within ``wait_ms``."""
        if self._shut_down:
            return True
        self._shut_down = True
        _LIVE.discard(self)
        self._debounce.stop()
        self._provider = None
        self._worker.stop()
        self._thread.quit()
        stopped = bool(self._thread.wait(int(wait_ms)))
        if stopped:
            self._worker.deleteLater()
        else:
            # an inference is still running (onnxruntime cannot be interrupted): keep the thread
            # and worker alive until it returns, so Qt never destroys a running QThread
            _ORPHANS.append((self._thread, self._worker))
            self._thread.finished.connect(lambda t=self._thread: _release_orphan(t))
        return stopped


class EventLoopLatencyProbe(QObject):
    """Measures GUI event-loop lateness with a repeating precise QTimer.

    Each tick records ``max(0, elapsed_since_last_tick - interval)`` in milliseconds: how
    long the event loop was busy beyond the timer period. Under a blocking call on the GUI
    thread the lateness grows to the call's duration; with inference on the worker thread
    it stays near zero.
    """

    def __init__(self, interval_ms: int = 10, parent: QObject | None = None) -> None:
        super().__init__(parent)
        if interval_ms < 1:
            raise ValueError(f"interval_ms must be >= 1, got {interval_ms}")
        self.interval_ms = int(interval_ms)
        self._timer = QTimer(self)
        self._timer.setTimerType(Qt.TimerType.PreciseTimer)
        self._timer.setInterval(self.interval_ms)
        self._timer.timeout.connect(self._tick)
        self._clock = QElapsedTimer()
        self.samples_ms: list[float] = []

    def start(self) -> None:
        self.samples_ms.clear()
        self._clock.start()
        self._timer.start()

    def stop(self) -> None:
        self._timer.stop()

    @property
    def running(self) -> bool:
        return self._timer.isActive()

    def _tick(self) -> None:
        elapsed = self._clock.nsecsElapsed() / 1e6
        self._clock.restart()
        self.samples_ms.append(max(0.0, elapsed - self.interval_ms))
        if len(self.samples_ms) > 10_000:  # bounded memory in a long session
            del self.samples_ms[:5_000]

    @property
    def max_ms(self) -> float:
        return max(self.samples_ms) if self.samples_ms else 0.0

    def percentile_ms(self, q: float) -> float:
        """The q-th percentile (0-100) of the recorded lateness, 0 when nothing was recorded."""
        return float(np.percentile(self.samples_ms, q)) if self.samples_ms else 0.0
