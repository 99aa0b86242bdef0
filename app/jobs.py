"""File work off the UI thread: a queue that runs callables one at a time, in order, on a thread of its own.

Autosave and mesh export write files (JSON with an encoded background image, a GLB); on a
loaded machine a write can take tens of milliseconds, and the UI thread must not wait for
it. A :class:`JobQueue` runs each job on a private one-thread QThreadPool, in submission
order (so an autosave never overtakes the deletion of the autosave file that followed it),
and calls ``on_done(result)`` or ``on_error(message)`` back on the GUI thread.
"""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import QObject, QThreadPool, Signal, Slot

from engine.errors import SketchmeshError

WAIT_MS = 10_000
"""How long :meth:`JobQueue.wait` waits by default (closing the window waits for the writes)."""


class JobQueue(QObject):
    """One-at-a-time, in-order background jobs with results delivered on the GUI thread.

    Signals:
        _finished(int, bool, object): internal (job id, ok, result or message), queued to the
            thread this object lives on.
    """

    _finished = Signal(int, bool, object)

    def __init__(self, name: str, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._pool = QThreadPool(self)
        self._pool.setMaxThreadCount(1)
        self._pool.setObjectName(name)
        self._next = 0
        self._callbacks: dict[int, tuple[Callable | None, Callable | None]] = {}
        self._finished.connect(self._deliver)

    def submit(self, fn: Callable[[], object], on_done: Callable[[object], None] | None = None,
               on_error: Callable[[str], None] | None = None) -> int:
        """Run ``fn()`` after every job submitted before it; returns the job id.

        ``on_done(result)`` / ``on_error(message)`` run later on this object's (GUI) thread;
        an exception in ``fn`` becomes ``on_error("Type: message")`` (a SketchmeshError: its
        message; an OSError: its strerror and file name).
        """
        self._next += 1
        jid = self._next
        self._callbacks[jid] = (on_done, on_error)

        def run() -> None:
            try:
                result = fn()
            except SketchmeshError as exc:
                self._finished.emit(jid, False, str(exc))
            except OSError as exc:
                self._finished.emit(jid, False, f"{exc.strerror or exc}" + (f": {exc.filename}" if exc.filename else ""))
            except Exception as exc:  # noqa: BLE001 (reported to the caller; the queue goes on)
                self._finished.emit(jid, False, f"{type(exc).__name__}: {exc}")
            else:
                self._finished.emit(jid, True, result)

        self._pool.start(run)
        return jid

    @property
    def pending(self) -> int:
        """Jobs submitted whose callbacks have not run yet."""
        return len(self._callbacks)

    def wait(self, timeout_ms: int = WAIT_MS) -> bool:
        """Block until every submitted job has run (callbacks come later, from the event loop)."""
        return bool(self._pool.waitForDone(int(timeout_ms)))

    @Slot(int, bool, object)
    def _deliver(self, jid: int, ok: bool, payload: object) -> None:
        on_done, on_error = self._callbacks.pop(jid, (None, None))
        if ok and on_done is not None:
            on_done(payload)
        elif not ok and on_error is not None:
            on_error(str(payload))
