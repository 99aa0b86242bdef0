"""SIGKILL in the middle of a write, then start again (issue 18, part 3).

The kill lands inside the write deterministically: ``SKETCHMESH_TEST_STALL_WRITE=NAME``
(:mod:`engine.fileio`) makes the atomic write of a file called ``NAME`` put half its bytes into
the temporary file, fsync, and sleep; the test waits for that half-written temporary file to
appear, then sends SIGKILL.

* training: the run is killed while it writes its third checkpoint; the resumed run continues
  from the second (the last complete one), deletes the half-checkpoint temporary file, and ends
  bit-identical (weights, BatchNorm statistics, Adam state) to a run that was never interrupted
  (mesh mode, for speed: tests/test_training_trainer.py shows resume is exact in joint mode too);
* the app: killed while it autosaves the third stroke; the next start offers the two strokes of
  the last complete autosave, exactly as drawn, and deletes the half-written temporary file.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from engine.fileio import STALL_ENV, STALL_SECONDS_ENV

ROOT = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent
TINY_FLAGS = ["--batch", "2", "--base-channels", "8", "--predictor-channels", "8", "--predictor-hidden", "32",
              "--predictor-latent", "16", "--template-level", "2", "--sobel-samples", "64", "--augment-strength", "0",
              "--quiet", "--threads", "2", "--val-every", "0", "--plot-every", "0", "--device", "cpu", "--extra-views", "1"]
KILL_WAIT_S = 120.0
"""Longest wait for the stalled write to start (torch or Qt imports included) before the test fails."""


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except FileNotFoundError:  # an ordinary write renamed it away meanwhile
        return 0


def _kill_when_half_written(proc: subprocess.Popen, folder: Path, name: str, armed=lambda: True) -> Path:
    """Once ``armed()``, wait until ``folder`` holds a non-empty temporary file of ``name``, then SIGKILL ``proc``.

    ``armed`` says the stall hook is set, so the temporary file seen is the stalled write's and not
    an ordinary write's passing through.
    """
    deadline = time.monotonic() + KILL_WAIT_S
    try:
        while time.monotonic() < deadline:
            ready = armed() and folder.is_dir()
            tmp = [p for p in folder.glob(f".{name}.*.tmp") if _size(p) > 0] if ready else []
            if tmp:
                os.kill(proc.pid, signal.SIGKILL)
                proc.wait(timeout=30)
                return tmp[0]
            if proc.poll() is not None:
                out = proc.stdout.read().decode(errors="replace") if proc.stdout else ""
                pytest.fail(f"the process ended (exit {proc.returncode}) before its write stalled: {out[-3000:]}")
            time.sleep(0.02)
        pytest.fail(f"no half-written .{name}.*.tmp in {folder} after {KILL_WAIT_S} s")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=30)


# ------------------------------------------------------------------------------------------- training


def test_sigkill_during_a_checkpoint_write_then_resume_is_bit_identical(tmp_path):
    torch = pytest.importorskip("torch")
    from synthetic_data import write_synthetic_dataset

    from sketchmesh.cli import main
    from training.loop.checkpoint import checkpoint_paths, load_checkpoint_file, load_latest_checkpoint

    data = write_synthetic_dataset(tmp_path / "data", categories=("blob",), splits=("train", "train"), views=2)
    flags = ["--data", str(data), "--iters", "4", "--ckpt-every", "1", "--log-every", "1", *TINY_FLAGS]
    killed = tmp_path / "killed"
    env = os.environ | {STALL_ENV: "ckpt_00000003.pt", STALL_SECONDS_ENV: "600", "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "sketchmesh", "train", "mesh", *flags, "--out", str(killed)],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    half = _kill_when_half_written(proc, killed / "checkpoints", "ckpt_00000003.pt")
    assert proc.returncode == -signal.SIGKILL
    assert half.exists() and half.stat().st_size > 10_000  # the torn write is there, half a checkpoint
    assert [p.name for p in checkpoint_paths(killed)] == ["ckpt_00000002.pt", "ckpt_00000001.pt"]

    assert main(["train", "mesh", *flags, "--out", str(killed)]) == 0  # resume, in this process
    assert not list(killed.rglob("*.tmp")), "the half-written checkpoint was not cleaned up"
    assert "resumed from" in (killed / "events.log").read_text() and "iteration 2" in (killed / "events.log").read_text()
    straight = tmp_path / "straight"
    assert main(["train", "mesh", *flags, "--out", str(straight)]) == 0  # never interrupted

    a, b = load_latest_checkpoint(straight), load_latest_checkpoint(killed)
    assert a["iteration"] == b["iteration"] == 4
    for group in ("models", "optimizers"):
        flat_a, flat_b = _flatten(a[group]), _flatten(b[group])
        assert flat_a.keys() == flat_b.keys()
        for key, va in flat_a.items():
            vb = flat_b[key]
            if isinstance(va, torch.Tensor):
                assert torch.equal(va, vb), f"{group} {key} differs by {float((va.double() - vb.double()).abs().max())}"
            else:
                assert va == vb, f"{group} {key}: {va} != {vb}"
    assert load_checkpoint_file(checkpoint_paths(killed)[0])["iteration"] == 4


def _flatten(tree, prefix: str = "") -> dict:
    if isinstance(tree, dict):
        out = {}
        for k, v in tree.items():
            out.update(_flatten(v, f"{prefix}/{k}"))
        return out
    if isinstance(tree, (list, tuple)):
        out = {}
        for i, v in enumerate(tree):
            out.update(_flatten(v, f"{prefix}[{i}]"))
        return out
    return {prefix: tree}


# ------------------------------------------------------------------------------------------- the app

_APP_DRIVER = r"""
import json, os, sys, time
from pathlib import Path
autosave_dir, log_path = Path(sys.argv[1]), Path(sys.argv[2])
sys.path.insert(0, sys.argv[3])
from PySide6.QtWidgets import QApplication
app = QApplication([])
from gui_helpers import FakeEngine, draw_stroke, fake_factory, line_points
from app.autosave import AUTOSAVE_NAME, read_sketch_file
from app.window import MainWindow
w = MainWindow(engine_factory=fake_factory(FakeEngine()), autosave_dir=autosave_dir, persist_settings=False,
               debounce_ms=10)
