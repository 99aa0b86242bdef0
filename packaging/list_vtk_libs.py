"""Measure which VTK files the app maps at run time, for a lean PyInstaller bundle.

Runs the real window under the current display (use xvfb-run), opens a sample sketch,
waits for the mesh, then exercises every viewport feature (each view preset, wireframe on
and off, reset, a screenshot, a mesh export in every format), and writes the basenames of
the ``vtkmodules`` files mapped into the process to ``packaging/vtk_runtime_libs.txt``. The
spec ships only those VTK binaries. Rerun it after upgrading VTK, or after the app starts
using a new VTK feature:

    xvfb-run -a python packaging/list_vtk_libs.py --models DIR
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUT = HERE / "vtk_runtime_libs.txt"


def mapped_vtk_files() -> list[str]:
    names = set()
    with open("/proc/self/maps") as fh:
        for line in fh:
            parts = line.split()
            if len(parts) >= 6 and "/vtkmodules/" in parts[5]:
                names.add(os.path.basename(parts[5]))
    return sorted(names)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", required=True, help="a model folder (e.g. tests' fixture models)")
    parser.add_argument("--sample", default=str(HERE.parent / "assets" / "samples" / "chair_chair_00018_v3.png"))
    args = parser.parse_args()

    from PySide6.QtWidgets import QApplication

    from app.window import MainWindow
    from engine.export import supported_suffixes

    app = QApplication.instance() or QApplication(sys.argv)
    window = MainWindow(models_dir=args.models, autosave=False, persist_settings=False)
    window.show()
    done = []
    window.meshUpdated.connect(lambda _id: done.append(True))
    window.inferenceFailed.connect(lambda _id, msg: (print(f"inference failed: {msg}", file=sys.stderr), sys.exit(1)))
    if not window.open_path(args.sample, interactive=False):
        print(f"could not open {args.sample}", file=sys.stderr)
        return 1
    while not done:
        app.processEvents()
    for preset in ("sketch", "front", "side", "top", "iso"):
        window.viewport.set_view(preset)
        app.processEvents()
    for on in (True, False):
        window.viewport.set_wireframe(on)
        app.processEvents()
    window.viewport.reset_view()
    with tempfile.TemporaryDirectory() as tmp:
        window.save_screenshot(Path(tmp) / "shot.png")
        for suffix in supported_suffixes():
            window.export_mesh_to(Path(tmp) / f"mesh{suffix}")
    libs = mapped_vtk_files()
    window.force_close()
    OUT.write_text("\n".join(libs) + "\n")
    print(f"{len(libs)} VTK files mapped; wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
