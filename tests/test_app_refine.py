"""The app's "Refine to outline" toggle drives the engine's refinement and shows its time (issue 17); the
"Mirror average" toggle drives the engine's mirror averaging, "Repair folds" its fold repair."""

from __future__ import annotations

import numpy as np
import pytest
from gui_helpers import draw_stroke, gui_isolation, line_points
from onnx_fixtures import write_fixture_models

from app.window import MIRROR_BY_DEFAULT, REFINE_BY_DEFAULT, REPAIR_BY_DEFAULT, MainWindow
from engine.pipeline import SketchEngine
from engine.refine import DEFAULT_STEPS

WAIT_MS = 20000


@pytest.fixture(autouse=True)
def dialogs(qapp, tmp_path, monkeypatch):
    with gui_isolation(tmp_path, monkeypatch) as recorder:
        yield recorder


@pytest.fixture
def models(tmp_path):
    return write_fixture_models(tmp_path / "models")


@pytest.fixture
def window(qtbot, tmp_path, models):
    """A shown main window on the fixture models, closed afterwards."""
    w = MainWindow(models_dir=models, autosave_dir=tmp_path / "autosave", debounce_ms=10)
    try:
        w.resize(1000, 620)
        w.show()
        qtbot.waitExposed(w)
        yield w
    finally:
        w.force_close()
        w.deleteLater()


def test_refine_toggle_sets_the_engine_steps_and_the_status_bar_shows_the_time(qtbot, window):
    w = window
    act = w.actions["refine"]
    assert act.isCheckable() and act.isChecked() == REFINE_BY_DEFAULT
    assert w.engine.refine_steps == (DEFAULT_STEPS if REFINE_BY_DEFAULT else 0)
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    if not act.isChecked():
        with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
            act.trigger()
    assert w.engine.refine_steps == DEFAULT_STEPS
    assert "refine" in w.timing_label.text()
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        act.trigger()  # off: the sketch is predicted again, without refinement
    assert w.engine.refine_steps == 0 and w.last_prediction.timings_ms["refine"] == 0.0


def test_mirror_toggle_sets_the_engine_and_predicts_again(qtbot, window, models):
    w = window
    act = w.actions["mirror"]
    assert act.isCheckable() and act.isChecked() == MIRROR_BY_DEFAULT
    assert w.engine.mirror_average == MIRROR_BY_DEFAULT
    if w.actions["refine"].isChecked():
        w.actions["refine"].trigger()  # compare the networks' meshes alone
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    meshes = {}
    for _ in range(2):
        meshes[w.engine.mirror_average] = w.last_prediction.mesh.vertices.copy()
        with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
            act.trigger()
        assert w.engine.mirror_average == act.isChecked()
    # each mode's mesh is the engine's own for the same drawing, and the two differ
    raster = w.last_prediction.sketch
    for on, vertices in meshes.items():
        ref = SketchEngine(models, threads=1, cache_size=0, mirror_average=on,
                           repair_folds=w.engine.repair_folds).predict(raster).mesh.vertices
        np.testing.assert_allclose(vertices, ref, atol=1e-5)
    assert np.abs(meshes[True] - meshes[False]).max() > 1e-3


def test_repair_toggle_sets_the_engine_and_predicts_again(qtbot, window):
    w = window
    act = w.actions["repair"]
    assert act.isCheckable() and act.isChecked() == REPAIR_BY_DEFAULT
    assert w.engine.repair_folds == REPAIR_BY_DEFAULT
    if not act.isChecked():
        act.trigger()
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    first = w.last_prediction
    assert first.repair_folds and first.timings_ms["repair"] > 0.0 and "repair" in w.timing_label.text()
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        act.trigger()  # off: predicted again without the repair
    off = w.last_prediction
    assert not w.engine.repair_folds and not off.repair_folds and not off.cached and off.timings_ms["repair"] == 0.0
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        act.trigger()  # on again: the repaired mesh of the same drawing, from the cache
    again = w.last_prediction
    assert w.engine.repair_folds and again.repair_folds and again.cached
    np.testing.assert_array_equal(again.mesh.vertices, first.mesh.vertices)
