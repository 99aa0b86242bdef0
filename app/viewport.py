"""The 3D viewport: VTK renders off screen on its own thread; a plain widget shows the frames.

Why not an OpenGL widget in the window: on a machine without a GPU (Mesa llvmpipe, the
2-core development machine, Xvfb) a ``QOpenGLWidget`` switches the whole top-level window to
OpenGL composition, and then *every* repaint of *any* widget (a canvas update under the pen,
a status-bar text) cost about 20 ms of the UI thread; a VTK render with 4x multisampling
cost 27 ms more, twice per mesh (measured with ``sketchmesh --report``). So VTK draws into an
off-screen render window (EGL or OSMesa on Linux, no X connection), reads the pixels back,
and :class:`MeshViewport` paints that image like any other widget.

Threads: :class:`_Scene` owns every VTK object and lives on the ``sketchmesh-render``
QThread (on macOS, where Cocoa GL contexts must stay on the main thread, it lives on the GUI
thread and renders from the event loop). The GUI thread talks to it only through queued
signals that carry immutable values (an :class:`engine.mesh.Mesh`, strings, numbers, event
tuples) and receives each frame as a QImage made on the render thread. Render requests are
coalesced: a burst of changes (a new mesh, a drag of the camera) costs one render.

One ``vtkPolyData`` and one actor are made at the first mesh and then updated in place: the
vertex and normal arrays are numpy buffers that VTK reads directly, overwritten for a mesh of
the same topology, so the camera stays where the user put it and nothing flickers. Smooth
shading uses per-vertex normals from :func:`engine.mesh.vertex_normals` as the active point
normals (Phong interpolation). The first render (shader compilation, a few hundred ms on a
software renderer) happens on the render thread while the window opens.

Rendering happens only when the widget is visible and something changed; a change while
hidden marks the view dirty and it renders on the next show. Orbit with the left mouse
button, pan with the middle (or Shift+left), zoom with the wheel or the right button (VTK's
trackball-camera style, driven by forwarded mouse events).

View presets, in the predicted mesh's view frame (engine.camera): ``sketch`` is the camera
that drew the sketch (on +Z at ``DEFAULT_DISTANCE`` looking at the origin, +Y up, the
training field of view); ``front`` looks from +Z fitted to the mesh; ``side`` from +X;
``top`` from +Y (with -Z up on screen); ``iso`` from (1, 1, 1).
"""

from __future__ import annotations

import atexit
import os
import sys
import time

import numpy as np
import shiboken6
from PySide6.QtCore import QEventLoop, QMetaObject, QObject, QRectF, Qt, QThread, QTimer, Signal, Slot
from PySide6.QtGui import QColor, QImage, QMouseEvent, QPainter, QPaintEvent, QResizeEvent, QShowEvent, QWheelEvent
from PySide6.QtWidgets import QSizePolicy, QWidget

from app.worker import lower_thread_priority, nice_from_env
from engine.camera import DEFAULT_DISTANCE, DEFAULT_FOV_DEG
from engine.mesh import Mesh, vertex_normals

VIEW_PRESETS = ("sketch", "front", "side", "top", "iso")
BACKGROUND_COLOR = (0.16, 0.17, 0.20)
MESH_COLOR = (0.82, 0.80, 0.76)
EDGE_COLOR = (0.25, 0.55, 0.95)

RENDER_ON_THREAD = sys.platform != "darwin"
"""Render on a thread of its own (macOS: on the GUI thread, from the event loop)."""

RENDER_NICE_ENV = "SKETCHMESH_RENDER_NICE"
RENDER_NICE = nice_from_env(RENDER_NICE_ENV, 0)
"""Nice value of the render thread (Linux; a software rasterizer's threads inherit it); 0 (the
default) leaves it at the app's priority. It was 5 until 2026-11-27: under load its frames took
twice as long (31 against 14 ms p50) for no gain in the UI's lag (``reproduce_models.sh session-nice``;
the VTK calls hold Python's GIL, so a slowed render thread can hold up the UI thread too)."""

SYNC_TIMEOUT_MS = 10_000
"""Longest wait for a frame in :meth:`MeshViewport.sync` (screenshots, tests)."""

SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "Software Rasterizer")
"""GL renderer names without a GPU: there multisampling costs 5x the render, so it is off."""

MULTISAMPLES_GPU = 4

