"""The app's "Refine to outline" toggle drives the engine's refinement and shows its time (issue 17)."""

from __future__ import annotations

import pytest
from gui_helpers import draw_stroke, gui_isolation, line_points
from onnx_fixtures import write_fixture_models

from app.window import REFINE_BY_DEFAULT, MainWindow
from engine.refine import DEFAULT_STEPS

WAIT_MS = 20000


@pytest.fixture(autouse=True)
def dialogs(qapp, tmp_path, monkeypatch):
    with gui_isolation(tmp_path, monkeypatch) as recorder:
        yield recorder


def test_refine_toggle_sets_the_engine_steps_and_the_status_bar_shows_the_time(qtbot, tmp_path):
    models = write_fixture_models(tmp_path / "models")
    w = MainWindow(models_dir=models, autosave_dir=tmp_path / "autosave", debounce_ms=10)
    try:
        w.resize(1000, 620)
        w.show()
        qtbot.waitExposed(w)
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
    finally:
        w.force_close()
        w.deleteLater()
