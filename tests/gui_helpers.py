"""Shared helpers for the GUI tests: a fake engine, simulated mouse strokes, isolation.

Each GUI test module wraps :func:`gui_isolation` in an autouse fixture (named ``dialogs``,
since it yields the dialog recorder)::

    @pytest.fixture(autouse=True)
    def dialogs(qapp, tmp_path, monkeypatch):
        with gui_isolation(tmp_path, monkeypatch) as recorder:
            yield recorder

It points QSettings and the autosave folder at tmp_path, replaces QMessageBox's static
dialogs by a recorder (no modal dialog can hang a test), and fails the test if a top-level
widget leaks.
"""

from __future__ import annotations

import contextlib
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QSettings, Qt
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QApplication, QMessageBox

from engine.errors import EmptySketchError, SketchmeshError
from engine.icosphere import icosphere
from engine.mesh import Mesh
from engine.pipeline import STAGES, Prediction
from engine.strokes import Stroke

FAKE_LEVEL = 2
"""Icosphere level of the fake engine's meshes (162 vertices: cheap to render)."""


class FakeEngine:
    """Same interface as engine.pipeline.SketchEngine; controllable delay, gate and errors.

    The mesh is an icosphere scaled by ``0.2 + 0.1 * (number of strokes)`` (or by the ink
    fraction for rasters), so a test can tell which request a shown mesh came from.
    """

    def __init__(self, models_dir: str | Path = "/fake/models", *, delay_s: float = 0.0, gated: bool = False) -> None:
        self.models_dir = Path(models_dir)
        self.delay_s = delay_s
        self.gate = threading.Event()
        if not gated:
            self.gate.set()
        self.error: Exception | None = None
        self.calls: list[object] = []
        self.started = threading.Event()
        self.thread_ids: set[int] = set()
        self._template = icosphere(FAKE_LEVEL)

    def model_info(self) -> dict:
        return {"models_dir": str(self.models_dir), "fake": True}

    @staticmethod
    def scale_for(sketch: object) -> float:
        if isinstance(sketch, np.ndarray):
            return 0.2 + float(np.mean(sketch > 0.5))
        return 0.2 + 0.1 * len(list(sketch))

    def predict(self, sketch: object, *, want_normals: bool = False) -> Prediction:
        self.thread_ids.add(threading.get_ident())
        self.calls.append(sketch)
        self.started.set()
        if not self.gate.wait(timeout=20):
            raise RuntimeError("FakeEngine gate never opened")
        if self.delay_s:
            time.sleep(self.delay_s)
        if self.error is not None:
            raise self.error
        if isinstance(sketch, (list, tuple)) and not sketch:
            raise EmptySketchError("the sketch has no strokes")
        raster = np.zeros((256, 256), np.float32)
        raster[100:150, 100:150] = 1.0
        s = self.scale_for(sketch)
        mesh = Mesh(self._template.vertices * s, self._template.faces)
        normals = np.full((256, 256, 3), 0.5, np.float32) if want_normals else None
        if normals is not None:
            normals[:, :, 2] = 1.0
        return Prediction(mesh, normals, raster, {k: 1.0 for k in STAGES}, False)


def fake_factory(engine: FakeEngine):
    """An engine factory for MainWindow that always returns ``engine`` (any folder)."""

    def factory(folder: Path) -> FakeEngine:
        engine.models_dir = Path(folder)
        return engine

    return factory


def failing_factory(message: str):
    def factory(folder: Path) -> FakeEngine:
        raise SketchmeshError(message)

    return factory


def draw_stroke(widget, points, *, step_wait_ms: int = 0) -> None:
    """Press at points[0], move through the rest, release at points[-1] (left button)."""
    pts = [QPoint(int(round(x)), int(round(y))) for x, y in points]
    QTest.mousePress(widget, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, pts[0])
    for p in pts[1:]:
        QTest.mouseMove(widget, p, step_wait_ms)
    QTest.mouseRelease(widget, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, pts[-1])


def line_points(x0: float, y0: float, x1: float, y1: float, n: int = 12) -> list[tuple[float, float]]:
    t = np.linspace(0.0, 1.0, n)
    return list(zip(x0 + t * (x1 - x0), y0 + t * (y1 - y0)))


def make_stroke(points, width: float = 3.0) -> Stroke:
    return Stroke(np.asarray(points, dtype=np.float64), None, width)


@dataclass
class DialogRecorder:
    """Stands in for QMessageBox's static functions; answers come from ``answers`` (FIFO)."""

    calls: list[tuple[str, str, str]] = field(default_factory=list)
    answers: list[QMessageBox.StandardButton] = field(default_factory=list)
    default: QMessageBox.StandardButton = QMessageBox.StandardButton.Discard

    def _record(self, kind: str, title: str, text: str) -> QMessageBox.StandardButton:
        self.calls.append((kind, title, text))
        return self.answers.pop(0) if self.answers else self.default

    def kinds(self) -> list[str]:
        return [c[0] for c in self.calls]


def _deferred_delete() -> None:
    app = QApplication.instance()
    for _ in range(3):
        app.processEvents()
        QApplication.sendPostedEvents(None, 52)  # QEvent.DeferredDelete


@contextlib.contextmanager
def gui_isolation(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """Isolate settings/autosave in tmp_path, record dialogs, and catch leaked top-level widgets.

    Needs a QApplication (request pytest-qt's ``qapp`` fixture). Yields the DialogRecorder.
    """
    settings_dir = tmp_path / "settings"
    data_dir = tmp_path / "data"
    settings_dir.mkdir()
    data_dir.mkdir()
    QSettings.setPath(QSettings.Format.IniFormat, QSettings.Scope.UserScope, str(settings_dir))
    monkeypatch.setenv("XDG_CONFIG_HOME", str(settings_dir))
    monkeypatch.setenv("XDG_DATA_HOME", str(data_dir))
    rec = DialogRecorder()

    def question(parent, title, text, *a, **k):
        return rec._record("question", title, text)

    def warning(parent, title, text, *a, **k):
        return rec._record("warning", title, text)

    def critical(parent, title, text, *a, **k):
        return rec._record("critical", title, text)

    def information(parent, title, text, *a, **k):
        return rec._record("information", title, text)

    def about(parent, title, text):
        rec._record("about", title, text)

    monkeypatch.setattr(QMessageBox, "question", staticmethod(question))
    monkeypatch.setattr(QMessageBox, "warning", staticmethod(warning))
    monkeypatch.setattr(QMessageBox, "critical", staticmethod(critical))
    monkeypatch.setattr(QMessageBox, "information", staticmethod(information))
    monkeypatch.setattr(QMessageBox, "about", staticmethod(about))
    _deferred_delete()
    before = {id(w) for w in QApplication.topLevelWidgets()}
    yield rec
    _deferred_delete()
    leaked = [w for w in QApplication.topLevelWidgets() if id(w) not in before]
    names = [f"{type(w).__name__}{' (visible)' if w.isVisible() else ''}" for w in leaked]
    for w in leaked:
        w.close()
        w.deleteLater()
    _deferred_delete()
    assert not leaked, f"top-level widgets leaked: {names}"

