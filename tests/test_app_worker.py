"""Live inference wiring: worker thread, debounce, request ids, stale dropping, latency.

A fake engine (tests/gui_helpers.py) with a controllable gate/delay tests the wiring; the
real engine on the fixture ONNX models (tests/onnx_fixtures.py) tests that results are right.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from gui_helpers import FakeEngine, gui_isolation, make_stroke
from onnx_fixtures import write_fixture_models
from PySide6.QtCore import QObject, QTimer, Signal

import app.worker
from app.canvas import BackgroundLayer, CanvasComposite
from app.jobs import JobQueue
from app.worker import (
    MAX_NICE,
    CanvasRaster,
    EventLoopLatencyProbe,
    InferenceController,
    InferenceWorker,
    lower_thread_priority,
    nice_from_env,
)
from engine.errors import ModelError, SketchmeshError
from engine.pipeline import Prediction, SketchEngine
from engine.preprocess import preprocess_raster

SLOW_INFERENCE_S = 0.3
UI_LAG_BUDGET_MS = 100.0
"""Largest event-loop lateness accepted while a 300 ms inference runs on the worker (a blocked
GUI thread shows ~300 ms; a loaded 2-core CI machine adds scheduling noise of tens of ms)."""


@pytest.fixture(autouse=True)
def dialogs(qapp, tmp_path, monkeypatch):
    """Isolated settings/autosave, recorded QMessageBox calls, leak check (tests/gui_helpers.py)."""
    with gui_isolation(tmp_path, monkeypatch) as recorder:
        yield recorder


@pytest.fixture
def controller(qtbot):
    made = []

    def make(engine, debounce_ms=20, **kw):
        c = InferenceController(engine, debounce_ms, **kw)
        made.append((c, engine))
        return c

    yield make
    for c, engine in made:
        if isinstance(engine, FakeEngine):
            engine.gate.set()
        assert c.shutdown(5000), "worker thread did not stop"


def _strokes(n):
    return [make_stroke([[10.0 * i, 0.0], [10.0 * i + 5, 5.0]]) for i in range(n)]


def test_prediction_runs_on_worker_thread_and_arrives_on_gui_thread(qtbot, controller):
    eng = FakeEngine()
    c = controller(eng)
    received = []
    c.predictionReady.connect(lambda rid, p: received.append((rid, p, threading.get_ident())))
    with qtbot.waitSignal(c.predictionReady, timeout=5000):
        rid = c.submit(_strokes(2))
    (got_rid, pred, tid), = received
    assert got_rid == rid
    assert tid == threading.get_ident()  # delivered on the GUI thread
    assert threading.get_ident() not in eng.thread_ids and len(eng.thread_ids) == 1  # ran elsewhere
    np.testing.assert_allclose(np.abs(pred.mesh.vertices).max(), 0.5 * (0.2 + 0.1 * 2), rtol=1e-5)
    assert pred.normals.shape == (256, 256, 3)


def test_stale_results_are_dropped_and_superseded_requests_skipped(qtbot, controller):
    eng = FakeEngine(gated=True)
    c = controller(eng, debounce_ms=10)
    shown = []
    c.predictionReady.connect(lambda rid, p: shown.append((rid, len(p.mesh.vertices), float(np.abs(p.mesh.vertices).max()))))
    a = c.submit(_strokes(1))
    assert eng.started.wait(5)  # A is running (blocked on the gate)
    b = c.submit(_strokes(2))  # queued behind A, superseded by C before it starts
    last = c.submit(_strokes(3))
    assert a < b < last == c.latest_id
    assert c.busy
    eng.gate.set()
    qtbot.waitUntil(lambda: not c.busy, timeout=5000)
    assert [s[0] for s in shown] == [last]  # only the newest result reaches the UI
    assert shown[0][2] == pytest.approx(0.5 * (0.2 + 0.3), rel=1e-5)
    assert c.dropped_count == 1 and c.skipped_count == 1
    assert [len(x) for x in eng.calls] == [1, 3]  # B never ran: work follows the latest change


def test_debounce_sends_the_first_change_at_once_and_coalesces_the_rest_of_a_burst(qtbot, controller):
    """After a pause the first change is sent within schedule() itself; the nine that follow it
    within the delay make one more request, sent the delay after the last of them, and only its
    mesh is shown. After another pause, the next change goes at once again."""
    eng = FakeEngine()
    c = controller(eng, debounce_ms=200)
    calls, shown = [], []
    c.predictionReady.connect(lambda rid, p: shown.append(rid))

    def provider():
        calls.append(time.perf_counter())
        return _strokes(len(calls))

    c.schedule(provider)
    first = c.latest_id
    assert len(calls) == 1 and c.busy  # sent at once: the sketch had been quiet
    t_last = None
    for _ in range(9):
        t_last = time.perf_counter()  # before the call: the timer restarts inside it, so no earlier
        c.schedule(provider)
    assert len(calls) == 1  # the rest wait for the delay
    qtbot.waitUntil(lambda: not c.busy, timeout=5000)
    # one more, the delay after the last change (a precise timer: never early; Qt counts whole ms)
    assert len(calls) == 2 and calls[1] - t_last >= 0.199
    assert shown == [c.latest_id] and c.latest_id > first
    qtbot.wait(250)  # a pause longer than the delay
    c.schedule(provider)
    assert len(calls) == 3
    qtbot.waitUntil(lambda: not c.busy, timeout=5000)
    assert shown[-1] == c.latest_id


def test_empty_sketch_clears_and_drops_the_running_request(qtbot, controller):
    eng = FakeEngine(gated=True)
    c = controller(eng)
    ready = []
    c.predictionReady.connect(lambda rid, p: ready.append(rid))
    c.submit(_strokes(1))
    assert eng.started.wait(5)
    with qtbot.waitSignal(c.cleared, timeout=2000):
        c.submit(None)
    with qtbot.waitSignal(c.cleared, timeout=2000):
        c.submit([])
    eng.gate.set()
    qtbot.waitUntil(lambda: not c.busy, timeout=5000)
    assert ready == [] and c.dropped_count == 1


def test_engine_errors_become_messages_and_the_worker_survives(qtbot, controller):
    eng = FakeEngine()
    c = controller(eng)
    eng.error = ModelError("generator.onnx: corrupt model")
    with qtbot.waitSignal(c.predictionFailed, timeout=5000) as blocker:
        c.submit(_strokes(1))
    assert blocker.args[1] == "generator.onnx: corrupt model"
    eng.error = ZeroDivisionError("boom")
    with qtbot.waitSignal(c.predictionFailed, timeout=5000) as blocker:
        c.submit(_strokes(1))
    assert blocker.args[1] == "ZeroDivisionError: boom"
    eng.error = None
    with qtbot.waitSignal(c.predictionReady, timeout=5000):
        c.submit(_strokes(1))
    c.set_engine(None)
    with qtbot.waitSignal(c.predictionFailed, timeout=2000) as blocker:
        c.submit(_strokes(1))
    assert "Load models" in blocker.args[1]


def test_event_loop_stays_responsive_during_slow_inference(qtbot, controller):
    """The probe measures real lateness: ~0 with inference on the worker, ~300 ms when the GUI blocks."""
    eng = FakeEngine(delay_s=SLOW_INFERENCE_S)
    c = controller(eng)
    probe = EventLoopLatencyProbe(10)
    probe.start()
    with qtbot.waitSignal(c.predictionReady, timeout=5000):
        c.submit(_strokes(2))
    probe.stop()
    assert len(probe.samples_ms) >= 10  # it ticked throughout
    assert probe.max_ms < UI_LAG_BUDGET_MS, f"GUI lagged {probe.max_ms:.0f} ms while inference ran"
    # control: the same work on the GUI thread is seen by the probe
    probe.start()
    QTimer.singleShot(20, lambda: time.sleep(SLOW_INFERENCE_S))
    qtbot.wait(int(SLOW_INFERENCE_S * 1000) + 150)
    probe.stop()
    assert probe.max_ms >= 0.8 * SLOW_INFERENCE_S * 1000
    assert probe.percentile_ms(50) < probe.max_ms


def test_shutdown_is_cooperative(qtbot):
    eng = FakeEngine(gated=True)
    c = InferenceController(eng, 10)
    c.submit(_strokes(1))
    assert eng.started.wait(5)
    c.submit(_strokes(2))  # queued: skipped on shutdown
    threading.Timer(0.2, eng.gate.set).start()
    t0 = time.perf_counter()
    assert c.shutdown(5000)
    assert time.perf_counter() - t0 < 3.0
    assert len(eng.calls) == 1
    with pytest.raises(RuntimeError, match="shut down"):
        c.submit(_strokes(1))


def test_real_engine_on_fixture_models(qtbot, controller, tmp_path):
    models = write_fixture_models(tmp_path / "models")
    eng = SketchEngine(models, threads=1)
    c = controller(eng)
    strokes = [make_stroke([[20.0, 20.0], [120.0, 40.0], [80.0, 160.0]]), make_stroke([[30.0, 150.0], [150.0, 150.0]])]
    with qtbot.waitSignal(c.predictionReady, timeout=30000) as blocker:
        c.submit(strokes)
    pred = blocker.args[1]
    direct = eng.predict(strokes, want_normals=True)  # same engine, same input, on this thread
    assert pred.mesh.num_vertices == 642 and pred.mesh.num_faces == 1280
    np.testing.assert_array_equal(pred.mesh.vertices, direct.mesh.vertices)
    assert pred.normals.shape == (256, 256, 3) and np.all((pred.normals >= 0) & (pred.normals <= 1))
    # a canvas composite is framed on the worker exactly like preprocess_raster does
    ink = np.zeros((200, 300), np.float32)
    ink[50:150, 100:104] = 1.0
    ink[98:102, 60:250] = 1.0
    with qtbot.waitSignal(c.predictionReady, timeout=30000) as blocker:
        c.submit(CanvasRaster(ink))
    np.testing.assert_array_equal(blocker.args[1].sketch, preprocess_raster(ink))
    np.testing.assert_array_equal(blocker.args[1].mesh.vertices, eng.predict(preprocess_raster(ink)).mesh.vertices)


def test_shutdown_timeout_keeps_the_running_thread_alive(qtbot):
    eng = FakeEngine(gated=True)
    c = InferenceController(eng, 10)
    c.submit(_strokes(1))
    assert eng.started.wait(5)
    assert not c.shutdown(50)  # still running: reported, not destroyed
    import app.worker as worker_module

    assert any(t is c._thread for t, _ in worker_module._ORPHANS)
    eng.gate.set()
    qtbot.waitUntil(lambda: not worker_module._ORPHANS, timeout=5000)


class _Pinger(QObject):
    ping = Signal()


def test_signal_emit_does_not_leak_references_to_true():
    """PySide6 6.12.0 on CPython < 3.12 steals a reference to True on every Python emit(), so a
    drawing session aborts in bool_dealloc; pyproject pins PySide6 below 6.12 for that reason."""
    p = _Pinger()
    n = 2000
    rc0 = sys.getrefcount(True)
    for _ in range(n):
        p.ping.emit()
    assert abs(rc0 - sys.getrefcount(True)) < 50


def test_preload_loads_on_the_worker_and_reports_broken_models(qtbot, controller):
    class Loading(FakeEngine):
        def load(self):
            self.thread_ids.add(threading.get_ident())
            if self.error is not None:
                raise self.error
            self.loaded = True

    eng = Loading()
    c = controller(eng)
    c.preload()
    qtbot.waitUntil(lambda: getattr(eng, "loaded", False) and not c.busy, timeout=5000)
    assert threading.get_ident() not in eng.thread_ids and eng.calls == []
    eng.error = ModelError("mesh_predictor.onnx: not an ONNX model")
    with qtbot.waitSignal(c.predictionFailed, timeout=5000) as blocker:
        c.preload()
    assert blocker.args[1] == "mesh_predictor.onnx: not an ONNX model"
    assert not c.busy


def test_load_engine_loads_a_candidate_on_the_worker_and_keeps_the_engine_in_use(qtbot, controller):
    class Loading(FakeEngine):
        def load(self):
            self.thread_ids.add(threading.get_ident())
            if self.error is not None:
                raise self.error
            self.loaded = True

    old, new = FakeEngine(), Loading()
    c = controller(old)
    loaded = []
    c.engineLoaded.connect(lambda token, engine: loaded.append((token, engine)))
    with qtbot.waitSignals([c.engineLoaded, c.predictionReady], timeout=5000):
        token = c.load_engine(new)
        assert c.loading and c.busy
        c.submit(_strokes(1))  # a stroke drawn while the load runs: answered, and the load not cancelled
    assert loaded == [(token, new)] and c.engine is old  # loaded, not switched to
    assert len(old.calls) == 1 and new.calls == [] and getattr(new, "loaded", False)
    assert threading.get_ident() not in new.thread_ids and not c.busy
    broken = Loading()
    broken.error = ModelError("generator.onnx: model role is 'predictor', expected 'generator' (files swapped?)")
    with qtbot.waitSignal(c.engineLoadFailed, timeout=5000) as blocker:
        token = c.load_engine(broken)
    assert blocker.args == [token, str(broken.error)] and c.engine is old and not c.busy
    loaded.clear()
    first, second = Loading(), Loading()
    with qtbot.waitSignal(c.engineLoaded, timeout=5000):
        c.load_engine(first)
        c.load_engine(second)
    qtbot.wait(50)
    assert [e for _, e in loaded] == [second] and getattr(first, "loaded", False) and not c.busy  # the older answer is dropped


def test_composite_framing_and_thumbnails_happen_on_the_worker(qtbot, controller, tmp_path):
    models = write_fixture_models(tmp_path / "models")
    eng = SketchEngine(models, threads=1)
    c = controller(eng, thumbnail_size=100)
    ink = np.zeros((80, 120), np.float32)
    ink[20:60, 30:34] = 1.0
    comp = CanvasComposite((make_stroke([[20.0, 150.0], [260.0, 40.0]]),), BackgroundLayer(ink, (30.0, 20.0, 240.0, 160.0)),
                           (300, 200), (300, 200))
    with qtbot.waitSignal(c.predictionReady, timeout=30000) as blocker:
        c.submit(comp)
    rid, pred = blocker.args
    np.testing.assert_array_equal(pred.sketch, preprocess_raster(comp.render()))
    thumbs = c.take_thumbnails(rid)
    assert thumbs.sketch.width() == 100 and thumbs.normals.width() == 100  # made on the worker, fitted
    assert c.take_thumbnails(rid) is None  # handed out once


def test_job_queue_runs_in_order_off_the_gui_thread_and_reports_errors(qtbot, tmp_path):
    q = JobQueue("test-jobs")
    ran, threads, results, errors = [], set(), [], []

    def job(i):
        threads.add(threading.get_ident())
        time.sleep(0.005 * (5 - i))  # later jobs are quicker: order must still hold
        ran.append(i)
        return i * i

    for i in range(5):
        q.submit(lambda i=i: job(i), results.append, errors.append)
    q.submit(lambda: (tmp_path / "missing" / "x.txt").write_text("x"), results.append, errors.append)
    q.submit(lambda: 1 / 0, results.append, errors.append)
    assert q.wait(10_000)
    qtbot.waitUntil(lambda: q.pending == 0, timeout=5000)
    assert ran == [0, 1, 2, 3, 4] and results == [0, 1, 4, 9, 16]
    assert threading.get_ident() not in threads
    assert "No such file" in errors[0] and errors[1].startswith("ZeroDivisionError")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread nice values are Linux's")
def test_lower_thread_priority_affects_only_the_calling_thread():
    import os

    main_nice = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    seen = []

    def run():
        seen.append(lower_thread_priority(7))
        seen.append(os.getpriority(os.PRIO_PROCESS, threading.get_native_id()))

    t = threading.Thread(target=run)
    t.start()
    t.join(5)
    assert seen[0] is True and seen[1] >= 7
    assert os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == main_nice
    assert lower_thread_priority(0) is False


def test_nice_values_from_the_environment(monkeypatch):
    monkeypatch.delenv("SKETCHMESH_TEST_NICE", raising=False)
    assert nice_from_env("SKETCHMESH_TEST_NICE", 4) == 4
    for text, want in (("0", 0), (" 7 ", 7), (str(MAX_NICE), MAX_NICE), ("", 4)):
        monkeypatch.setenv("SKETCHMESH_TEST_NICE", text)
        assert nice_from_env("SKETCHMESH_TEST_NICE", 4) == want
    for bad in ("-1", "20", "low", "2.5"):
        monkeypatch.setenv("SKETCHMESH_TEST_NICE", bad)
        with pytest.raises(SketchmeshError, match=f"SKETCHMESH_TEST_NICE must be a whole number .* got '{re.escape(bad)}'"):
            nice_from_env("SKETCHMESH_TEST_NICE", 4)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread nice values are Linux's")
@pytest.mark.parametrize("nice", [0, 6])
def test_the_worker_runs_inference_at_the_configured_nice_value(qtbot, controller, monkeypatch, nice):
    # 0 (the default) leaves the worker at the app's priority: a higher value hands inference to any other
    # process on a busy machine (reproduce_models.sh session-nice)
    import os

    monkeypatch.setattr(app.worker, "WORKER_NICE", nice)
    seen = []

    class Recording(FakeEngine):
        def predict(self, sketch, **kw):
            seen.append(os.getpriority(os.PRIO_PROCESS, threading.get_native_id()))
            return super().predict(sketch, **kw)

    main_nice = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    c = controller(Recording())
    with qtbot.waitSignal(c.predictionReady, timeout=5000):
        c.submit(_strokes(1))
    assert seen == [max(main_nice, nice)]


def test_a_bad_nice_value_is_a_clear_error_from_the_command_line(tmp_path):
    for name in ("SKETCHMESH_WORKER_NICE", "SKETCHMESH_RENDER_NICE"):
        r = subprocess.run([sys.executable, "-m", "sketchmesh", "--report", str(tmp_path / "r.json")],
                           capture_output=True, text=True, cwd=tmp_path, timeout=120,
                           env={**os.environ, name: "high", "QT_QPA_PLATFORM": "offscreen"})
        lines = [ln for ln in r.stderr.strip().splitlines() if ln.startswith("sketchmesh:")]
        assert r.returncode != 0 and "Traceback" not in r.stderr, r.stderr
        assert len(lines) == 1 and f"{name} must be a whole number" in lines[0], r.stderr
        assert not (tmp_path / "r.json").exists()


class _RefiningEngine(FakeEngine):
    """A FakeEngine whose outline refinement is on: records each call's ``refine`` and, after the networks' call,
    runs ``on_networks`` (a newer drawing arriving meanwhile); the refined call's refine stage takes 7 ms."""

    refine_steps = 3

    def __init__(self, on_networks=None) -> None:
        super().__init__()
        self.refines: list[object] = []
        self.on_networks = on_networks

    def predict(self, sketch, *, want_normals=False, refine=None):
        self.refines.append(refine)
        p = super().predict(sketch, want_normals=want_normals)
        if refine == 0:
            if self.on_networks is not None:
                self.on_networks()
            return p
        return Prediction(p.mesh, p.normals, p.sketch, {**dict.fromkeys(p.timings_ms, 0.0), "refine": 7.0}, True)