_PRESET_DIRECTIONS = {
    "front": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "side": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    "top": ((0.0, 1.0, 0.0), (0.0, 0.0, -1.0)),
    "iso": ((1.0, 1.0, 1.0), (0.0, 1.0, 0.0)),
}

_BUTTONS = {Qt.MouseButton.LeftButton: "Left", Qt.MouseButton.MiddleButton: "Middle", Qt.MouseButton.RightButton: "Right"}


def faces_to_vtk(faces: np.ndarray) -> np.ndarray:
    """(F, 3) int triangle indices -> (4F,) int64 VTK cell array ``[3, i, j, k, 3, ...]``."""
    f = np.asarray(faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must be (F, 3), got {f.shape}")
    return np.hstack([np.full((len(f), 1), 3, dtype=np.int64), f]).ravel()


def _offscreen_render_window():  # noqa: ANN202 (vtkRenderWindow, imported lazily)
    """An off-screen VTK render window that needs no X connection where one exists.

    Linux: EGL, then OSMesa, then VTK's default; elsewhere VTK's default. ``VTK_DEFAULT_OPENGL_WINDOW``
    in the environment overrides the choice (VTK's own factory then decides).
    """
    import vtkmodules.vtkRenderingOpenGL2 as gl  # noqa: PLC0415
    from vtkmodules.vtkRenderingCore import vtkRenderWindow  # noqa: PLC0415

    names = ("vtkEGLRenderWindow", "vtkOSOpenGLRenderWindow") if sys.platform.startswith("linux") else ()
    if os.environ.get("VTK_DEFAULT_OPENGL_WINDOW"):
        names = ()
    for name in names:
        cls = getattr(gl, name, None)
        if cls is None:
            continue
        rw = cls()
        rw.SetOffScreenRendering(1)
        if rw.SupportsOpenGL():
            return rw
    rw = vtkRenderWindow()
    rw.SetOffScreenRendering(1)
    return rw


class _Scene(QObject):
    """Every VTK object of the viewport; lives on the render thread (see module docstring).

    Slots are called through queued signals only. ``frameReady(image, serial, info)`` carries
    an RGB888 QImage at device pixels, the newest render request it answers and a dict:
    ``render_ms`` (render + read-back on this thread), ``camera`` ((position, focal point,
    view up)) and ``visible`` (whether a mesh is shown).
    """

    frameReady = Signal(object, int, object)
    failed = Signal(str)
    readied = Signal()

    def __init__(self) -> None:
        super().__init__()
        self._rw = None
        self._ren = None
        self._iren = None
        self._actor = None
        self._poly = None
        self._points_np: np.ndarray | None = None
        self._normals_np: np.ndarray | None = None
        self._vtk_keep: list = []  # VTK arrays that borrow the numpy buffers above
        self._faces: np.ndarray | None = None
        self._has_mesh = False
        self._wireframe = False
        self._size = (320, 240)
        self._want = 0
        self._scheduled = False
        self._broken: str | None = None
        self.topology_changes = 0

    # ---- setup / teardown ------------------------------------------------------------------
    @Slot(int, int)
    def setup(self, width: int, height: int) -> None:
        try:
            self._setup(width, height)
        except Exception as exc:  # noqa: BLE001 (no GL: the view says so, the app goes on)
            self._broken = f"3D view unavailable: {type(exc).__name__}: {exc}"
            self.failed.emit(self._broken)
        self.readied.emit()

    def _setup(self, width: int, height: int) -> None:
        if RENDER_ON_THREAD:
            lower_thread_priority(RENDER_NICE)  # before GL starts its rasterizer threads: they inherit it
        import vtkmodules.vtkInteractionStyle  # noqa: F401, PLC0415 (registers the styles)
        from vtkmodules.vtkInteractionStyle import vtkInteractorStyleTrackballCamera  # noqa: PLC0415
        from vtkmodules.vtkRenderingCore import vtkActor, vtkLightKit, vtkPolyDataMapper, vtkRenderer  # noqa: PLC0415
        from vtkmodules.vtkRenderingUI import vtkGenericRenderWindowInteractor  # noqa: PLC0415

        self._size = (max(1, int(width)), max(1, int(height)))
        rw = _offscreen_render_window()
        rw.SetSize(*self._size)
        rw.SetMultiSamples(0)
        rw.Initialize()
        caps = rw.ReportCapabilities() or ""
        if not any(s in caps for s in SOFTWARE_RENDERERS):
            rw.SetMultiSamples(MULTISAMPLES_GPU)
        ren = vtkRenderer()
        ren.SetBackground(*BACKGROUND_COLOR)
        rw.AddRenderer(ren)
        vtkLightKit().AddLightsToRenderer(ren)
        iren = vtkGenericRenderWindowInteractor()
        iren.SetRenderWindow(rw)
        iren.EnableRenderOff()  # the style moves the camera; this object renders, once per batch
        iren.SetInteractorStyle(vtkInteractorStyleTrackballCamera())
        iren.Initialize()
        iren.UpdateSize(*self._size)
        mapper = vtkPolyDataMapper()
        mapper.ScalarVisibilityOff()
        actor = vtkActor()
        actor.SetMapper(mapper)
        actor.SetVisibility(False)
        prop = actor.GetProperty()
        prop.SetSpecular(0.25)
        prop.SetSpecularPower(20.0)
        prop.SetDiffuse(0.85)
        prop.SetAmbient(0.12)
        prop.SetInterpolationToPhong()
        ren.AddActor(actor)
        self._rw, self._ren, self._iren, self._actor = rw, ren, iren, actor
        self._apply_style()
        self.set_view("sketch")
        # warm up: compile the shaders of a lit, normal-shaded mesh now, not at the first result
        from engine.icosphere import icosphere  # noqa: PLC0415

        self.set_mesh(icosphere(1, 0.01))
        self._rw.Render()
        self.set_mesh(None)
        self.topology_changes = 0

    @Slot()
    def finalize(self) -> None:
        """Release the GL resources on the thread that made them, then end that thread's loop."""
        if self._rw is not None:
            self._rw.Finalize()
        self._rw = self._ren = self._iren = self._actor = self._poly = None
        self._vtk_keep.clear()
        if RENDER_ON_THREAD:
            QThread.currentThread().quit()

    # ---- scene changes ------------------------------------------------------------------------
    @Slot(object)
    def set_mesh(self, mesh: Mesh | None) -> None:
        if self._actor is None:
            return
        if mesh is None or mesh.num_faces == 0:
            self._actor.SetVisibility(False)
            self._has_mesh = False
            return
        verts = np.asarray(mesh.vertices, dtype=np.float32)
        normals = vertex_normals(mesh.vertices, mesh.faces).astype(np.float32)
        same = self._faces is not None and self._faces.shape == mesh.faces.shape and np.array_equal(self._faces, mesh.faces)
        if same and self._points_np is not None and self._points_np.shape == verts.shape:
            self._points_np[:] = verts  # same topology: VTK reads these buffers, so in place
            self._normals_np[:] = normals
            self._vtk_keep[0].Modified()
            self._vtk_keep[1].Modified()
            self._poly.GetPoints().Modified()
            self._poly.Modified()
        else:
            self._build(verts, normals, np.array(mesh.faces))
        self._actor.SetVisibility(True)
        self._has_mesh = True

    def _build(self, verts: np.ndarray, normals: np.ndarray, faces: np.ndarray) -> None:
        from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray  # noqa: PLC0415
        from vtkmodules.vtkCommonCore import vtkPoints  # noqa: PLC0415
        from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData  # noqa: PLC0415

        self._points_np = np.ascontiguousarray(verts, dtype=np.float32).copy()
        self._normals_np = np.ascontiguousarray(normals, dtype=np.float32).copy()
        vtk_pts = numpy_to_vtk(self._points_np, deep=False)
        vtk_nrm = numpy_to_vtk(self._normals_np, deep=False)
        vtk_nrm.SetName("Normals")
        self._vtk_keep = [vtk_pts, vtk_nrm]
        pts = vtkPoints()
        pts.SetData(vtk_pts)
        cells = vtkCellArray()
        cells.ImportLegacyFormat(numpy_to_vtkIdTypeArray(faces_to_vtk(faces), deep=True))
        poly = vtkPolyData()
        poly.SetPoints(pts)
        poly.SetPolys(cells)
        poly.GetPointData().SetNormals(vtk_nrm)
        self._poly = poly
        self._actor.GetMapper().SetInputData(poly)
        self._faces = faces
        self.topology_changes += 1

    @Slot(bool)
    def set_wireframe(self, on: bool) -> None:
        self._wireframe = bool(on)
        self._apply_style()

    def _apply_style(self) -> None:
        if self._actor is None:
            return
        prop = self._actor.GetProperty()
        if self._wireframe:
            prop.SetRepresentationToWireframe()
            prop.SetColor(*EDGE_COLOR)
            prop.SetLineWidth(1.0)
        else:
            prop.SetRepresentationToSurface()
            prop.SetColor(*MESH_COLOR)

    @Slot(str)
    def set_view(self, preset: str) -> None:
        if self._ren is None:
            return
        cam = self._ren.GetActiveCamera()
        cam.SetParallelProjection(False)
        cam.SetFocalPoint(0.0, 0.0, 0.0)
        cam.SetViewAngle(DEFAULT_FOV_DEG)
        if preset == "sketch":
            cam.SetPosition(0.0, 0.0, DEFAULT_DISTANCE)
            cam.SetViewUp(0.0, 1.0, 0.0)
        else:
            direction, up = _PRESET_DIRECTIONS[preset]
            d = np.asarray(direction, dtype=np.float64)
            d /= np.linalg.norm(d)
            cam.SetPosition(*(d * DEFAULT_DISTANCE))
            cam.SetViewUp(*up)
            if self._has_mesh:
                self._ren.ResetCamera()  # fit the mesh, keeping the direction
        self._ren.ResetCameraClippingRange()

    @Slot(int, int)
    def resize(self, width: int, height: int) -> None:
        self._size = (max(1, int(width)), max(1, int(height)))
        if self._rw is not None:
            self._rw.SetSize(*self._size)
            self._iren.UpdateSize(*self._size)

    @Slot(object)
    def interact(self, event: tuple) -> None:
        """A forwarded mouse event: ``(kind, button, x, y, ctrl, shift)`` in device pixels,
        y down; kind is press / move / release / wheel (button "Forward" or "Backward")."""
        if self._iren is None:
            return
        kind, button, x, y, ctrl, shift = event
        self._iren.SetEventInformationFlipY(int(x), int(y), int(ctrl), int(shift))
        if kind == "move":
            self._iren.MouseMoveEvent()
        elif kind == "press":
            getattr(self._iren, f"{button}ButtonPressEvent")()
        elif kind == "release":
            getattr(self._iren, f"{button}ButtonReleaseEvent")()
        elif kind == "wheel":
            getattr(self._iren, f"MouseWheel{button}Event")()
        self._schedule()

    # ---- rendering ------------------------------------------------------------------------------
    @Slot(int)
    def request_render(self, serial: int) -> None:
        self._want = max(self._want, int(serial))
        self._schedule()

    def _schedule(self) -> None:
        if not self._scheduled:
            self._scheduled = True
            QTimer.singleShot(0, self._render)  # after the events already queued: one render per burst

    def _render(self) -> None:
        self._scheduled = False
        if self._rw is None:
            if self._broken is not None:
                self.frameReady.emit(None, self._want, {"render_ms": 0.0, "camera": None, "visible": False})
            return
        from vtkmodules.util.numpy_support import vtk_to_numpy  # noqa: PLC0415
        from vtkmodules.vtkCommonCore import vtkUnsignedCharArray  # noqa: PLC0415

        t0 = time.perf_counter()
        self._ren.ResetCameraClippingRange()
        self._rw.Render()
        w, h = self._rw.GetSize()
        buf = vtkUnsignedCharArray()
        self._rw.GetPixelData(0, 0, w - 1, h - 1, 0, buf, 0)
        rgb = np.ascontiguousarray(vtk_to_numpy(buf).reshape(h, w, 3)[::-1])  # VTK rows go up
        image = QImage(rgb.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy()
        cam = self._ren.GetActiveCamera()
        info = {
            "render_ms": (time.perf_counter() - t0) * 1e3,
            "camera": (tuple(cam.GetPosition()), tuple(cam.GetFocalPoint()), tuple(cam.GetViewUp())),
            "visible": self._has_mesh,
            "topology_changes": self.topology_changes,
            "representation": self._actor.GetProperty().GetRepresentation(),
        }
        self.frameReady.emit(image, self._want, info)


_RUNNING: dict[int, tuple[_Scene, QThread]] = {}
"""Render threads started and not yet stopped, by id of their thread: stopped at interpreter
exit (:func:`_stop_all_render_threads`) if their viewport was never closed, since Qt aborts
the process when a running QThread is destroyed. Holding them here also keeps their Python
wrappers (and so the C++ objects) alive until they are stopped."""


def _stop_render_thread(scene: _Scene, thread: QThread) -> None:
    """Finalize the scene on its thread and wait for that thread to end (idempotent; a thread or
    scene whose C++ object is already gone, as at interpreter exit, is left alone)."""
    _RUNNING.pop(id(thread), None)
    if not (shiboken6.isValid(thread) and shiboken6.isValid(scene)):
        return
    if thread.isFinished() or not thread.isRunning():
        return
    QMetaObject.invokeMethod(scene, "finalize", Qt.ConnectionType.QueuedConnection)
    if not thread.wait(SYNC_TIMEOUT_MS):
        thread.quit()
        thread.wait(SYNC_TIMEOUT_MS)


@atexit.register
def _stop_all_render_threads() -> None:
    """Interpreter exit with a viewport still open (a script that never closed its window):
    stop its render thread before Python tears the wrappers down in an arbitrary order."""
    for scene, thread in list(_RUNNING.values()):
        _stop_render_thread(scene, thread)


class MeshViewport(QWidget):
    """Shows one predicted mesh, lit and smooth-shaded, with orbit/pan/zoom.

    The GUI thread only forwards changes and paints the newest frame (module docstring).

    Attributes:
        render_count: frames rendered for this view and delivered (tests check that hidden
            or unchanged views do not render).
        mesh_updates: meshes handed to the renderer.
        step_ms: UI-thread cost per step, in ms: ``mesh_upload`` (handing a mesh over) and
            ``frame`` (taking a frame in). Read by ``sketchmesh --report``.
        render_ms: render + read-back per frame, in ms, measured on the render thread.
    """

    _setup_sig = Signal(int, int)
    _mesh_sig = Signal(object)
    _wire_sig = Signal(bool)
    _view_sig = Signal(str)
    _size_sig = Signal(int, int)
    _event_sig = Signal(object)
    _render_sig = Signal(int)
    _finalize_sig = Signal()
    frameShown = Signal(int)
    """A new frame arrived (its serial); the widget repaints."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent, True)
        self.setMinimumSize(64, 64)
        self._image: QImage | None = None
        self._message: str | None = None
        self._wireframe = False
        self._dirty = True
        self._has_mesh = False
        self._closed = False
        self._requested = 0
        self._delivered = 0
        self._info: dict = {}
        self._last_mesh: Mesh | None = None
        self._ready = False
        self.render_count = 0
        self.mesh_updates = 0
        self.step_ms: dict[str, list[float]] = {"mesh_upload": [], "frame": []}
        self.render_ms: list[float] = []

        self._scene = _Scene()
        self._thread: QThread | None = None
        if RENDER_ON_THREAD:
            self._thread = QThread()
            self._thread.setObjectName("sketchmesh-render")
            self._scene.moveToThread(self._thread)
            self._thread.start()
        q = Qt.ConnectionType.QueuedConnection
        self._setup_sig.connect(self._scene.setup, q)
        self._mesh_sig.connect(self._scene.set_mesh, q)
        self._wire_sig.connect(self._scene.set_wireframe, q)
        self._view_sig.connect(self._scene.set_view, q)
        self._size_sig.connect(self._scene.resize, q)
        self._event_sig.connect(self._scene.interact, q)
        self._render_sig.connect(self._scene.request_render, q)
        self._finalize_sig.connect(self._scene.finalize, q)
        self._scene.frameReady.connect(self._on_frame, q)
        self._scene.failed.connect(self._on_failed, q)
        self._scene.readied.connect(self._on_readied, q)
        self._on_destroyed = None
        if self._thread is not None:  # a viewport destroyed without close_plotter() still stops its thread
            _RUNNING[id(self._thread)] = (self._scene, self._thread)
            self._on_destroyed = self.destroyed.connect(
                lambda *_a, scene=self._scene, thread=self._thread: _stop_render_thread(scene, thread)
            )
        w, h = self._device_size()
        self._setup_sig.emit(w, h)

    def _device_size(self) -> tuple[int, int]:
        dpr = self.devicePixelRatioF()
        return max(1, round(self.width() * dpr)), max(1, round(self.height() * dpr))

    # ---- mesh -----------------------------------------------------------------------------
    @property
    def has_mesh(self) -> bool:
        return self._has_mesh

    @property
    def mesh(self) -> Mesh | None:
        """The mesh shown (None before the first mesh or after clearing)."""
        return self._last_mesh if self._has_mesh else None

    @property
    def topology_changes(self) -> int:
        """How often the renderer had to rebuild its arrays (a new face list), as of the last frame."""
        return int(self._info.get("topology_changes", 0))

    def set_mesh(self, mesh: Mesh | None) -> None:
        """Show ``mesh`` (updated in place on the render thread), or nothing for None / no faces."""
        if self._closed:
            return
        t0 = time.perf_counter()
        if mesh is None or mesh.num_faces == 0:
            if self._has_mesh:
                self._has_mesh = False
                self._mesh_sig.emit(None)
                self._changed()
            return
        if not isinstance(mesh, Mesh):
            raise TypeError(f"set_mesh needs an engine.mesh.Mesh, got {type(mesh).__name__}")
        self._last_mesh = mesh
        self._mesh_sig.emit(mesh)  # a frozen value: nothing is shared that either side changes
        self._has_mesh = True
        self.mesh_updates += 1
        self._changed()
        self.step_ms["mesh_upload"].append((time.perf_counter() - t0) * 1e3)

    # ---- view -----------------------------------------------------------------------------
    @property
    def wireframe(self) -> bool:
        return self._wireframe

    @property
    def representation(self) -> int | None:
        """VTK representation of the mesh in the last frame (1 wireframe, 2 surface)."""
        return self._info.get("representation")

    def set_wireframe(self, on: bool) -> None:
        self._wireframe = bool(on)
        self._wire_sig.emit(self._wireframe)
        self._changed()

    def set_view(self, preset: str, *, render: bool = True) -> None:
        """Move the camera to a preset (see module docstring); keeps the mesh."""
        if preset not in VIEW_PRESETS:
            raise ValueError(f"view preset must be one of {VIEW_PRESETS}, got {preset!r}")
        self._view_sig.emit(preset)
        if render:
            self._changed()

    def reset_view(self) -> None:
        """Back to the sketch's view."""
        self.set_view("sketch")

    def camera_position(self) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
        """(position, focal point, view up) of the current camera (waits for the renderer)."""
        self.sync()
        cam = self._info.get("camera")
        if cam is None:
            raise RuntimeError("the 3D view has no camera (no OpenGL?)")
        return cam

    # ---- rendering --------------------------------------------------------------------------
    def _changed(self) -> None:
        self._dirty = True
        if self.isVisible():
            self.render_now()

    def render_now(self) -> None:
        """Ask for a render if visible and dirty (no-op otherwise); the frame comes later."""
        if self._closed or not self._dirty or not self.isVisible():
            return
        self._dirty = False
        self._requested += 1
        self._render_sig.emit(self._requested)

    @property
    def idle(self) -> bool:
        """True when every render asked for has been delivered."""
        return self._delivered >= self._requested

    def sync(self, timeout_ms: int = SYNC_TIMEOUT_MS) -> bool:
        """Render now (even if nothing changed) and wait for that frame; False on timeout."""
        if self._closed:
            return False
        self._requested += 1
        target = self._requested
        self._render_sig.emit(target)
        if self._delivered >= target:
            return True
        loop = QEventLoop()
        done = self.frameShown.connect(lambda s: loop.quit() if s >= target else None)
        timer = QTimer.singleShot(int(timeout_ms), loop.quit)
        del timer
        loop.exec()
        self.frameShown.disconnect(done)
        return self._delivered >= target

    @Slot(object, int, object)
    def _on_frame(self, image: QImage | None, serial: int, info: dict) -> None:
        t0 = time.perf_counter()
        if self._closed:
            return
        if image is not None:
            image.setDevicePixelRatio(self.devicePixelRatioF())
            self._image = image
            self.render_count += 1
            self._info = info
            self.render_ms.append(float(info.get("render_ms", 0.0)))
        self._delivered = max(self._delivered, serial)
        self.update()
        self.step_ms["frame"].append((time.perf_counter() - t0) * 1e3)
        self.frameShown.emit(serial)

    @property
    def ready(self) -> bool:
        """The renderer is set up and its shaders compiled (or it failed and says so)."""
        return self._ready

    @Slot()
    def _on_readied(self) -> None:
        self._ready = True

    @Slot(str)
    def _on_failed(self, message: str) -> None:
        self._message = message
        self.update()

    def paintEvent(self, event: QPaintEvent) -> None:  # noqa: N802 (Qt API)
        p = QPainter(self)
        try:
            if self._image is None:
                p.fillRect(self.rect(), QColor.fromRgbF(*BACKGROUND_COLOR))
            else:
                p.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform, True)
                p.drawImage(QRectF(self.rect()), self._image)  # a stale size while resizing: scaled
            if self._message:
                p.setPen(QColor(220, 220, 220))
                p.drawText(self.rect(), Qt.AlignmentFlag.AlignCenter | Qt.TextFlag.TextWordWrap, self._message)
        finally:
            p.end()

    def showEvent(self, event: QShowEvent) -> None:  # noqa: N802 (Qt API)
        super().showEvent(event)
        self.render_now()

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802 (Qt API)
        super().resizeEvent(event)
        self._size_sig.emit(*self._device_size())
        self._changed()

    def screenshot(self) -> np.ndarray:
        """(H, W, 3) uint8 image of the 3D view as VTK rendered it (renders and waits)."""
        if self._closed:
            raise RuntimeError("the viewport is closed")
        if not self.sync() or self._image is None:
            raise RuntimeError(self._message or "the 3D view did not render in time")
        img = self._image.convertToFormat(QImage.Format.Format_RGB888)
        h, w, bpl = img.height(), img.width(), img.bytesPerLine()
        return np.frombuffer(img.constBits(), np.uint8, count=h * bpl).reshape(h, bpl)[:, : 3 * w].reshape(h, w, 3).copy()

    # ---- mouse: forwarded to VTK's trackball style on the render thread ---------------------------
    def _forward(self, kind: str, button: str, event: QMouseEvent | QWheelEvent) -> None:
        dpr = self.devicePixelRatioF()
        pos = event.position()
        mods = event.modifiers()
        self._event_sig.emit((
            kind, button, round(pos.x() * dpr), round(pos.y() * dpr),
            bool(mods & Qt.KeyboardModifier.ControlModifier), bool(mods & Qt.KeyboardModifier.ShiftModifier),
        ))
        self._requested += 1  # the renderer renders after each batch of events
        self._render_sig.emit(self._requested)

    def mousePressEvent(self, event: QMouseEvent) -> None:  # noqa: N802 (Qt API)
        button = _BUTTONS.get(event.button())
        if button is None:
            return super().mousePressEvent(event)
        self._forward("press", button, event)
        event.accept()

    def mouseMoveEvent(self, event: QMouseEvent) -> None:  # noqa: N802 (Qt API)
        self._forward("move", "", event)
        event.accept()

    def mouseReleaseEvent(self, event: QMouseEvent) -> None:  # noqa: N802 (Qt API)
        button = _BUTTONS.get(event.button())
        if button is None:
            return super().mouseReleaseEvent(event)
        self._forward("release", button, event)
        event.accept()

    def wheelEvent(self, event: QWheelEvent) -> None:  # noqa: N802 (Qt API)
        dy = event.angleDelta().y()
        if dy:
            self._forward("wheel", "Forward" if dy > 0 else "Backward", event)
        event.accept()

    # ---- lifetime ----------------------------------------------------------------------------------
    def close_plotter(self) -> None:
        """Release VTK and stop the render thread (call before the window is destroyed)."""
        if self._closed:
            return
        self._closed = True
        if self._thread is not None:
            self._finalize_sig.emit()  # the scene quits its thread when done
            if not self._thread.wait(SYNC_TIMEOUT_MS):
                self._thread.quit()
                self._thread.wait(SYNC_TIMEOUT_MS)
            if self._thread.isFinished():
                # stopped: drop the destructor-time safety net, which would otherwise run at
                # interpreter exit on a thread wrapper Python may already have deleted
                _RUNNING.pop(id(self._thread), None)
                if self._on_destroyed is not None:
                    self.destroyed.disconnect(self._on_destroyed)
                    self._on_destroyed = None
        else:
            self._scene.finalize()
