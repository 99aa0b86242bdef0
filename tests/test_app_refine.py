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


def test_exports_repair_folds_unless_told_not_to(qtbot, tmp_path):
    import trimesh

    from engine.mesh import Mesh
    from engine.postprocess import repair_self_intersections, self_intersections

    folding = write_fixture_models(tmp_path / "folding", fold=True)  # every predicted mesh crosses itself
    w = MainWindow(models_dir=folding, autosave_dir=tmp_path / "autosave", debounce_ms=10)
    try:
        w.show()
        qtbot.waitExposed(w)
        act = w.actions["repair"]
        assert act.isCheckable() and act.isChecked() == REPAIR_BY_DEFAULT
        if not act.isChecked():
            act.trigger()
        with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
            draw_stroke(w.canvas, line_points(60, 80, 300, 300))
        shown = w.last_prediction.mesh
        assert self_intersections(shown) > 20  # the preview is the prediction, folds included
        exported = {}
        for on in (True, False):
            if act.isChecked() != on:
                act.trigger()
            path = tmp_path / f"mesh_{on}.obj"
            with qtbot.waitSignal(w.exportFinished, timeout=WAIT_MS) as done:
                assert w.export_mesh_to(path)
            assert done.args == [str(path), ""], w.status_text()
            loaded = trimesh.load(path, force="mesh", process=False)
            exported[on] = Mesh(np.asarray(loaded.vertices), np.asarray(loaded.faces))
            assert ("folds repaired" in w.status_text()) == on
        assert self_intersections(exported[True]) == 0
        np.testing.assert_allclose(exported[True].vertices, repair_self_intersections(shown).mesh.vertices, atol=1e-5)
        np.testing.assert_allclose(exported[False].vertices, shown.vertices, atol=1e-5)
        assert w.last_prediction.mesh is shown  # exporting never re-predicts
    finally:
        w.close()
        w.deleteLater()


def test_with_the_refinement_on_the_window_shows_the_networks_mesh_then_the_refined_one(qtbot, window, models):
    """Refinement on: the networks' mesh is shown as soon as it is ready, then the refined one replaces it and alone
    becomes the last prediction (what exports take); each is the engine's own for the drawing."""
    w = window
    if not w.actions["refine"].isChecked():
        w.actions["refine"].trigger()
    shown = []
    w.controller.previewReady.connect(lambda i, p: shown.append(("preview", i, p)))
    w.controller.predictionReady.connect(lambda i, p: shown.append(("final", i, p)))
    with qtbot.waitSignals([w.previewShown, w.meshUpdated], order="strict", timeout=WAIT_MS):
        draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    (kind0, id0, preview), (kind1, id1, final) = shown[-2:]
    assert (kind0, kind1) == ("preview", "final") and id0 == id1
    assert w.last_prediction is final
    raster = final.sketch
    ref = SketchEngine(models, threads=1, cache_size=0, mirror_average=w.engine.mirror_average,
                       repair_folds=w.engine.repair_folds)
    np.testing.assert_allclose(preview.mesh.vertices, ref.predict(raster, refine=0).mesh.vertices, atol=1e-5)
    np.testing.assert_allclose(final.mesh.vertices, ref.predict(raster, refine=DEFAULT_STEPS).mesh.vertices, atol=1e-5)
    assert preview.timings_ms["refine"] == 0.0 and final.timings_ms["refine"] > 0.0
    assert final.timings_ms["generator"] == preview.timings_ms["generator"] > 0.0  # not the cache hit's zeros
