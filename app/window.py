"""The main window: sketch canvas (left), 3D viewport and normal-image panel (right).

Composition (no multiple inheritance): :class:`MainWindow` holds an
:class:`app.canvas.SketchCanvas`, an :class:`app.viewport.MeshViewport`, an
:class:`app.worker.InferenceController` (engine calls on a worker QThread) and an
:class:`app.autosave.Autosaver`. Data flow: canvas ``sketchChanged`` -> debounce ->
worker -> ``predictionReady`` -> viewport / normal panel / status bar (GUI thread).

:func:`run` is the entry point behind ``sketchmesh`` (see app/main.py), including the
headless ``--open SKETCH --screenshot OUT.png`` mode.
"""

from __future__ import annotations

import gc
import os
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
from PySide6.QtCore import QBuffer, QByteArray, QEventLoop, QIODevice, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QActionGroup, QCloseEvent, QImage, QKeySequence, QPixmap
from PySide6.QtWidgets import (
    QApplication,
    QDoubleSpinBox,
    QFileDialog,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QMessageBox,
    QSplitter,
    QStyle,
    QToolBar,
    QVBoxLayout,
    QWidget,
)

from app.autosave import SKETCH_SUFFIX, Autosaver, default_autosave_dir, read_sketch_file, write_sketch_file
from app.canvas import TOOL_ERASER, TOOL_PEN, SketchCanvas, ink_to_qimage
from app.history import SketchState
from app.jobs import JobQueue
from app.settings import MAX_BRUSH_WIDTH, MIN_BRUSH_WIDTH, AppSettings
from app.viewport import VIEW_PRESETS, MeshViewport
from app.worker import (
    LIVE_WHILE_DRAWING_MAX_MS,
    CanvasRaster,
    EventLoopLatencyProbe,
    InferenceController,
    rgb_to_qimage,
)
from engine.contract import GENERATOR_FILE, PREDICTOR_FILE
from engine.errors import ModelError, SketchInputError, SketchmeshError
from engine.fileio import atomic_write_bytes

APP_NAME = "Sketchmesh"
IMAGE_FILTER = "Sketches (*.png *.jpg *.jpeg *.bmp *.tif *.tiff *.webp *.sketch.json);;All files (*)"
MESH_FILTERS = {
    ".obj": "Wavefront OBJ (*.obj)",
    ".glb": "glTF binary (*.glb)",
    ".gltf": "glTF text, embedded buffers (*.gltf)",
    ".ply": "Stanford PLY (*.ply)",
    ".stl": "STL (*.stl)",
}
PANEL_SIZE = 148
"""Side of the model-input and normal-image thumbnails, in pixels."""
THUMBNAIL_SIZE = PANEL_SIZE - 2
"""Side the worker scales the thumbnails to (inside the panel's 1-px border)."""
SCREENSHOT_TIMEOUT_S = 120.0
"""How long ``--screenshot`` waits for the mesh before giving up."""
READY_TIMEOUT_S = 10.0
"""How long :meth:`MainWindow.wait_until_ready` waits before the window is shown anyway."""
GIL_SWITCH_INTERVAL_S = 0.001
"""How long a background thread running Python may keep the UI thread waiting for the
interpreter lock (Python's default is 5 ms; measured: the UI thread waited for the lock in
about a sixth of its busy samples)."""

EngineFactory = Callable[[Path], object]


def models_present(folder: Path) -> bool:
    """True when ``folder`` holds both ONNX files of the engine contract."""
    return (folder / GENERATOR_FILE).is_file() and (folder / PREDICTOR_FILE).is_file()


def no_models_message(folder: Path) -> str:
    """Why ``folder`` cannot be used, naming the ONNX file when exactly one of the two is missing."""
    missing = [name for name in (GENERATOR_FILE, PREDICTOR_FILE) if not (folder / name).is_file()]
    what = f" ({missing[0]} is missing)" if folder.is_dir() and len(missing) == 1 else ""
    return f"No models in {folder}{what}: choose a model folder (File > Load models...)"


def default_engine_factory(folder: Path) -> object:
    """``engine.pipeline.SketchEngine(folder)``; ModelError when the folder lacks the models."""
    if not models_present(folder):
        raise ModelError(no_models_message(folder))
    from engine.pipeline import SketchEngine  # noqa: PLC0415 (onnxruntime loads with the engine)

    return SketchEngine(folder)


def bundled_models_dir() -> Path:
    """``assets.MODELS_DIR``; falls back to the source tree's assets/models when ``assets`` is not
    importable (an editable install made before ``assets`` became a package)."""
    try:
        from assets import MODELS_DIR  # noqa: PLC0415
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[1] / "assets" / "models"
    return Path(MODELS_DIR)


_rgb_to_qimage = rgb_to_qimage  # (H, W, 3) float in [0, 1] or uint8 -> RGB888 QImage


def _png_bytes(image: QImage | QPixmap) -> bytes:
    buf = QBuffer()
    buf.open(QIODevice.OpenModeFlag.WriteOnly)
    if not image.save(buf, "PNG"):
        raise OSError("PNG encoding failed")
    return bytes(buf.data().data())


def read_sketch_source(path: Path) -> SketchState | np.ndarray:
    """What File > Open reads (any thread): a ``.sketch.json``'s state, or an image's (H, W) ink.

    Raises:
        SketchInputError: missing, corrupt or blank file.
    """
    if path.name.lower().endswith(SKETCH_SUFFIX):
        return read_sketch_file(path)[0]
    from engine.preprocess import load_sketch_image  # noqa: PLC0415

    ink = load_sketch_image(path)
    if not np.any(ink > 0.5):
        raise SketchInputError(f"{path}: the image has no ink (a blank page?)")
    return ink


