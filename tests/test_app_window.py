"""The main window end to end: drawing -> worker -> viewport, menus, files, autosave, CLI.

Runs under Xvfb (tests/conftest.py). Each test builds one window; the VTK viewport is real.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from gui_helpers import FakeEngine, draw_stroke, fake_factory, gui_isolation, line_points
from onnx_fixtures import write_fixture_models
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QImage, QWheelEvent
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QApplication, QFileDialog, QMessageBox

from app.autosave import AUTOSAVE_NAME, read_sketch_file
from app.settings import AppSettings
from app.viewport import BACKGROUND_COLOR
from app.window import MESH_FILTERS, MainWindow, no_models_message
from engine.camera import DEFAULT_DISTANCE
from engine.export import supported_suffixes

ROOT = Path(__file__).resolve().parents[1]
WAIT_MS = 20000
NOT_BLANK_MIN_PIXELS = 500
"""Viewport pixels that must differ from the background for 'the mesh is visible'."""


@pytest.fixture(autouse=True)
def dialogs(qapp, tmp_path, monkeypatch):
    """Isolated settings/autosave, recorded QMessageBox calls, leak check (tests/gui_helpers.py)."""
    with gui_isolation(tmp_path, monkeypatch) as recorder:
        yield recorder


@pytest.fixture
def make_window(qtbot, tmp_path):
    windows = []

    def make(engine=None, **kw):
        kw.setdefault("engine_factory", fake_factory(engine if engine is not None else FakeEngine()))
        kw.setdefault("autosave_dir", tmp_path / "autosave")
        kw.setdefault("debounce_ms", 10)
        w = MainWindow(**kw)
        windows.append((w, engine))
        w.resize(1000, 620)
        w.show()
        qtbot.waitExposed(w)
        return w

    yield make
    for w, engine in windows:
        if isinstance(engine, FakeEngine):
            engine.gate.set()
        w.force_close()
        w.deleteLater()


def _draw_and_wait(qtbot, w, points):
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        draw_stroke(w.canvas, points)


def _qimage_to_array(img: QImage) -> np.ndarray:
    img = img.convertToFormat(QImage.Format.Format_RGB888)
    h, w, bpl = img.height(), img.width(), img.bytesPerLine()
    return np.frombuffer(img.constBits(), np.uint8, count=h * bpl).reshape(h, bpl)[:, : 3 * w].reshape(h, w, 3).copy()


def _non_background_pixels(rgb: np.ndarray) -> int:
    bg = np.round(np.array(BACKGROUND_COLOR) * 255)
    return int((np.abs(rgb.astype(np.int32) - bg).max(axis=2) > 30).sum())


def test_drawing_updates_mesh_normals_and_status_in_place(qtbot, make_window):
    eng = FakeEngine()
    w = make_window(eng)
    assert not w.viewport.has_mesh
    _draw_and_wait(qtbot, w, line_points(60, 80, 300, 300))
    assert w.viewport.sync()  # the render thread took the mesh and rendered it
    points = w.viewport._scene._points_np  # the buffer VTK reads; safe to look at while the renderer idles
    pred = w.last_prediction
    np.testing.assert_array_equal(points, pred.mesh.vertices)
    assert w.normal_panel.has_image and w.input_panel.has_image
    status = w.status_text()
    assert "generator 1.0 ms" in status and "Model: " in status and "UI lag" in status
    assert threading_safe(eng)
    # the user orbits; a new stroke updates the same PolyData and keeps the camera
    w.viewport.set_view("iso")
    cam = w.viewport.camera_position()
    _draw_and_wait(qtbot, w, line_points(60, 300, 300, 80))
    assert w.viewport.camera_position() == cam  # (waits for the renderer)
    assert w.viewport._scene._points_np is points and w.viewport.topology_changes == 1  # updated in place
    np.testing.assert_allclose(np.abs(points).max(), 0.5 * (0.2 + 0.1 * 2), rtol=1e-5)
    # undo via the menu action re-infers; clearing empties the viewport without an error
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        w.actions["undo"].trigger()
    assert w.viewport.sync()
    np.testing.assert_allclose(np.abs(points).max(), 0.5 * 0.3, rtol=1e-5)
    w.actions["clear"].trigger()
    qtbot.waitUntil(lambda: not w.viewport.has_mesh, timeout=WAIT_MS)
    assert not w.normal_panel.has_image and "failed" not in w.status_text().lower()


def threading_safe(eng: FakeEngine) -> bool:
    import threading

    return threading.get_ident() not in eng.thread_ids and len(eng.thread_ids) >= 1


def test_screenshot_shows_the_lit_mesh(qtbot, make_window, tmp_path):
    w = make_window(FakeEngine())
    blank = w.grab_with_viewport()
    vp_pos = w.viewport.mapTo(w, QPoint(0, 0))
    vw, vh = w.viewport.width(), w.viewport.height()

    def vp_region(img):
        return _qimage_to_array(img)[vp_pos.y() : vp_pos.y() + vh, vp_pos.x() : vp_pos.x() + vw]

    assert _non_background_pixels(vp_region(blank)) < NOT_BLANK_MIN_PIXELS  # empty canvas, empty view
    _draw_and_wait(qtbot, w, line_points(60, 80, 300, 300))
    shot = vp_region(w.grab_with_viewport())
    assert _non_background_pixels(shot) > NOT_BLANK_MIN_PIXELS
    centre = shot[vh // 2 - 5 : vh // 2 + 5, vw // 2 - 5 : vw // 2 + 5].reshape(-1, 3).astype(float)
    assert centre.mean() > 120  # the light-grey, lit sphere faces the camera in the sketch's view
    gray = shot.astype(float).mean(axis=2)
    mesh_px = gray[np.abs(shot.astype(int) - np.round(np.array(BACKGROUND_COLOR) * 255)).max(axis=2) > 30]
    assert mesh_px.std() > 5  # shaded, not a flat silhouette
    w.save_screenshot(tmp_path / "shot.png")
    assert QImage(str(tmp_path / "shot.png")).width() == w.width()


@pytest.mark.parametrize("suffix", list(MESH_FILTERS))
def test_export_mesh_through_menu(qtbot, make_window, tmp_path, monkeypatch, suffix):
    w = make_window(FakeEngine())
    _draw_and_wait(qtbot, w, line_points(60, 80, 300, 300))
    target = tmp_path / "out" / "mesh"  # no suffix: the chosen filter supplies it
    monkeypatch.setattr(QFileDialog, "getSaveFileName", staticmethod(lambda *a, **k: (str(target), MESH_FILTERS[suffix])))
    with qtbot.waitSignal(w.exportFinished, timeout=WAIT_MS) as done:
        w.actions["export_mesh"].trigger()  # written on a background thread
    path = target.with_suffix(suffix)
    assert done.args == [str(path), ""] and path.is_file(), w.status_text()
    loaded = trimesh.load(path, force="mesh", process=False)
    mesh = w.last_prediction.mesh
    assert len(loaded.faces) == mesh.num_faces
    assert suffix in supported_suffixes()
    if suffix != ".stl":  # STL stores unshared triangle corners
        assert len(loaded.vertices) == mesh.num_vertices
        np.testing.assert_allclose(loaded.vertices, mesh.vertices, atol=1e-5)
    assert "Exported" in w.status_text()


def test_export_without_mesh_and_export_errors_are_reported(qtbot, make_window, tmp_path, monkeypatch, dialogs):
    w = make_window(FakeEngine())
    called = []
    monkeypatch.setattr(QFileDialog, "getSaveFileName", staticmethod(lambda *a, **k: called.append(1) or ("", "")))
    w.actions["export_mesh"].trigger()
    assert not called and "Nothing to export" in w.status_text()
    w.actions["about"].trigger()
    assert dialogs.kinds() == ["about"]
    dialogs.calls.clear()
    _draw_and_wait(qtbot, w, line_points(60, 80, 300, 300))
    assert not w.export_mesh_to(tmp_path / "mesh.xyz")
    assert dialogs.kinds() == ["warning"] and ".obj" in dialogs.calls[0][2]
    dialogs.calls.clear()
    (tmp_path / "blocker").write_text("a file where a folder should be")
    with qtbot.waitSignal(w.exportFinished, timeout=WAIT_MS) as done:
        assert w.export_mesh_to(tmp_path / "blocker" / "mesh.obj")  # accepted; the write fails later
    assert done.args[1] and dialogs.kinds() == ["warning"] and "Export failed" in w.status_text()


def test_open_corrupt_image_keeps_drawing_and_valid_image_becomes_background(qtbot, make_window, tmp_path, monkeypatch, dialogs):
    eng = FakeEngine()
    w = make_window(eng)
    _draw_and_wait(qtbot, w, line_points(60, 80, 300, 300))
    before = w.canvas.strokes()
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\nthis is not a png")
    monkeypatch.setattr(QFileDialog, "getOpenFileName", staticmethod(lambda *a, **k: (str(bad), "")))
    with qtbot.waitSignal(w.sketchOpened, timeout=WAIT_MS) as opened:
        w.actions["open"].trigger()  # decoded on a job thread
    assert opened.args[0] == str(bad) and "bad.png" in opened.args[1]
    assert dialogs.kinds() == ["warning"] and "bad.png" in dialogs.calls[0][2]
    assert w.canvas.strokes() == before and w.canvas.background is None
    assert "Could not open bad.png" in w.status_text()
    # a real image: dark lines on white
    img = QImage(120, 80, QImage.Format.Format_Grayscale8)
    img.fill(255)
    arr = np.full((80, 120), 255, np.uint8)
    arr[20:60, 30:34] = 0
    arr[38:42, 10:110] = 0
    img = QImage(arr.data, 120, 80, 120, QImage.Format.Format_Grayscale8).copy()
    good = tmp_path / "good.png"
    assert img.save(str(good))
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        assert w.open_path(good)
    assert w.canvas.background is not None and w.canvas.strokes() == before
    assert isinstance(eng.calls[-1], np.ndarray) and eng.calls[-1].shape == (256, 256)  # framed composite


def test_autosave_and_restore_after_a_crash(qtbot, make_window, tmp_path, dialogs):
    w = make_window(FakeEngine())
    draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    draw_stroke(w.canvas, line_points(60, 300, 300, 80))
    autosave = tmp_path / "autosave" / AUTOSAVE_NAME
    qtbot.waitUntil(autosave.is_file, timeout=WAIT_MS)
    qtbot.waitUntil(lambda: len(read_sketch_file(autosave)[0].strokes) == 2, timeout=WAIT_MS)
    drawn = w.canvas.strokes()
    # "crash": the window goes away without the close dialog; the autosave stays
    w.force_close()
    assert autosave.is_file()
    dialogs.answers = [QMessageBox.StandardButton.Yes]
    w2 = make_window(FakeEngine())
    with qtbot.waitSignal(w2.meshUpdated, timeout=WAIT_MS):
        assert w2.offer_restore()
    assert dialogs.kinds() == ["question"]
    assert [s.points.tolist() for s in w2.canvas.strokes()] == [s.points.tolist() for s in drawn]
    assert w2.is_dirty and not w2.canvas.history.can_undo


def test_close_with_unsaved_work_asks_save_discard_cancel(qtbot, make_window, tmp_path, monkeypatch, dialogs):
    w = make_window(FakeEngine())
    draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    assert w.is_dirty
    dialogs.answers = [QMessageBox.StandardButton.Cancel]
    assert not w.close() and w.isVisible()
    target = tmp_path / "saved" / "drawing"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", staticmethod(lambda *a, **k: (str(target), "")))
    dialogs.answers = [QMessageBox.StandardButton.Save]
    assert w.close()
    saved = target.parent / "drawing.sketch.json"
    state, _ = read_sketch_file(saved)
    assert len(state.strokes) == 1
    png = QImage(str(target.parent / "drawing.png"))
    assert png.width() == w.canvas.width() and png.height() == w.canvas.height()
    assert not (tmp_path / "autosave" / AUTOSAVE_NAME).exists()  # saved: nothing to recover
    assert [k for k in dialogs.kinds()] == ["question", "question"]


def test_discard_on_close_removes_autosave_and_settings_persist(qtbot, make_window, tmp_path, dialogs):
    w = make_window(FakeEngine())
    w.width_spin.setValue(9.5)
    draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    assert w.canvas.strokes()[0].width == 9.5
    autosave = tmp_path / "autosave" / AUTOSAVE_NAME
    qtbot.waitUntil(autosave.is_file, timeout=WAIT_MS)
    dialogs.answers = [QMessageBox.StandardButton.Discard]
    assert w.close()
    assert not autosave.exists()
    saved = AppSettings.load()
    assert saved.geometry and saved.window_state and saved.brush_width == 9.5
    w2 = make_window(FakeEngine())
    assert w2.canvas.brush_width == 9.5 and w2.width_spin.value() == 9.5


def test_no_models_lets_the_user_draw_and_says_what_to_do(qtbot, make_window, tmp_path):
    empty = tmp_path / "no_models"
    empty.mkdir()
    w = make_window(engine_factory=None, models_dir=empty)
    assert w.engine is None
    assert no_models_message(empty) in w.status_text()
    assert "No models in" in no_models_message(empty) and "File > Load models..." in no_models_message(empty)
    draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    qtbot.wait(100)
    assert len(w.canvas.strokes()) == 1 and not w.viewport.has_mesh
    assert no_models_message(empty) in w.status_text()


def test_real_engine_on_fixture_models_and_engine_errors_in_status_bar(qtbot, make_window, tmp_path):
    models = write_fixture_models(tmp_path / "models")
    w = make_window(engine_factory=None, models_dir=models)
    assert w.engine is not None and "Model: models" in w.status_text()
    qtbot.waitUntil(lambda: w.engine.is_loaded, timeout=WAIT_MS)  # preloaded on the worker before any stroke
    _draw_and_wait(qtbot, w, line_points(60, 80, 300, 300))
    mesh = w.last_prediction.mesh
    assert mesh.num_vertices == 642
    assert np.abs(np.linalg.norm(mesh.vertices, axis=1) - 0.5).max() < 0.1  # fixture stays near the sphere
    assert "predictor" in w.status_text()
    # a broken model folder chosen later: the error shows, the working models stay in use
    working = w.engine
    empty = tmp_path / "empty"
    empty.mkdir()
    assert not w.load_models(empty)  # a wrong folder: say so, keep the working models
    assert w.engine is working and no_models_message(empty) in w.status_text() and "still using" in w.status_text()
    broken = tmp_path / "broken"
    broken.mkdir()
    for name in ("generator.onnx", "mesh_predictor.onnx"):
        (broken / name).write_bytes(b"not an onnx model")
    w.actions["clear"].trigger()
    with qtbot.waitSignal(w.modelsLoaded, timeout=WAIT_MS) as blocker:
        assert w.load_models(broken)  # loaded and validated on the worker before anything switches
    assert blocker.args[0] == str(broken) and "cannot load model" in blocker.args[1]
    assert f"Could not load models from {broken}" in w.status_text() and "still using" in w.status_text()
    assert w.engine is working
    _draw_and_wait(qtbot, w, line_points(60, 300, 300, 80))  # the working models still answer
    assert len(w.canvas.strokes()) == 1 and w.isVisible()
    # a good folder replaces them once its models are loaded (on the worker), and redoes the sketch
    other = write_fixture_models(tmp_path / "other_models")
    with qtbot.waitSignal(w.meshUpdated, timeout=WAIT_MS):
        assert w.load_models(other)
        assert w.engine is working and "Loading models from" in w.status_text()
    assert w.engine is not working and w.engine.is_loaded and "Model: other_models" in w.status_text()


def test_a_routed_model_folder_says_what_it_read_the_drawing_as(qtbot, make_window, tmp_path):
    """A folder with a router: the mesh comes from the specialist it picks, and the status bar says so."""
    from onnx_fixtures import make_predictor, make_router, write_model

    models = write_fixture_models(tmp_path / "models")
    write_model(make_predictor(3, seed=7), models / "mesh_predictor_legged.onnx")
    write_model(make_router([0.02, 0.03, 0.95]), models / "router.onnx")
    w = make_window(engine_factory=None, models_dir=models)
    _draw_and_wait(qtbot, w, line_points(60, 80, 300, 300))
    assert w.last_prediction.route == "mesh_predictor_legged.onnx"
    assert "read as chair, shaped by mesh_predictor_legged.onnx" in w.status_text()


def test_keyboard_shortcuts_undo_redo(qtbot, make_window):
    w = make_window(FakeEngine())
    draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    with qtbot.waitActive(w, timeout=5000):
        w.activateWindow()
    assert w.canvas.hasFocus()  # not the brush-width box, which would take Ctrl+Z for itself
    QTest.keyClick(w.canvas, Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier)
    qtbot.waitUntil(lambda: w.canvas.strokes() == (), timeout=2000)
    QTest.keyClick(w.canvas, Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier | Qt.KeyboardModifier.ShiftModifier)
    qtbot.waitUntil(lambda: len(w.canvas.strokes()) == 1, timeout=2000)


# ------------------------------------------------------------------ the headless CLI


def _cli(args, tmp_path, timeout=120):
    env = dict(os.environ)
    env["XDG_CONFIG_HOME"] = str(tmp_path / "cfg")
    env["XDG_DATA_HOME"] = str(tmp_path / "data")
    return subprocess.run([sys.executable, "-m", "sketchmesh", *args], capture_output=True, text=True, cwd=ROOT, env=env, timeout=timeout)


def _sketch_png(path: Path) -> Path:
    arr = np.full((200, 200), 255, np.uint8)
    yy, xx = np.mgrid[:200, :200]
    arr[np.abs(np.hypot(yy - 100, xx - 100) - 60) < 2] = 0
    QImage(arr.data, 200, 200, 200, QImage.Format.Format_Grayscale8).copy().save(str(path))
    return path


def test_cli_screenshot_end_to_end_and_failures(tmp_path):
    models = write_fixture_models(tmp_path / "models")
    sketch = _sketch_png(tmp_path / "circle.png")
    out = tmp_path / "shot.png"
    r = _cli(["--open", str(sketch), "--screenshot", str(out), "--models", str(models)], tmp_path)
    assert r.returncode == 0, r.stderr
    img = QImage(str(out))
    assert not img.isNull() and img.width() >= 1000
    arr = _qimage_to_array(img)
    assert _non_background_pixels(arr[:, arr.shape[1] // 2 :]) > NOT_BLANK_MIN_PIXELS
    assert not (tmp_path / "data").exists() or not list((tmp_path / "data").rglob(AUTOSAVE_NAME))
    # failures: one line on stderr, non-zero exit, no traceback
    corrupt = tmp_path / "corrupt.png"
    corrupt.write_bytes(b"\x89PNG\r\n\x1a\ngarbage")
    cases = [
        (["--open", str(corrupt), "--screenshot", str(tmp_path / "x.png"), "--models", str(models)], "corrupt.png"),
        (["--open", str(tmp_path / "missing.png"), "--screenshot", str(tmp_path / "x.png")], "no such file"),
        (["--open", str(sketch), "--screenshot", str(tmp_path / "x.png"), "--models", str(tmp_path)], "No models in"),
        (["--screenshot", str(tmp_path / "x.png")], "--open"),
    ]
    for args, needle in cases:
        r = _cli(args, tmp_path)
        assert r.returncode != 0, args
        lines = [ln for ln in r.stderr.strip().splitlines() if ln.startswith("sketchmesh:")]
        assert len(lines) == 1 and needle in lines[0], r.stderr
        assert "Traceback" not in r.stderr
        assert not (tmp_path / "x.png").exists()


def test_viewport_renders_only_when_visible_and_changed(qtbot, make_window):
    w = make_window(FakeEngine())
    vp = w.viewport
    _draw_and_wait(qtbot, w, line_points(60, 80, 300, 300))
    qtbot.waitUntil(lambda: vp.idle, timeout=WAIT_MS)
    n = vp.render_count
    vp.render_now()  # nothing changed: no render
    assert vp.idle and vp.render_count == n
    vp.hide()
    _draw_and_wait(qtbot, w, line_points(60, 300, 300, 80))
    qtbot.wait(50)
    assert vp.render_count == n and vp.mesh_updates == 2  # updated data, no render while hidden
    vp.show()
    qtbot.waitUntil(lambda: vp.render_count == n + 1, timeout=5000)
    with pytest.raises(ValueError, match="preset"):
        vp.set_view("bottom")
    w.actions["wireframe"].trigger()
    assert vp.wireframe and w.settings.wireframe
    assert vp.sync() and vp.representation == 1  # VTK_WIREFRAME, as rendered
    w.actions["wireframe"].trigger()
    assert vp.sync() and vp.representation == 2  # VTK_SURFACE


def test_viewport_renders_on_its_own_thread_and_orbits_and_zooms_with_the_mouse(qtbot, make_window):
    w = make_window(FakeEngine())
    vp = w.viewport
    _draw_and_wait(qtbot, w, line_points(60, 80, 300, 300))
    assert vp._scene.thread() is not QApplication.instance().thread()  # VTK never runs on the UI thread
    pos0, focal0, _ = vp.camera_position()
    c = vp.rect().center()
    QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, c)
    for dx in range(10, 90, 10):
        QTest.mouseMove(vp, c + QPoint(dx, dx // 4))
    QTest.mouseRelease(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, c + QPoint(80, 20))
    pos1, focal1, _ = vp.camera_position()
    assert np.linalg.norm(np.subtract(pos1, pos0)) > 0.1  # orbited
    np.testing.assert_allclose(np.linalg.norm(np.subtract(pos1, focal1)), np.linalg.norm(np.subtract(pos0, focal0)), rtol=1e-3)
    wheel = QWheelEvent(QPointF(c), QPointF(vp.mapToGlobal(c)), QPoint(0, 0), QPoint(0, 120), Qt.MouseButton.NoButton,
                        Qt.KeyboardModifier.NoModifier, Qt.ScrollPhase.NoScrollPhase, False)
    QApplication.sendEvent(vp, wheel)
    pos2, focal2, _ = vp.camera_position()
    assert np.linalg.norm(np.subtract(pos2, focal2)) < np.linalg.norm(np.subtract(pos1, focal1))  # zoomed in
    vp.reset_view()
    np.testing.assert_allclose(vp.camera_position()[0], (0.0, 0.0, DEFAULT_DISTANCE), atol=1e-9)
    assert vp.step_ms["mesh_upload"] and vp.render_ms  # the UI-thread and render-thread steps are measured


def test_a_viewport_deleted_without_close_stops_its_render_thread(qtbot):
    from app.viewport import MeshViewport
    from engine.icosphere import icosphere

    vp = MeshViewport()
    vp.resize(200, 160)
    vp.show()
    qtbot.waitExposed(vp)
    vp.set_mesh(icosphere(2, 0.5))
    assert vp.sync() and vp.render_count >= 1
    thread = vp._thread
    vp.deleteLater()
    qtbot.waitUntil(thread.isFinished, timeout=5000)


_EXIT_SCRIPT = """
import sys
sys.path.insert(0, {tests!r})
from gui_helpers import FakeEngine, fake_factory
from PySide6.QtWidgets import QApplication
from app.window import MainWindow
app = QApplication([sys.argv[0]])
w = MainWindow(engine_factory=fake_factory(FakeEngine()), autosave=False, persist_settings=False, debounce_ms=0)
w.wait_until_ready()
w.show()
app.processEvents()
if sys.argv[1] == "close":
    w.close()  # closed, never deleted: Python tears the wrappers down at exit
