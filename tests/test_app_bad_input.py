"""Bad input swept through the app's File > Open and File > Load models (issue 18, part 3).

The command-line sweep is tests/test_bad_input_sweep.py; here the same images (tests/bad_inputs.py),
half-written and foreign sketch documents, and broken model folders go through the real menu
actions (the file dialogs answered by monkeypatch) of a real window. The contract:

* File > Open of a bad file: one warning dialog whose text names the file and the problem, the
  status bar says so, and the drawing (strokes and background) is untouched. Exotic but valid
  encodings (16-bit, CMYK, palette, alpha-only) open as the background like a plain PNG.
* File > Load models of a broken folder: the status bar names the folder or file and the problem,
  and the models already loaded stay in use (the next stroke still gets a mesh from them).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from bad_inputs import write_images
from gui_helpers import draw_stroke, gui_isolation, line_points
from onnx_fixtures import write_corrupt_model, write_fixture_models
from PySide6.QtCore import QEventLoop, QTimer
from PySide6.QtWidgets import QFileDialog

from app.window import MainWindow
from engine import contract as C

WAIT_MS = 20000
LOAD_WAIT_MS = 5000
"""A broken model folder is reported at once (files missing), or once the worker has tried to load it (well under a second)."""


@pytest.fixture(autouse=True)
def dialogs(qapp, tmp_path, monkeypatch):
    with gui_isolation(tmp_path, monkeypatch) as recorder:
        yield recorder


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("app_inputs")
    p = write_images(root / "images")
    docs = root / "docs"
    docs.mkdir()
    good = {"format": "sketchmesh-sketch", "version": 1, "canvas": [512, 512],
            "strokes": [{"points": [[10.0, 10.0], [200.0, 200.0]], "width": 3.0}], "background": None}
    text = json.dumps(good)
    p["half-written sketch"] = docs / "half.sketch.json"
    p["half-written sketch"].write_text(text[: len(text) // 2])
    p["foreign JSON sketch"] = docs / "other.sketch.json"
    p["foreign JSON sketch"].write_text(json.dumps({"type": "FeatureCollection", "features": []}))
    p["newer sketch version"] = docs / "future.sketch.json"
    p["newer sketch version"].write_text(json.dumps(good | {"version": 99}))
    p["zero-byte sketch"] = docs / "empty.sketch.json"
    p["zero-byte sketch"].write_text("")
    p["missing file"] = root / "vanished.png"
    p["folder"] = root / "images"
    models = write_fixture_models(root / "models")
    p["models"] = models
    p["models: one ONNX missing"] = root / "models_missing_one"
    p["models: one ONNX missing"].mkdir()
    shutil.copy(models / C.GENERATOR_FILE, p["models: one ONNX missing"] / C.GENERATOR_FILE)
    p["models: swapped"] = root / "models_swapped"
    p["models: swapped"].mkdir()
    shutil.copy(models / C.GENERATOR_FILE, p["models: swapped"] / C.PREDICTOR_FILE)
    shutil.copy(models / C.PREDICTOR_FILE, p["models: swapped"] / C.GENERATOR_FILE)
    p["models: corrupt"] = root / "models_corrupt"
    write_corrupt_model(p["models: corrupt"] / C.GENERATOR_FILE)
    shutil.copy(models / C.PREDICTOR_FILE, p["models: corrupt"] / C.PREDICTOR_FILE)
    p["models: empty folder"] = root / "models_empty"
    p["models: empty folder"].mkdir()
    p["models: missing folder"] = root / "models_nowhere"
    p["models: a file"] = p["good"]
    return p


@pytest.fixture
def window(qtbot, tmp_path, inputs):
    """A window on the fixture models (the real engine), one stroke drawn and its mesh shown."""
    w = MainWindow(models_dir=inputs["models"], autosave_dir=tmp_path / "autosave", persist_settings=False,
                   debounce_ms=10)
    w.resize(1000, 620)
    w.show()
    qtbot.waitExposed(w)
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    yield w
    w.force_close()
    w.deleteLater()


def _open(w: MainWindow, path: Path, monkeypatch) -> None:
    """File > Open, then wait until the file has been read (that happens on a job thread)."""
    monkeypatch.setattr(QFileDialog, "getOpenFileName", staticmethod(lambda *a, **k: (str(path), "")))
    loop = QEventLoop()
    w.sketchOpened.connect(loop.quit)
    QTimer.singleShot(WAIT_MS, loop.quit)
    w.actions["open"].trigger()
    loop.exec()
    w.sketchOpened.disconnect(loop.quit)


OPEN_CASES = {
    "truncated": "PNG file is truncated",
    "zero-byte": "file is empty",
    "1x1": "image is 1x1 pixels, too small",
    "20000x20000": "image is 20000x20000 pixels, larger than the limit",
    "all-ink": "no ink",
    "all-paper": "no ink",
    "not-an-image": "not a supported image",
    "missing file": "no such file",
    "folder": "not a file",
    "half-written sketch": "cannot read sketch file",
    "foreign JSON sketch": "not a Sketchmesh sketch",
    "newer sketch version": "unsupported sketch file version 99",
    "zero-byte sketch": "cannot read sketch file",
}


def test_file_open_of_a_bad_file_is_one_dialog_and_keeps_the_drawing(window, inputs, dialogs, monkeypatch):
    for kind, needle in OPEN_CASES.items():  # one window for all: each case must leave it as it was
        dialogs.calls.clear()
        before = (window.canvas.strokes(), window.canvas.background)
        path = inputs[kind]
        _open(window, path, monkeypatch)
        assert dialogs.kinds() == ["warning"], (kind, dialogs.calls)
        text = dialogs.calls[0][2]
        assert path.name in text and needle in text, (kind, text)
        assert len(text.splitlines()) == 1 and "Traceback" not in text, (kind, text)
        assert f"Could not open {path.name}" in window.status_text(), (kind, window.status_text())
        assert (window.canvas.strokes(), window.canvas.background) == before, kind


def test_file_open_of_exotic_but_valid_images_sets_the_same_background(window, inputs, dialogs, monkeypatch, qtbot):
    _open(window, inputs["good"], monkeypatch)
    reference = window.canvas.background.ink.copy()
    for kind in ("16-bit", "cmyk", "palette", "alpha-only"):
        with qtbot.waitSignal(window.meshUpdated, timeout=WAIT_MS):
            _open(window, inputs[kind], monkeypatch)
        assert dialogs.kinds() == [] and window.canvas.background is not None, (kind, dialogs.calls)
        np.testing.assert_array_equal(window.canvas.background.ink > 0.5, reference > 0.5, err_msg=kind)


LOAD_CASES = {
    "models: one ONNX missing": "(mesh_predictor.onnx is missing)",
    "models: swapped": "files swapped?",
    "models: corrupt": "cannot load model",
    "models: empty folder": "No models in",
    "models: missing folder": "No models in",
    "models: a file": "No models in",
}


@pytest.mark.parametrize("kind", list(LOAD_CASES))
def test_load_models_of_a_broken_folder_says_why_and_keeps_the_working_models(kind, window, inputs, dialogs,
                                                                               monkeypatch, qtbot):
    engine = window.engine
    folder = inputs[kind]
    monkeypatch.setattr(QFileDialog, "getExistingDirectory", staticmethod(lambda *a, **k: str(folder)))
    window.actions["load_models"].trigger()
    qtbot.waitUntil(lambda: LOAD_CASES[kind] in window.status_text(), timeout=LOAD_WAIT_MS)
    assert folder.name in window.status_text() and "Traceback" not in window.status_text()
    assert window.engine is engine  # the working models stay in use ...
    with qtbot.waitSignal(window.meshUpdated, timeout=WAIT_MS):  # ... and still answer the next stroke
        draw_stroke(window.canvas, line_points(60, 300, 300, 80))