REFINE_BY_DEFAULT = False
"""Whether "Refine to outline" starts checked. Off since 2026-11-30: the refinement fits the mesh to the drawn outline
(silhouette IoU against it 0.857 -> 0.891 on clean test sketches) but not to the true one (0.809 both ways), costs 3D
accuracy (voxel IoU 0.6208 -> 0.5989 clean, 0.5670 -> 0.5434 strong) and takes the live update over the 60 ms budget on
2 cores (`reproduce_models.sh latency-app-v49`; README, "Refining the mesh to the outline"); an artist who wants the
drawn outline turns it on (R)."""
MIRROR_BY_DEFAULT = True
"""Whether "Mirror average" starts checked: each mesh averaged with the one predicted from the drawing flipped
left to right (engine.pipeline), which raises voxel IoU from sketches for a second pass of both networks
(model card, "Mirror averaging")."""
REPAIR_BY_DEFAULT = True
"""Whether "Repair folds on export" starts checked: where the mesh's surface crosses itself (thin parts' folds), the
exported mesh is smoothed just there until it does not (README, "Repairing folds"); the live preview is not repaired,
which would cost tens of milliseconds a stroke on folded meshes."""


def prediction_message(prediction) -> str:
    """The status bar's line for a new mesh: its size, what the model folder's router read the drawing as (and the
    specialist predictor it chose), and any warning."""
    m = prediction.mesh
    text = f"Mesh: {m.num_vertices} vertices, {m.num_faces} faces"
    category = getattr(prediction, "category", None)
    if category:
        route = getattr(prediction, "route", None)
        text += f"; read as {category}" + (f", shaped by {route}" if route else "")
    return text + "".join(f" ({w})" for w in getattr(prediction, "warnings", ()))


def format_timings(timings_ms: dict[str, float], cached: bool = False) -> str:
    """One status-bar line: ``generator 12.3 ms · predictor 2.1 ms · total 15.0 ms``."""
    parts = [f"{k} {float(v):.1f} ms" for k, v in timings_ms.items()]
    text = " \u00b7 ".join(parts) if parts else "no timings"
    return text + (" (cached)" if cached else "")