print("exiting", flush=True)
"""


@pytest.mark.parametrize("how", ["close", "leave_open"])
def test_a_script_exiting_with_the_window_closed_or_open_exits_cleanly(tmp_path, how):
    """Regression (issue 18): the viewport's destroyed-signal safety net ran at interpreter exit on
    a QThread wrapper Python had already deleted (RuntimeError traceback), and a window left open
    aborted the process (a running QThread destroyed)."""
    script = tmp_path / "exit_script.py"
    script.write_text(_EXIT_SCRIPT.format(tests=str(ROOT / "tests")))
    env = dict(os.environ, XDG_CONFIG_HOME=str(tmp_path / "cfg"), XDG_DATA_HOME=str(tmp_path / "data"))
    r = subprocess.run([sys.executable, str(script), how], capture_output=True, text=True, cwd=ROOT, env=env, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "exiting" in r.stdout
    for bad in ("Traceback", "RuntimeError", "already deleted", "Destroyed while thread"):
        assert bad not in r.stderr, r.stderr


def test_wait_until_ready_loads_models_and_shaders_before_the_window_shows(qtbot, tmp_path):
    w = MainWindow(engine_factory=fake_factory(FakeEngine()), autosave=False, persist_settings=False)
    try:
        assert w.wait_until_ready() and w.is_ready and w.viewport.ready and not w.controller.busy
    finally:
        w.force_close()
        w.deleteLater()


def test_live_updates_while_drawing_when_inference_is_fast(qtbot, make_window):
    eng = FakeEngine()
    w = make_window(eng)
    _draw_and_wait(qtbot, w, line_points(60, 80, 300, 300))  # measures the round trip
    assert w.controller.last_roundtrip_ms is not None
    shown = []
    w.meshUpdated.connect(lambda rid: shown.append(w.canvas.is_drawing))
    pts = [QPoint(int(x), int(y)) for x, y in line_points(60, 300, 300, 80, 20)]
    QTest.mousePress(w.canvas, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, pts[0])
    for p in pts[1:]:
        QTest.mouseMove(w.canvas, p)
        qtbot.wait(15)
    qtbot.waitUntil(lambda: any(shown), timeout=WAIT_MS)  # a mesh arrived before the pen lifted
    QTest.mouseRelease(w.canvas, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, pts[-1])
    qtbot.waitUntil(lambda: not w.controller.busy and len(shown) >= 2 and not shown[-1], timeout=WAIT_MS)
    assert len(eng.calls[-1]) == 2  # the final request holds the committed stroke


def test_save_and_reopen_sketch_document(qtbot, make_window, tmp_path, monkeypatch):
    w = make_window(FakeEngine())
    draw_stroke(w.canvas, line_points(60, 80, 300, 300))
    draw_stroke(w.canvas, line_points(60, 300, 300, 80))
    target = tmp_path / "doc.sketch.json"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", staticmethod(lambda *a, **k: (str(target), "")))
    w.actions["save"].trigger()
    assert target.is_file() and (tmp_path / "doc.png").is_file() and not w.is_dirty
    drawn = w.canvas.strokes()
    w.actions["clear"].trigger()
    assert w.is_dirty
    monkeypatch.setattr(QFileDialog, "getOpenFileName", staticmethod(lambda *a, **k: (str(target), "")))
    with qtbot.waitSignal(w.sketchOpened, timeout=WAIT_MS):
        w.actions["open"].trigger()
    assert [s.points.tolist() for s in w.canvas.strokes()] == [s.points.tolist() for s in drawn]
    assert not w.is_dirty and w.canvas.history.can_undo  # opening is undoable too
