"""The scripted session behind ``sketchmesh --open SKETCH --report JSON``: it plays its plan on
the real window with real mouse and key events and writes a report with sane values.

No timing is asserted (the lag targets are printed by the benchmark, never tested): only
that the figures exist, are ordered and non-negative, and that every step really happened.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from gui_helpers import gui_isolation
from onnx_fixtures import write_fixture_models
from PySide6.QtGui import QImage

from app.canvas import guide_rect
from app.session import LAG_TARGETS_MS, SessionPlan, eraser_paths, format_report, run_session, stroke_paths
from app.viewport import VIEW_PRESETS
from engine.pipeline import STAGES

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def dialogs(qapp, tmp_path, monkeypatch):
    """Isolated settings/autosave, recorded QMessageBox calls, leak check (tests/gui_helpers.py)."""
    with gui_isolation(tmp_path, monkeypatch) as recorder:
        yield recorder


def _sketch_png(path: Path) -> Path:
    arr = np.full((200, 240), 255, np.uint8)
    yy, xx = np.mgrid[:200, :240]
    arr[np.abs(np.hypot(yy - 100, xx - 120) - 70) < 2] = 0  # a ring
    arr[96:100, 40:200] = 0  # and a bar
    assert QImage(arr.data, 240, 200, 240, QImage.Format.Format_Grayscale8).copy().save(str(path))
    return path


def _check_figures(d: dict, keys: tuple[str, ...]) -> None:
    assert set(keys) <= set(d), d
    vals = [d[k] for k in keys]
    assert all(np.isfinite(v) and v >= 0 for v in vals), d
    assert vals == sorted(vals), f"percentiles out of order: {d}"


def _check_report(r: dict, plan: SessionPlan, export: Path) -> None:
    assert r["error"] is None and not r["failures"], r["error"]
    assert (r["strokes"], r["undo"], r["redo"], r["erase"]) == (plan.strokes, plan.undo, plan.redo, plan.erase)
    assert r["views"] == list(plan.views)
    _check_figures(r["lag_ms"], ("p50", "p99", "max"))
    assert r["lag_ms"]["interval_ms"] == 5 and r["lag_ms"]["count"] > 100
    assert r["lag_targets_ms"] == LAG_TARGETS_MS and isinstance(r["lag_targets_met"], bool)
    phases = r["lag_by_phase_ms"]  # every tick in one phase: the counts add up, the worst is the session's
    expected = ["open"] * (r["sketch"] is not None) + ["strokes", "undo", "redo", "erase", "views", "export"]
    assert [k for k in phases if k not in ("start", "end")] == expected
    for v in phases.values():
        _check_figures(v, ("p50", "p99", "max"))
    assert sum(v["count"] for v in phases.values()) == r["lag_ms"]["count"]
    assert max(v["max"] for v in phases.values()) == r["lag_ms"]["max"]
    assert "UI lag by phase" in format_report(r)
    _check_figures(r["pen_delay_ms"], ("p50", "p99", "max"))
    assert r["pen_delay_ms"]["count"] >= plan.strokes * 20  # every pen event was delivered and timed
    lat = r["stroke_latency_ms"]
    assert len(lat) == plan.strokes and all(v > 0 for v in lat)
    _check_figures(r["stroke_latency_summary_ms"], ("p50", "p95", "max"))
    assert r["meshes_shown"] >= plan.strokes + 1  # the opened sketch, then each stroke (at least)
    assert r["engine_ms"]["count"] >= 1 and r["render_thread_ms"]["count"] >= 1
    stages = r["engine_stages_ms"]  # every stage of every prediction, in pipeline order, adding up to engine_ms
    assert list(stages) == list(STAGES)
    for v in stages.values():
        _check_figures(v, ("p50", "p95", "max"))
        assert v["count"] == r["engine_ms"]["count"]
    assert sum(v["mean"] for v in stages.values()) == pytest.approx(r["engine_ms"]["mean"], rel=1e-3, abs=0.05)
    assert "engine stages, p50: " in format_report(r)
    if r["sketch"] is not None:  # the opened sketch is a background layer: every prediction renders a composite
        _check_figures(r["composite_ms"], ("p50", "p99", "max"))
        assert r["composite_ms"]["count"] >= plan.strokes and "canvas composite" in format_report(r)
    assert set(r["ui_steps_ms"]) == {"mesh_upload", "frame"}
    assert 0 < r["ui_thread_cpu_s"] < r["duration_s"]
    assert r["export"] == str(export) and r["export_bytes"] == export.stat().st_size > 0
    mesh = trimesh.load(export, force="mesh", process=False)
    assert len(mesh.faces) == 1280
    assert "UI lag" in format_report(r)


def test_session_plays_its_plan_and_reports(tmp_path):
    models = write_fixture_models(tmp_path / "models")
    plan = SessionPlan(strokes=3, undo=2, redo=1, erase=2, views=("front", "iso"))
    report, shot = tmp_path / "run" / "report.json", tmp_path / "run" / "shot.png"
    report.parent.mkdir()
    assert run_session(str(_sketch_png(tmp_path / "ring.png")), str(report), str(shot), str(models), plan) == 0
    r = json.loads(report.read_text())
    _check_report(r, plan, report.with_suffix(".glb"))
    assert r["erases_that_cut"] >= 1  # the sweeps cross the strokes
    img = QImage(str(shot))
    assert not img.isNull() and img.width() >= 1000
    assert not list(tmp_path.glob("**/autosave.sketch.json"))  # the session's autosave stays in its temp folder


def test_cli_report_plays_the_documented_session(tmp_path):
    """The full default plan through the command line: 20 strokes, 5 undo, 5 redo, 3 erase, every view, one export."""
    models = write_fixture_models(tmp_path / "models")
    report = tmp_path / "session.json"
    env = dict(os.environ, XDG_CONFIG_HOME=str(tmp_path / "cfg"), XDG_DATA_HOME=str(tmp_path / "data"),
               SKETCHMESH_WORKER_NICE="2", SKETCHMESH_RENDER_NICE="0")  # the report says what the threads ran at
    cmd = [sys.executable, "-m", "sketchmesh", "--open", str(_sketch_png(tmp_path / "ring.png")), "--report", str(report),
           "--models", str(models)]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "UI lag (event-loop delay" in r.stdout and "pen up -> mesh on screen" in r.stdout
    _check_report(json.loads(report.read_text()), SessionPlan(), tmp_path / "session.glb")
    assert json.loads(report.read_text())["nice"] == {"worker": 2, "render": 0}
    # a broken request fails with one line, and writes nothing
    bad = subprocess.run([*cmd[:-2], "--models", str(tmp_path)], capture_output=True, text=True, cwd=ROOT, env=env, timeout=120)
    lines = [ln for ln in bad.stderr.strip().splitlines() if ln.startswith("sketchmesh:")]
    assert bad.returncode != 0 and len(lines) == 1 and "No models in" in lines[0], bad.stderr


def test_scripted_paths_are_deterministic_and_inside_the_guide():
    a, b = stroke_paths(600, 500, 20, seed=3), stroke_paths(600, 500, 20, seed=3)
    assert len(a) == 20 and all(np.array_equal(p, q) for p, q in zip(a, b))
    gx, gy, gw, gh = guide_rect(600, 500)
    for p in a + eraser_paths(600, 500, 3):
        assert p.shape[1] == 2 and np.all(p[:, 0] >= gx) and np.all(p[:, 0] <= gx + gw)
        assert np.all(p[:, 1] >= gy) and np.all(p[:, 1] <= gy + gh)


@pytest.mark.parametrize("kw, match", [
    ({"strokes": 0}, "strokes"),
    ({"strokes": 3, "undo": 4, "redo": 0}, "undo"),
    ({"undo": 2, "redo": 3}, "redo"),
    ({"erase": -1}, "erase"),
    ({"views": ("bottom",)}, "views"),
])
def test_session_plan_rejects_impossible_plans(kw, match):
    with pytest.raises(ValueError, match=match):
        SessionPlan(**kw)
    assert SessionPlan().views == VIEW_PRESETS
