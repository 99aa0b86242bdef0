"""Draw the app-made sample sketches of ``assets/samples/`` through the app's own canvas.

Usage (needs a display; under CI or a server use ``xvfb-run``)::

    python tests/draw_samples.py assets/samples

Each sample is a list of strokes in the sketch view the models were trained for (30 degrees
above, 45 degrees to the side). The strokes are *scripted*, not drawn by a person: every stroke
is pressed, moved and released with mouse events on the real :class:`app.window.MainWindow`
canvas, with hand-like wobble, overshoot at corners and the odd gap, and saved with the app's
"Save sketch" (``.sketch.json`` + PNG). They show what a mouse drawing in the app looks like
to the models; the rendered test-split sketches beside them show the training distribution.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))


def _box(cx, cy, w, h, d):
    """Edges of a box seen from above-right: front face w x h, receding by d up-right."""
    dx, dy = 0.7 * d, -0.45 * d
    f = [(cx - w / 2, cy - h / 2), (cx + w / 2, cy - h / 2), (cx + w / 2, cy + h / 2), (cx - w / 2, cy + h / 2)]
    b = [(x + dx, y + dy) for x, y in f]
    return [[f[0], f[1], f[2], f[3], f[0]], [f[0], b[0], b[1], f[1]], [f[1], b[1], b[2], f[2]]]


def _ellipse(cx, cy, rx, ry, a0=0.0, a1=2 * np.pi, n=40):
    t = np.linspace(a0, a1, n)
    return list(zip(cx + rx * np.cos(t), cy + ry * np.sin(t)))


def sample_strokes() -> dict[str, list[list[tuple[float, float]]]]:
    """Strokes of each sample in unit canvas coordinates (0..1, y down)."""
    mug = [
        _ellipse(0.45, 0.3, 0.17, 0.06),
        [(0.28, 0.3), (0.28, 0.72)],
        [(0.62, 0.3), (0.62, 0.72)],
        _ellipse(0.45, 0.72, 0.17, 0.06, 0.0, np.pi),
        _ellipse(0.66, 0.5, 0.1, 0.13, -np.pi / 2, np.pi / 2),
    ]
    table = [[(0.18, 0.38), (0.6, 0.32), (0.84, 0.42), (0.42, 0.5), (0.18, 0.38)],
             [(0.18, 0.38), (0.18, 0.44), (0.42, 0.56), (0.84, 0.48), (0.84, 0.42)],
             [(0.42, 0.56), (0.42, 0.5)],
             [(0.21, 0.43), (0.21, 0.78)], [(0.4, 0.55), (0.4, 0.88)], [(0.81, 0.48), (0.81, 0.8)],
             [(0.6, 0.37), (0.6, 0.66)]]
    cabinet = _box(0.45, 0.58, 0.42, 0.5, 0.3) + [[(0.45, 0.33), (0.45, 0.83)], [(0.41, 0.58), (0.41, 0.64)],
                                                  [(0.49, 0.58), (0.49, 0.64)]]
    lamp = [[(0.36, 0.2), (0.64, 0.2), (0.74, 0.42), (0.26, 0.42), (0.36, 0.2)],
            [(0.5, 0.42), (0.5, 0.8)],
            _ellipse(0.5, 0.84, 0.16, 0.05)]
    return {"drawn_mug": mug, "drawn_table": table, "drawn_cabinet": cabinet, "drawn_lamp": lamp}


def handify(path, size, rng, spacing=4.0):
    """Resample a polyline to ~``spacing`` px steps with wobble and a small overshoot at both ends."""
    p = np.asarray(path, float) * size
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    cum = np.concatenate([[0], np.cumsum(seg)])
    t = np.linspace(0, cum[-1], max(2, int(cum[-1] / spacing)))
    pts = np.stack([np.interp(t, cum, p[:, 0]), np.interp(t, cum, p[:, 1])], axis=1)
    if len(pts) > 2:
        d0, d1 = pts[1] - pts[0], pts[-1] - pts[-2]
        pts = np.vstack([pts[0] - 1.5 * d0, pts, pts[-1] + 1.5 * d1])
    wobble = np.cumsum(rng.normal(0, 0.25, pts.shape), axis=0)
    wobble -= np.linspace(0, 1, len(pts))[:, None] * wobble[-1]  # ends stay near the intended points
    return pts + wobble


def main(argv: list[str]) -> int:
    out = Path(argv[0] if argv else "assets/samples")
    out.mkdir(parents=True, exist_ok=True)
    from gui_helpers import FakeEngine, draw_stroke
    from PySide6.QtWidgets import QApplication

    from app.window import MainWindow

    app = QApplication.instance() or QApplication(["draw_samples"])
    rng = np.random.default_rng(7)
    for name, strokes in sample_strokes().items():
        window = MainWindow(engine_factory=FakeEngine, autosave=False, persist_settings=False)
        window.resize(900, 700)
        window.show()
        app.processEvents()
        size = min(window.canvas.width(), window.canvas.height())
        for s in strokes:
            draw_stroke(window.canvas, handify(s, size, rng))
            app.processEvents()
        window.save_to(out / f"{name}.sketch.json")  # also marks the sketch saved: closing asks nothing
        (out / f"{name}.sketch.json").unlink()  # keep the PNG: that is what File > Open reads
        window.close()
        window.deleteLater()
        app.processEvents()
        print(f"wrote {out / (name + '.png')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