class ImagePanel(QLabel):
    """A small titled thumbnail (model input or normal image)."""

    def __init__(self, title: str, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.title = title
        self.setFixedSize(PANEL_SIZE, PANEL_SIZE)
        self.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.setToolTip(title)
        self.setStyleSheet("background: #202228; color: #888; border: 1px solid #333;")
        self.clear_image()

    def clear_image(self) -> None:
        self.clear()
        self.setText(self.title)
        self.has_image = False

    def set_image(self, image: QImage) -> None:
        """Show ``image``, scaled down to fit unless it already fits (the worker's thumbnails do)."""
        pm = QPixmap.fromImage(image)
        if pm.width() > THUMBNAIL_SIZE or pm.height() > THUMBNAIL_SIZE:
            pm = pm.scaled(THUMBNAIL_SIZE, THUMBNAIL_SIZE, Qt.AspectRatioMode.KeepAspectRatio, Qt.TransformationMode.SmoothTransformation)
        self.setPixmap(pm)
        self.has_image = True


class MainWindow(QMainWindow):
    """The Sketchmesh main window.

    Args:
        models_dir: model folder to use (overrides the saved setting and the bundled one).
        engine_factory: builds an engine from a folder (default: SketchEngine, after checking
            the ONNX files exist); tests pass a fake.
        autosave_dir: where the autosave file goes (default QStandardPaths AppDataLocation);
            None together with ``autosave=False`` disables autosave (headless screenshots).
        autosave: whether to autosave at all.
        persist_settings: whether to write QSettings on close.
        debounce_ms: inference debounce.

    Signals:
        meshUpdated(int): a fresh prediction was shown (request id).
        previewShown(int): the unrefined mesh of a drawing being refined was shown (request id; meshUpdated follows).
        inferenceFailed(int, str): the newest request failed (request id, message).
        exportFinished(str, str): a mesh export ended (path, error message or "").
        sketchOpened(str, str): opening a file ended (path, error message or "").
        modelsLoaded(str, str): a :meth:`load_models` ended (folder, error message or "").
    """

    meshUpdated = Signal(int)
    previewShown = Signal(int)
    inferenceFailed = Signal(int, str)
    exportFinished = Signal(str, str)
    sketchOpened = Signal(str, str)
    modelsLoaded = Signal(str, str)

    def __init__(
        self,
        *,
        models_dir: str | os.PathLike | None = None,
        engine_factory: EngineFactory | None = None,
        autosave_dir: str | os.PathLike | None = None,
        autosave: bool = True,
        persist_settings: bool = True,
        debounce_ms: int | None = None,
    ) -> None:
        super().__init__()
        self.setWindowTitle(APP_NAME)
        self.settings = AppSettings.load()
        self._persist_settings = persist_settings
        self._engine_factory = engine_factory or default_engine_factory
        self._current_path: Path | None = None
        self._saved_state: SketchState | None = None
        self._last_prediction = None
        self._model_problem: str | None = None
        self._models_pending: tuple[int, Path, bool] | None = None
        """(load token, folder, remember) of the model folder loading on the worker."""
        self._force_close = False
        self._closed = False

        # ---- widgets
        self.canvas = SketchCanvas()
        self.canvas.set_brush_width(self.settings.brush_width)
        self.canvas.set_eraser_width(self.settings.eraser_width)
        self.canvas.set_show_guide(self.settings.show_guide)
        self.viewport = MeshViewport()
        self.viewport.set_wireframe(self.settings.wireframe)
        self.input_panel = ImagePanel("Model input")
        self.normal_panel = ImagePanel("Generated normals")
        right = QWidget()
        rl = QVBoxLayout(right)
        rl.setContentsMargins(0, 0, 0, 0)
        rl.addWidget(self.viewport, 1)
        panels = QHBoxLayout()
        panels.setContentsMargins(4, 4, 4, 4)
        panels.addWidget(self.input_panel)
        panels.addWidget(self.normal_panel)
        panels.addStretch(1)
        rl.addLayout(panels)
        splitter = QSplitter(Qt.Orientation.Horizontal)
        splitter.addWidget(self.canvas)
        splitter.addWidget(right)
        splitter.setStretchFactor(0, 1)
        splitter.setStretchFactor(1, 1)
        splitter.setChildrenCollapsible(False)
        self.setCentralWidget(splitter)

        # ---- status bar
        self.message_label = QLabel("Draw a sketch")
        self.timing_label = QLabel("")
        self.lag_label = QLabel("")
        self.model_label = QLabel("")
        sb = self.statusBar()
        sb.addWidget(self.message_label, 1)
        sb.addPermanentWidget(self.timing_label)
        sb.addPermanentWidget(self.lag_label)
        sb.addPermanentWidget(self.model_label)

        # ---- inference
        self.controller = InferenceController(None, 100 if debounce_ms is None else debounce_ms, self, thumbnail_size=THUMBNAIL_SIZE)
        self.controller.predictionReady.connect(self._on_prediction)
        self.controller.previewReady.connect(self._on_preview)
        self.controller.predictionFailed.connect(self._on_failure)
        self.controller.cleared.connect(self._on_cleared)
        self.controller.busyChanged.connect(self._on_busy)
        self.controller.engineLoaded.connect(self._on_models_loaded)
        self.controller.engineLoadFailed.connect(self._on_models_failed)
        self.latency_probe = EventLoopLatencyProbe(10, self)
        self.last_lag_ms: float | None = None
        """Largest event-loop lateness measured during the last inference (ms)."""

        self.jobs = JobQueue("sketchmesh-export", self)
        """File writes the user asked for (mesh export), off the UI thread."""
        self._exports_running = 0

        # ---- autosave
        self.autosaver: Autosaver | None = None
        if autosave:
            self.autosaver = Autosaver(autosave_dir if autosave_dir is not None else default_autosave_dir(), parent=self)
            self.autosaver.failed.connect(self.show_message)

        self._build_actions()
        self.canvas.sketchChanged.connect(self._on_sketch_changed)
        self.canvas.strokeProgress.connect(self._on_stroke_progress)
        self.canvas.historyChanged.connect(self._update_actions)

        folder = Path(models_dir) if models_dir else (Path(self.settings.models_dir) if self.settings.models_dir else bundled_models_dir())
        self.load_models(folder, remember=models_dir is None and bool(self.settings.models_dir))

        if self.settings.geometry:
            self.restoreGeometry(QByteArray(self.settings.geometry))
        else:
            self.resize(1200, 720)
        if self.settings.window_state:
            self.restoreState(QByteArray(self.settings.window_state))
        self._update_actions()
        self.canvas.setFocus()

    # ------------------------------------------------------------------ actions and menus
    def _action(self, key: str, text: str, slot: Callable, shortcut: QKeySequence | str | None = None, icon: QStyle.StandardPixmap | None = None, checkable: bool = False) -> QAction:
        act = QAction(text, self)
        if shortcut is not None:
            act.setShortcut(QKeySequence(shortcut))
        if icon is not None:
            act.setIcon(self.style().standardIcon(icon))
        act.setCheckable(checkable)
        act.triggered.connect(slot)
        self.actions[key] = act
        return act

    def _build_actions(self) -> None:
        self.actions: dict[str, QAction] = {}
        SP = QStyle.StandardPixmap
        a = self._action
        a("new", "&New", self.new_sketch, QKeySequence.StandardKey.New, SP.SP_FileIcon)
        a("open", "&Open sketch image...", self.open_dialog, QKeySequence.StandardKey.Open, SP.SP_DialogOpenButton)
        a("save", "&Save sketch", self.save, QKeySequence.StandardKey.Save, SP.SP_DialogSaveButton)
        a("save_as", "Save sketch &as...", self.save_as, QKeySequence("Ctrl+Shift+S"))
        a("export_png", "Export sketch as &PNG...", self.export_png_dialog)
        a("export_mesh", "&Export mesh...", self.export_mesh_dialog, QKeySequence("Ctrl+E"), SP.SP_DriveFDIcon)
        a("load_models", "Load &models...", self.load_models_dialog)
        a("remove_background", "Remove background image", self.canvas.clear_background)
        a("quit", "&Quit", self.close, QKeySequence.StandardKey.Quit)
        a("undo", "&Undo", self.canvas.undo, QKeySequence("Ctrl+Z"), SP.SP_ArrowBack)
        a("redo", "&Redo", self.canvas.redo, QKeySequence("Ctrl+Shift+Z"), SP.SP_ArrowForward)
        a("clear", "&Clear", self.canvas.clear, QKeySequence("Ctrl+Shift+Delete"), SP.SP_DialogResetButton)
        a("pen", "&Pen", lambda: self.set_tool(TOOL_PEN), QKeySequence("P"), checkable=True)
        a("eraser", "&Eraser", lambda: self.set_tool(TOOL_ERASER), QKeySequence("E"), checkable=True)
        group = QActionGroup(self)
        group.setExclusive(True)
        group.addAction(self.actions["pen"])
        group.addAction(self.actions["eraser"])
        self.actions["pen"].setChecked(True)
        for i, preset in enumerate(VIEW_PRESETS):
            a(f"view_{preset}", f"{preset.capitalize()} view", lambda _=False, p=preset: self.viewport.set_view(p), QKeySequence(f"Ctrl+{i + 1}"))
        self.actions["view_sketch"].setText("Sketch's view")
        a("reset_view", "&Reset view", self.viewport.reset_view, QKeySequence("Ctrl+0"))
        a("wireframe", "&Wireframe", self._toggle_wireframe, QKeySequence("W"), checkable=True)
        self.actions["wireframe"].setChecked(self.viewport.wireframe)
        a("guide", "Framing &guide", self._toggle_guide, checkable=True)
        self.actions["guide"].setChecked(self.canvas.show_guide)
        a("refine", "Re&fine to outline", self._toggle_engine_option, QKeySequence("R"), checkable=True)
        self.actions["refine"].setToolTip("Move the mesh so its outline from the sketch's view matches the drawing")
        self.actions["refine"].setChecked(REFINE_BY_DEFAULT)
        a("mirror", "&Mirror average", self._toggle_engine_option, QKeySequence("M"), checkable=True)
        self.actions["mirror"].setToolTip("Also read the drawing flipped left to right and average the two meshes "
                                          "(steadier shapes, about twice the networks' time)")
        self.actions["mirror"].setChecked(MIRROR_BY_DEFAULT)
        a("repair", "Repair f&olds on export", self._toggle_repair, checkable=True)
        self.actions["repair"].setToolTip("Where the exported mesh's surface crosses itself, smooth it just there "
                                          "until it does not (clean meshes for printing and booleans)")
        self.actions["repair"].setChecked(REPAIR_BY_DEFAULT)
        a("about", "&About Sketchmesh", self.about)

        mb = self.menuBar()
        m = mb.addMenu("&File")
        for k in ("new", "open", "save", "save_as", "export_png", "export_mesh", "repair", None, "load_models", "remove_background", None, "quit"):
            m.addSeparator() if k is None else m.addAction(self.actions[k])
        m = mb.addMenu("&Edit")
        for k in ("undo", "redo", None, "clear"):
            m.addSeparator() if k is None else m.addAction(self.actions[k])
        m = mb.addMenu("&Tools")
        for k in ("pen", "eraser"):
            m.addAction(self.actions[k])
        m = mb.addMenu("&View")
        for k in [f"view_{p}" for p in VIEW_PRESETS] + [None, "reset_view", "wireframe", "guide", "refine", "mirror"]:
            m.addSeparator() if k is None else m.addAction(self.actions[k])
        m = mb.addMenu("&Help")
        m.addAction(self.actions["about"])

        tb = QToolBar("Main")
        tb.setObjectName("main_toolbar")
        tb.setMovable(False)
        self.addToolBar(tb)
        for k in ("new", "open", "save", "export_mesh", None, "undo", "redo", "clear", None, "pen", "eraser"):
            tb.addSeparator() if k is None else tb.addAction(self.actions[k])
        self.width_spin = QDoubleSpinBox()
        self.width_spin.setRange(MIN_BRUSH_WIDTH, MAX_BRUSH_WIDTH)
        self.width_spin.setSingleStep(0.5)
        self.width_spin.setDecimals(1)
        self.width_spin.setSuffix(" px")
        self.width_spin.setToolTip("Brush width (the eraser has its own width)")
        self.width_spin.setValue(self.canvas.brush_width)
        self.width_spin.valueChanged.connect(self._on_width_changed)
        self.width_spin.setFocusPolicy(Qt.FocusPolicy.ClickFocus)
        self.width_spin.editingFinished.connect(self.canvas.setFocus)  # Ctrl+Z goes back to the drawing
        tb.addWidget(QLabel(" Width "))
        tb.addWidget(self.width_spin)
        tb.addSeparator()
        for k in [f"view_{p}" for p in VIEW_PRESETS] + ["wireframe", "refine", "mirror"]:
            tb.addAction(self.actions[k])

    def _update_actions(self) -> None:
        h = self.canvas.history
        self.actions["undo"].setEnabled(h.can_undo)
        self.actions["redo"].setEnabled(h.can_redo)
        self.actions["undo"].setText(f"&Undo {h.undo_label}".rstrip())
        self.actions["redo"].setText(f"&Redo {h.redo_label}".rstrip())
        self.actions["remove_background"].setEnabled(self.canvas.background is not None)
        self.setWindowModified(self.is_dirty)
        name = self._current_path.name if self._current_path else "untitled"
        self.setWindowTitle(f"{name}[*] - {APP_NAME}")

    def set_tool(self, tool: str) -> None:
        self.canvas.set_tool(tool)
        self.actions["pen" if tool == TOOL_PEN else "eraser"].setChecked(True)
        self.width_spin.blockSignals(True)
        self.width_spin.setValue(self.canvas.brush_width if tool == TOOL_PEN else self.canvas.eraser_width)
        self.width_spin.blockSignals(False)

    def _on_width_changed(self, value: float) -> None:
        if self.canvas.tool == TOOL_PEN:
            self.canvas.set_brush_width(value)
            self.settings.brush_width = value
        else:
            self.canvas.set_eraser_width(value)
            self.settings.eraser_width = value

    def _toggle_wireframe(self, on: bool) -> None:
        self.viewport.set_wireframe(on)
        self.settings.wireframe = bool(on)

    def _toggle_engine_option(self, on: bool) -> None:
        """Refine to outline or Mirror average toggled: tell the engine, predict the current sketch again."""
        self._apply_engine_options()
        if not self.canvas.is_empty:
            self._request_inference()

    def _apply_engine_options(self) -> None:
        """Tell the engine what the toggles ask for: refinement steps (engine/refine.py), mirror averaging
        (engine/pipeline.py). An engine without the option (a test double) is left alone."""
        from engine.refine import DEFAULT_STEPS  # noqa: PLC0415

        if self.engine is None:
            return
        if hasattr(self.engine, "refine_steps"):
            self.engine.refine_steps = DEFAULT_STEPS if self.actions["refine"].isChecked() else 0
        if hasattr(self.engine, "mirror_average"):
            self.engine.mirror_average = self.actions["mirror"].isChecked()

    def _toggle_repair(self, on: bool) -> None:
        self.show_message("Exports repair folds" if on else "Exports keep the mesh as predicted, folds included")

    def _toggle_guide(self, on: bool) -> None:
        self.canvas.set_show_guide(on)
        self.settings.show_guide = bool(on)

    # ------------------------------------------------------------------ status
    def show_message(self, text: str) -> None:
        """Main status-bar message (stays until replaced)."""
        self.message_label.setText(text)

    def status_text(self) -> str:
        """Everything the status bar shows, joined (for tests and logs)."""
        return " | ".join(t for t in (self.message_label.text(), self.timing_label.text(), self.lag_label.text(), self.model_label.text()) if t)

    # ------------------------------------------------------------------ models
    @property
    def engine(self) -> object | None:
        return self.controller.engine

    @property
    def model_problem(self) -> str | None:
        """Why no engine is loaded (None when one is)."""
        return self._model_problem

    def load_models(self, folder: str | os.PathLike, *, remember: bool = True) -> bool:
        """Use the models in ``folder``; on failure the status bar says why, naming the folder.

        With no models in use (at start), the new engine is used at once and its models load
        on the worker (broken ones are reported as an inference failure). With models in use,
        the new folder's models are loaded and validated on the worker first, and replace the
        ones in use only when that succeeds; until then, and when it fails, the models in use
        keep answering. ``modelsLoaded(folder, error)`` follows either way.

        Returns False when ``folder`` is refused at once (no models in it), else True.
        """
        folder = Path(folder).expanduser()
        try:
            engine = self._engine_factory(folder)  # cheap: checks the files, loads nothing
        except SketchmeshError as exc:
            if self.engine is not None:  # keep working with the models already loaded
                self.show_message(f"{exc} (still using {self.model_label.toolTip()})")
            else:
                self._model_problem = str(exc)
                self.model_label.setText("Model: none")
                self.model_label.setToolTip(str(folder))
                self.show_message(str(exc))
            self.modelsLoaded.emit(str(folder), str(exc))
            return False
        if self.engine is None:
            self._use_engine(engine, folder, remember)
            if self.canvas.is_empty:
                self.controller.preload()  # create the ONNX sessions now, on the worker
            return True
        token = self.controller.load_engine(engine)
        if token is None:  # closing
            return False
        self._models_pending = (token, folder, remember)
        self.show_message(f"Loading models from {folder}...")
        return True

    def _use_engine(self, engine: object, folder: Path, remember: bool) -> None:
        """Switch to ``engine`` (the models of ``folder``) and redo the current sketch with it."""
        self._model_problem = None
        self.controller.set_engine(engine)
        self._apply_engine_options()
        self.model_label.setText(f"Model: {folder.name or folder}")
        self.model_label.setToolTip(str(folder))
        if remember:
            self.settings.models_dir = str(folder)
        self.show_message(f"Models from {folder}")
        if not self.canvas.is_empty:
            self._request_inference()
        self.modelsLoaded.emit(str(folder), "")

    def _take_pending_models(self, token: int) -> tuple[Path, bool] | None:
        pending = self._models_pending
        if pending is None or pending[0] != token or self._closed:
            return None
        self._models_pending = None
        return pending[1], pending[2]

    def _on_models_loaded(self, token: int, engine: object) -> None:
        pending = self._take_pending_models(token)
        if pending is not None:
            self._use_engine(engine, *pending)

    def _on_models_failed(self, token: int, message: str) -> None:
        pending = self._take_pending_models(token)
        if pending is None:
            return
        folder = pending[0]
        why = message.replace(f"{folder}{os.sep}", "")  # the folder is named once, up front
        self.show_message(f"Could not load models from {folder}: {why} (still using {self.model_label.toolTip()})")
        self.modelsLoaded.emit(str(folder), message)

    def load_models_dialog(self) -> None:
        start = self.settings.models_dir or str(bundled_models_dir())
        folder = QFileDialog.getExistingDirectory(self, "Choose a model folder", start)
        if folder:
            self.load_models(folder)

    # ------------------------------------------------------------------ inference
    def _on_sketch_changed(self) -> None:
        self._update_actions()
        if self.autosaver is not None:
            self.autosaver.schedule(self.canvas.state, (self.canvas.width(), self.canvas.height()))
        self._request_inference()

    def _model_input(self, include_live: bool = False) -> object | None:
        """What the worker gets: strokes, a CanvasRaster or a CanvasComposite (rendered there)."""
        src = self.canvas.composite_request(include_live=include_live)
        return CanvasRaster(src) if isinstance(src, np.ndarray) else src

    def _request_inference(self) -> None:
        if self.canvas.is_empty:
            self.controller.submit(None)
            return
        if self.engine is None:
            self.show_message(self._model_problem or "No models loaded")
            return
        self.controller.schedule(self._model_input)

    def _on_stroke_progress(self) -> None:
        """Live update while drawing, only when inference is fast enough and idle."""
        rt = self.controller.last_roundtrip_ms
        if self.engine is None or rt is None or rt > LIVE_WHILE_DRAWING_MAX_MS or self.controller.busy:
            return
        self.controller.submit(self._model_input(include_live=True))

    def _on_busy(self, busy: bool) -> None:
        if busy and not self.latency_probe.running:
            self.latency_probe.start()
        elif not busy and self.latency_probe.running:
            self.latency_probe.stop()
            self.last_lag_ms = self.latency_probe.max_ms
            self.lag_label.setText(f"UI lag {self.last_lag_ms:.0f} ms")
            self.lag_label.setToolTip("largest event-loop delay while the last inference ran")

    def _on_preview(self, request_id: int, prediction: object) -> None:
        """The networks' mesh of a drawing the engine is refining: shown at once, replaced by the refined one (which
        alone becomes :attr:`last_prediction`, the mesh exports take) when it comes."""
        self._show_mesh(request_id, prediction)
        self.show_message("Refining to the outline...")
        self.previewShown.emit(request_id)

    def _on_prediction(self, request_id: int, prediction: object) -> None:
        self._last_prediction = prediction
        self._show_mesh(request_id, prediction)
        self.timing_label.setText(format_timings(dict(prediction.timings_ms), bool(getattr(prediction, "cached", False))))
        self.show_message(prediction_message(prediction))
        self._update_actions()
        self.meshUpdated.emit(request_id)

    def _show_mesh(self, request_id: int, prediction: object) -> None:
        """The viewport, the model-input and normal-image panels for ``prediction``."""
        self.viewport.set_mesh(prediction.mesh)
        thumbs = self.controller.take_thumbnails(request_id)
        sketch = thumbs.sketch if thumbs is not None else getattr(prediction, "sketch", None)
        if sketch is not None:
            self.input_panel.set_image(sketch if isinstance(sketch, QImage) else ink_to_qimage(np.asarray(sketch)))
        normals = thumbs.normals if thumbs is not None else getattr(prediction, "normals", None)
        if normals is not None:
            self.normal_panel.set_image(normals if isinstance(normals, QImage) else _rgb_to_qimage(np.asarray(normals)))

    def _on_failure(self, request_id: int, message: str) -> None:
        self.show_message(f"Inference failed: {message}")
        self.inferenceFailed.emit(request_id, message)

    def _on_cleared(self) -> None:
        self._last_prediction = None
        self.viewport.set_mesh(None)
        self.input_panel.clear_image()
        self.normal_panel.clear_image()
        self.timing_label.setText("")
        self.show_message("Draw a sketch" if self.engine is not None else (self._model_problem or ""))
        self._update_actions()

    @property
    def last_prediction(self) -> object | None:
        return self._last_prediction

    # ------------------------------------------------------------------ documents
    @property
    def is_dirty(self) -> bool:
        """True when the drawing differs from the last save (an empty never-saved sketch is clean)."""
        st = self.canvas.state
        if self._saved_state is None:
            return not st.is_empty
        return not st.same_content(self._saved_state)

    def new_sketch(self) -> None:
        if not self._maybe_save("Start a new sketch"):
            return
        self.canvas.new_sketch()
        self._current_path = None
        self._saved_state = None
        if self.autosaver is not None:
            self.autosaver.discard()
        self._update_actions()

    def open_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open sketch", self.settings.last_open_dir, IMAGE_FILTER)
        if path:
            self.open_path(path)

    def open_path(self, path: str | os.PathLike, *, interactive: bool = True) -> bool:
        """Open a sketch image (as a background layer) or a ``.sketch.json``.

        Interactive: the file is read and decoded on a job thread (a large scan takes a
        while) and applied when ready; returns True once the request is accepted, and
        ``sketchOpened(path, error)`` follows. On failure the current drawing is kept, and a
        message box and the status bar say why. Not interactive (CLI paths): synchronous,
        and the SketchInputError propagates.
        """
        p = Path(path)
        if not interactive:
            self._apply_opened(p, read_sketch_source(p))
            return True
        self.show_message(f"Opening {p.name}...")
        self.jobs.submit(lambda: read_sketch_source(p), lambda src: self._apply_opened(p, src), lambda msg: self._open_failed(p, msg))
        return True

    def _apply_opened(self, p: Path, source: SketchState | np.ndarray) -> None:
        if isinstance(source, SketchState):
            self.canvas.load_state(source)
            self._current_path = p
            self._saved_state = self.canvas.state
        else:
            self.canvas.set_background_ink(source)
        self.settings.last_open_dir = str(p.parent)
        self.show_message(f"Opened {p.name}")
        self._update_actions()
        self.sketchOpened.emit(str(p), "")

    def _open_failed(self, p: Path, message: str) -> None:
        self.show_message(f"Could not open {p.name}: {message}")
        if not self._closed:
            QMessageBox.warning(self, "Cannot open sketch", message)
        self.sketchOpened.emit(str(p), message)

    def save(self) -> bool:
        """Save to the current ``.sketch.json`` (asks for a name the first time)."""
        if self._current_path is None:
            return self.save_as()
        return self.save_to(self._current_path)

    def save_as(self) -> bool:
        start = str(Path(self.settings.last_save_dir or Path.home()) / ("sketch" + SKETCH_SUFFIX))
        path, _ = QFileDialog.getSaveFileName(self, "Save sketch", start, f"Sketchmesh sketch (*{SKETCH_SUFFIX})")
        if not path:
            return False
        if not path.lower().endswith(SKETCH_SUFFIX):
            path = str(Path(path).with_suffix("")) + SKETCH_SUFFIX if path.lower().endswith(".json") else path + SKETCH_SUFFIX
        return self.save_to(path)

    def save_to(self, path: str | os.PathLike) -> bool:
        """Write the strokes (``.sketch.json``) and, beside it, a PNG of the canvas raster."""
        p = Path(path)
        try:
            write_sketch_file(p, self.canvas.state, (self.canvas.width(), self.canvas.height()))
            png = p.with_name(p.name[: -len(SKETCH_SUFFIX)] + ".png") if p.name.lower().endswith(SKETCH_SUFFIX) else p.with_suffix(".png")
            self.write_sketch_png(png)
        except (OSError, SketchmeshError) as exc:
            self.show_message(f"Save failed: {exc}")
            QMessageBox.warning(self, "Cannot save sketch", str(exc))
            return False
        self._current_path = p
        self._saved_state = self.canvas.state
        self.settings.last_save_dir = str(p.parent)
        if self.autosaver is not None:
            self.autosaver.discard()
        self.show_message(f"Saved {p.name} and {png.name}")
        self._update_actions()
        return True

    def write_sketch_png(self, path: str | os.PathLike) -> None:
        """The canvas raster (background + strokes), dark on white, at canvas size, atomically."""
        ink = self.canvas.render_raster()
        atomic_write_bytes(path, _png_bytes(ink_to_qimage(ink)))

    def export_png_dialog(self) -> None:
        start = str(Path(self.settings.last_save_dir or Path.home()) / "sketch.png")
        path, _ = QFileDialog.getSaveFileName(self, "Export sketch as PNG", start, "PNG image (*.png)")
        if not path:
            return
        if not path.lower().endswith(".png"):
            path += ".png"
        try:
            self.write_sketch_png(path)
        except OSError as exc:
            QMessageBox.warning(self, "Cannot export PNG", str(exc))
            return
        self.show_message(f"Exported {Path(path).name}")

    def export_mesh_dialog(self) -> bool:
        """Ask for a file name (one filter per format) and export the current mesh."""
        if self._last_prediction is None:
            self.show_message("Nothing to export yet: draw a sketch first")
            return False
        filters = ";;".join(MESH_FILTERS.values())
        start = str(Path(self.settings.last_export_dir or Path.home()) / "mesh.obj")
        path, selected = QFileDialog.getSaveFileName(self, "Export mesh", start, filters, MESH_FILTERS[".obj"])
        if not path:
            return False
        suffix = Path(path).suffix.lower()
        if suffix not in MESH_FILTERS:
            chosen = next((s for s, f in MESH_FILTERS.items() if f == selected), ".obj")
            path += chosen
        return self.export_mesh_to(path)

    def export_mesh_to(self, path: str | os.PathLike) -> bool:
        """Export the current mesh to ``path`` on a background thread (the suffix picks the format).

        Returns False at once for nothing to export or an unsupported suffix; otherwise True,
        and ``exportFinished(path, error)`` follows (the status bar, or a message box, says how
        it went).
        """
        if self._last_prediction is None:
            self.show_message("Nothing to export yet: draw a sketch first")
            return False
        from engine.export import export_mesh, supported_suffixes  # noqa: PLC0415

        p = Path(path)
        if p.suffix.lower() not in supported_suffixes():
            msg = f"{p.name}: unsupported mesh format {p.suffix or '(none)'}; choose one of {', '.join(supported_suffixes())}"
            self.show_message(f"Export failed: {msg}")
            QMessageBox.warning(self, "Cannot export mesh", msg)
            return False
        mesh = self._last_prediction.mesh  # immutable: safe to hand to the writer thread
        repair = self.actions["repair"].isChecked()
        self._exports_running += 1
        self.show_message(f"Exporting {p.name}...")

        def write() -> tuple[int, int]:
            """On the worker: the fold repair (when asked), then the atomic write; (crossings before, after)."""
            out, counts = mesh, (0, 0)
            if repair:
                from engine.postprocess import repair_self_intersections  # noqa: PLC0415

                fixed = repair_self_intersections(mesh)
                out, counts = fixed.mesh, (fixed.before, fixed.after)
            export_mesh(out, p)
            return counts

        def done(result: object) -> None:
            self._exports_running -= 1
            self.settings.last_export_dir = str(p.parent)
            before, after = result  # write()'s counts
            note = ""
            if after:
                note = f" ({after} crossing face pairs left of {before}: the fold repair ran out of rounds)"
            elif before:
                note = f" (folds repaired: {before} crossing face pairs)"
            self.show_message(f"Exported {p.name}{note}")
            self.exportFinished.emit(str(p), "")

        def failed(message: str) -> None:
            self._exports_running -= 1
            self.show_message(f"Export failed: {message}")
            if not self._closed:
                QMessageBox.warning(self, "Cannot export mesh", message)
            self.exportFinished.emit(str(p), message)

        self.jobs.submit(write, done, failed)
        return True

    @property
    def export_pending(self) -> bool:
        """A mesh export is still being written."""
        return self._exports_running > 0

    def about(self) -> None:
        QMessageBox.about(
            self,
            f"About {APP_NAME}",
            f"<b>{APP_NAME}</b><p>Draw one freehand sketch, get a 3D mesh back, live.</p>"
            "<p>Method: Xiang et al., <i>Sketch-based modeling with a differentiable renderer</i>.</p>"
            f"<p>Models: {self.model_label.toolTip()}</p>",
        )

    # ------------------------------------------------------------------ autosave / close
    def offer_restore(self) -> bool:
        """If an autosave from an earlier session exists, ask to restore it. Returns True if restored."""
        if self.autosaver is None or not self.autosaver.has_recovery():
            return False
        answer = QMessageBox.question(
            self,
            "Restore sketch?",
            "Sketchmesh found a drawing that was not saved last time. Restore it?",
            QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
            QMessageBox.StandardButton.Yes,
        )
        if answer != QMessageBox.StandardButton.Yes:
            self.autosaver.discard()
            return False
        try:
            state, _size = self.autosaver.load_recovery()
        except SketchInputError as exc:
            self.show_message(f"Could not restore the autosave: {exc}")
            return False
        self.canvas.load_state(state, reset_history=True)
        self._saved_state = None
        self.show_message("Restored the unsaved sketch")
        self._update_actions()
        return True

    def _maybe_save(self, what: str) -> bool:
        """Ask Save / Discard / Cancel when there is unsaved work. Returns False to abort."""
        if not self.is_dirty:
            return True
        answer = QMessageBox.question(
            self,
            what,
            "The sketch has unsaved changes. Save them?",
            QMessageBox.StandardButton.Save | QMessageBox.StandardButton.Discard | QMessageBox.StandardButton.Cancel,
            QMessageBox.StandardButton.Save,
        )
        if answer == QMessageBox.StandardButton.Save:
            return self.save()
        return answer == QMessageBox.StandardButton.Discard

    def force_close(self) -> None:
        """Close without asking (headless runs); autosave is left in place if work is unsaved."""
        self._force_close = True
        self.close()

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 (Qt API)
        if self._closed:
            event.accept()
            return
        if not self._force_close:
            if not self._maybe_save("Quit Sketchmesh"):
                event.ignore()
                return
            if self.autosaver is not None:
                self.autosaver.discard()  # saved, or discarded by the user's choice
        elif self.autosaver is not None and self.autosaver.pending:
            self.autosaver.flush()
        if self._persist_settings:
            self.settings.geometry = bytes(self.saveGeometry().data())
            self.settings.window_state = bytes(self.saveState().data())
            self.settings.save()
        self.shutdown()
        event.accept()

    def shutdown(self) -> None:
        """Stop the worker thread, the probe and VTK (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self.latency_probe.stop()
        self.controller.shutdown()
        self.viewport.close_plotter()
        self.jobs.wait()  # an export or an autosave in progress is finished, not cut off
        if self.autosaver is not None:
            self.autosaver.wait()

    def wait_until_ready(self, timeout_s: float = READY_TIMEOUT_S) -> bool:
        """Before the first show: let the worker load the models and import what it needs, and
        the render thread compile its shaders, so none of that can stall the UI once shown.
        Returns False when it took longer than ``timeout_s`` (the window is usable anyway).

        Then tunes the interpreter for a responsive UI thread (process-wide): every object
        made so far (modules, Qt and VTK wrappers) is frozen out of the cyclic garbage
        collector, whose full passes over them cost the UI thread tens of milliseconds at
        unpredictable moments, and the lock switch interval drops to
        :data:`GIL_SWITCH_INTERVAL_S`.
        """
        try:
            return self._wait_until_ready(timeout_s)
        finally:
            gc.collect()
            gc.freeze()
            sys.setswitchinterval(min(sys.getswitchinterval(), GIL_SWITCH_INTERVAL_S))

    def _wait_until_ready(self, timeout_s: float) -> bool:
        loop = QEventLoop()
        deadline = QTimer()
        deadline.setSingleShot(True)
        deadline.timeout.connect(loop.quit)
        poll = QTimer()
        poll.setInterval(5)
        poll.timeout.connect(lambda: loop.quit() if self.is_ready else None)
        if self.is_ready:
            return True
        deadline.start(int(timeout_s * 1000))
        poll.start()
        loop.exec()
        poll.stop()
        return self.is_ready

    @property
    def is_ready(self) -> bool:
        """No model load in flight and the 3D view set up (or failed to set up)."""
        return not self.controller.busy and self.viewport.ready

    # ------------------------------------------------------------------ screenshots
    def grab_with_viewport(self) -> QImage:
        """The whole window as an image, with a 3D view rendered just now."""
        self.viewport.sync()
        return self.grab().toImage().convertToFormat(QImage.Format.Format_RGB888)

    def save_screenshot(self, path: str | os.PathLike) -> None:
        atomic_write_bytes(path, _png_bytes(self.grab_with_viewport()))


def _wait_for_result(window: MainWindow, timeout_s: float) -> tuple[bool, str]:
    """Spin an event loop until the window shows a mesh or reports a failure."""
    loop = QEventLoop()
    outcome: list[tuple[bool, str]] = []

    def ok(_rid: int) -> None:
        outcome.append((True, ""))
        loop.quit()

    def bad(_rid: int, msg: str) -> None:
        outcome.append((False, msg))
        loop.quit()

    window.meshUpdated.connect(ok)
    window.inferenceFailed.connect(bad)
    QTimer.singleShot(int(timeout_s * 1000), loop.quit)
    window.controller.flush()
    if not outcome:
        loop.exec()
    window.meshUpdated.disconnect(ok)
    window.inferenceFailed.disconnect(bad)
    if not outcome:
        return False, f"no mesh after {timeout_s:.0f} s (timeout)"
    return outcome[0]


def run_screenshot(sketch: str, out: str, models: str | None, timeout_s: float = SCREENSHOT_TIMEOUT_S) -> int:
    """Headless: open ``sketch``, infer, save a screenshot of the whole window to ``out``.

    Raises:
        SketchmeshError: missing/corrupt sketch, no models, inference failure or timeout.
    """
    from engine.preprocess import load_sketch_image  # noqa: PLC0415

    # fail fast, before the (seconds-long) VTK window is built
    folder = Path(models) if models else (Path(AppSettings.load().models_dir or bundled_models_dir()))
    if not models_present(folder):
        raise ModelError(no_models_message(folder))
    ink = load_sketch_image(sketch)
    if not np.any(ink > 0.5):
        raise SketchInputError(f"{sketch}: the image has no ink (a blank page?)")
    QApplication.instance() or QApplication([sys.argv[0]])
    window = MainWindow(models_dir=folder, autosave=False, persist_settings=False, debounce_ms=0)
    try:
        if window.engine is None:
            raise ModelError(window.model_problem or "no models loaded")
        window.resize(1280, 760)
        window.wait_until_ready()
        window.show()
        QApplication.processEvents()
        window.canvas.set_background_ink(ink)
        ok, message = _wait_for_result(window, timeout_s)
        if not ok:
            raise SketchmeshError(f"{sketch}: {message}")
        QApplication.processEvents()
        window.save_screenshot(out)
    finally:
        window.force_close()
        window.deleteLater()
        QApplication.processEvents()
    print(f"sketchmesh: screenshot written to {out}")
    return 0


def check_display(*, need_vtk_pixels: bool) -> None:
    """Fail with a clear message instead of Qt aborting (no display) or a blank 3D view.

    Raises:
        SketchmeshError: on Linux with neither DISPLAY nor WAYLAND_DISPLAY and no headless Qt
            platform chosen; or a screenshot requested under QT_QPA_PLATFORM=offscreen/minimal,
            where the VTK viewport renders nothing (see MEASUREMENTS.md).
    """
    if not sys.platform.startswith("linux"):
        return
    platform = os.environ.get("QT_QPA_PLATFORM", "").split(":")[0]
    headless = platform in ("offscreen", "minimal", "vnc", "eglfs", "linuxfb")
    if need_vtk_pixels and platform in ("offscreen", "minimal"):
        raise SketchmeshError(
            f"--screenshot needs an X display: the 3D view stays blank with QT_QPA_PLATFORM={platform} "
            "(run under xvfb-run instead)"
        )
    if not headless and not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise SketchmeshError("no display found (DISPLAY is not set): start the app in a desktop session, or run under xvfb-run")


def run(args) -> int:  # noqa: ANN001 (argparse.Namespace)
    """Entry point for ``sketchmesh`` with no subcommand (see app/main.py)."""
    if args.screenshot and not args.open and not getattr(args, "report", None):
        raise SketchInputError("--screenshot needs --open SKETCH (the sketch to render)")
    if args.models and not Path(args.models).is_dir():
        raise ModelError(f"{args.models}: no such model folder")
    if args.open and not Path(args.open).is_file():
        raise SketchInputError(f"{args.open}: no such file")
    report = getattr(args, "report", None)
    check_display(need_vtk_pixels=bool(args.screenshot or report))
    app = QApplication.instance() or QApplication([sys.argv[0]])
    app.setOrganizationName("Sketchmesh")
    app.setApplicationName("Sketchmesh")
    if report:
        from app.session import run_session  # noqa: PLC0415

        return run_session(args.open, report, args.screenshot, args.models)
    if args.screenshot:
        return run_screenshot(args.open, args.screenshot, args.models)
    window = MainWindow(models_dir=args.models)
    window.wait_until_ready()
    window.show()
    if args.open:
        window.open_path(args.open)
    QTimer.singleShot(0, window.offer_restore)
    return int(app.exec())