def _worker_answers(worker: InferenceWorker) -> dict[str, list]:
    seen: dict[str, list] = {"preview": [], "result": [], "skipped": []}
    worker.previewReady.connect(lambda i, r: seen["preview"].append((i, r[0])))
    worker.resultReady.connect(lambda i, r: seen["result"].append((i, r[0])))
    worker.skipped.connect(lambda i: seen["skipped"].append(i))
    return seen


def test_with_the_refinement_on_the_worker_answers_with_the_networks_mesh_first_then_the_refined_one(qapp):
    worker = InferenceWorker()
    seen = _worker_answers(worker)
    engine = _RefiningEngine()
    raster = np.zeros((256, 256), np.float32)
    worker.process(1, engine, raster)
    assert engine.refines == [0, 3]  # the networks' call, then the refining one (its networks from the cache)
    assert [i for i, _ in seen["preview"]] == [1] and [i for i, _ in seen["result"]] == [1] and seen["skipped"] == []
    final = seen["result"][0][1]
    # the networks' stages as they ran for the preview, the refinement's time from the second call, not "cached"
    assert final.timings_ms["generator"] == 1.0 and final.timings_ms["refine"] == 7.0 and final.cached is False


def test_a_drawing_superseded_during_its_preview_is_not_refined(qapp):
    worker = InferenceWorker()
    seen = _worker_answers(worker)
    engine = _RefiningEngine(on_networks=lambda: worker.note_latest(2))
    worker.process(1, engine, np.zeros((256, 256), np.float32))
    assert engine.refines == [0]  # no refinement of a drawing already replaced
    assert [i for i, _ in seen["preview"]] == [1] and seen["result"] == [] and seen["skipped"] == [1]