w.resize(1000, 620)
w.show()
path = autosave_dir / AUTOSAVE_NAME

def wait_for(done, timeout=60.0):
    end = time.monotonic() + timeout
    while not done():
        if time.monotonic() > end:
            sys.exit(f"timed out waiting in the driver")
        app.processEvents()
        time.sleep(0.01)

def saved(n):
    try:
        return path.is_file() and len(read_sketch_file(path)[0].strokes) == n
    except Exception:
        return False

for i in range(2):
    draw_stroke(w.canvas, line_points(60 + 30 * i, 80, 300, 300 - 40 * i))
    wait_for(lambda: saved(i + 1))
log_path.write_text(json.dumps([[s.points.tolist(), s.width] for s in w.canvas.strokes()]))
os.environ["SKETCHMESH_TEST_STALL_WRITE"] = AUTOSAVE_NAME  # the next autosave stalls half-written
draw_stroke(w.canvas, line_points(200, 60, 80, 320))
wait_for(lambda: False, timeout=600)  # keep the event loop alive until the test kills us
"""


def test_sigkill_during_an_autosave_then_restart_offers_the_last_autosave(tmp_path, qtbot, monkeypatch):
    pytest.importorskip("PySide6")
    from gui_helpers import FakeEngine, fake_factory, gui_isolation
    from PySide6.QtWidgets import QMessageBox

    from app.autosave import AUTOSAVE_NAME
    from app.window import MainWindow

    autosave_dir, log = tmp_path / "autosave", tmp_path / "drawn.json"
    env = os.environ | {"XDG_CONFIG_HOME": str(tmp_path / "config"), "XDG_DATA_HOME": str(tmp_path / "share"),
                        STALL_SECONDS_ENV: "600", "PYTHONPATH": str(ROOT)}
    env.pop(STALL_ENV, None)
    proc = subprocess.Popen([sys.executable, "-c", _APP_DRIVER, str(autosave_dir), str(log), str(TESTS)],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    half = _kill_when_half_written(proc, autosave_dir, AUTOSAVE_NAME, armed=log.is_file)
    assert proc.returncode == -signal.SIGKILL
    assert half.exists() and log.is_file()
    drawn = json.loads(log.read_text())
    assert len(drawn) == 2

    (tmp_path / "next").mkdir()
    with gui_isolation(tmp_path / "next", monkeypatch) as dialogs:
        dialogs.answers = [QMessageBox.StandardButton.Yes]
        w = MainWindow(engine_factory=fake_factory(FakeEngine()), autosave_dir=autosave_dir, persist_settings=False,
                       debounce_ms=10)
        try:
            w.show()
            qtbot.waitExposed(w)
            assert w.offer_restore()  # the next start offers the last complete autosave ...
            assert dialogs.kinds() == ["question"]
            restored = [[s.points.tolist(), s.width] for s in w.canvas.strokes()]
            assert restored == drawn  # ... with every stroke as drawn, none corrupted
            qtbot.waitUntil(lambda: bool(w.autosaver.stale_removed), timeout=5000)  # ... and deletes the
            assert w.autosaver.stale_removed == [half] and not half.exists()  # killed write's temporary file
            assert not list(autosave_dir.glob(f".{AUTOSAVE_NAME}.*.tmp"))
        finally:
            w.force_close()
            w.deleteLater()
