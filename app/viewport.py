"""The 3D viewport: a pyvistaqt QtInteractor wrapped (composed, not subclassed) in a QWidget.

One ``pyvista.PolyData`` and one actor are created at the first mesh and then updated in
place (points, faces and vertex normals replaced), so the camera stays where the user put it
and nothing flickers. Smooth shading uses per-vertex normals computed by
:func:`engine.mesh.vertex_normals` and stored as the active point normals (VTK Gouraud/Phong
interpolation), not by pyvista's ``smooth_shading`` (which would copy the mesh).

Rendering happens only when the widget is visible and something changed; a change while
hidden marks the view dirty and it renders on the next show.

View presets, in the predicted mesh's view frame (engine.camera): ``sketch`` is the camera
that drew the sketch (on +Z at ``DEFAULT_DISTANCE`` looking at the origin, +Y up, the
training field of view); ``front`` looks from +Z fitted to the mesh; ``side`` from +X;
``top`` from +Y (with -Z up on screen); ``iso`` from (1, 1, 1).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtGui import QShowEvent
from PySide6.QtWidgets import QVBoxLayout, QWidget

from engine.camera import DEFAULT_DISTANCE, DEFAULT_FOV_DEG
from engine.mesh import Mesh, vertex_normals

VIEW_PRESETS = ("sketch", "front", "side", "top", "iso")
BACKGROUND_COLOR = (0.16, 0.17, 0.20)
MESH_COLOR = (0.82, 0.80, 0.76)
EDGE_COLOR = (0.25, 0.55, 0.95)

_PRESET_DIRECTIONS = {
    "front": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "side": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    "top": ((0.0, 1.0, 0.0), (0.0, 0.0, -1.0)),
    "iso": ((1.0, 1.0, 1.0), (0.0, 1.0, 0.0)),
}


def faces_to_vtk(faces: np.ndarray) -> np.ndarray:
    """(F, 3) int triangle indices -> (4F,) int64 VTK cell array ``[3, i, j, k, 3, ...]``."""
    f = np.asarray(faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must be (F, 3), got {f.shape}")
    return np.hstack([np.full((len(f), 1), 3, dtype=np.int64), f]).ravel()


class MeshViewport(QWidget):
    """Shows one predicted mesh, lit and smooth-shaded, with orbit/pan/zoom (VTK trackball).

    Attributes:
        render_count: how many times this wrapper asked VTK to render (tests check that
            hidden or unchanged views do not render).
    """

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        import pyvista as pv  # noqa: PLC0415 (heavy: loaded when the window is built)
        from pyvistaqt import QtInteractor  # noqa: PLC0415

        self._pv = pv
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.plotter = QtInteractor(self, auto_update=False)
        layout.addWidget(self.plotter)
        self.plotter.set_background(BACKGROUND_COLOR)
        self.plotter.enable_trackball_style()
        self._poly = None
        self._actor = None
        self._faces: np.ndarray | None = None
        self._wireframe = False
        self._dirty = True
        self._has_mesh = False
        self._camera_set = False
        self.render_count = 0
        self.mesh_updates = 0
        self.topology_changes = 0
        self._closed = False
        self.set_view("sketch", render=False)

    # ---- mesh -----------------------------------------------------------------------------
    @property
    def has_mesh(self) -> bool:
        return self._has_mesh

    @property
    def polydata(self):  # noqa: ANN201 (pyvista.PolyData, imported lazily)
        """The single PolyData shown (None before the first mesh)."""
        return self._poly

    def set_mesh(self, mesh: Mesh | None) -> None:
        """Show ``mesh`` (updated in place), or nothing for None / a mesh with no faces."""
        if self._closed:
            return
        if mesh is None or mesh.num_faces == 0:
            if self._actor is not None and self._has_mesh:
                self._actor.SetVisibility(False)
                self._has_mesh = False
                self._changed()
            return
        if not isinstance(mesh, Mesh):
            raise TypeError(f"set_mesh needs an engine.mesh.Mesh, got {type(mesh).__name__}")
        verts = np.asarray(mesh.vertices, dtype=np.float32)
        normals = vertex_normals(mesh.vertices, mesh.faces).astype(np.float32)
        if self._poly is None:
            pv = self._pv
            self._poly = pv.PolyData(verts.copy(), faces_to_vtk(mesh.faces))
            self._poly.point_data.set_array(normals, "Normals")
            self._poly.point_data.active_normals_name = "Normals"
            self._actor = self.plotter.add_mesh(
                self._poly,
                color=MESH_COLOR,
                smooth_shading=False,  # we supply the vertex normals; pyvista's would copy the mesh
                specular=0.25,
                specular_power=20.0,
                diffuse=0.85,
                ambient=0.12,
                show_edges=False,
                reset_camera=False,
                name="prediction",
            )
            self._actor.GetProperty().SetInterpolationToPhong()
            self._faces = np.array(mesh.faces)
            self.topology_changes += 1
        else:
            if self._faces is None or self._faces.shape != mesh.faces.shape or not np.array_equal(self._faces, mesh.faces):
                self._poly.points = verts.copy()
                self._poly.faces = faces_to_vtk(mesh.faces)
                self._faces = np.array(mesh.faces)
                self.topology_changes += 1
            else:
                self._poly.points[:] = verts  # same topology: in place
            self._poly.point_data.set_array(normals, "Normals")
            self._poly.point_data.active_normals_name = "Normals"
            self._poly.Modified()
        self._actor.SetVisibility(True)
        self._apply_style()
        self._has_mesh = True
        self.mesh_updates += 1
        self._changed()

    # ---- view -----------------------------------------------------------------------------
    @property
    def wireframe(self) -> bool:
        return self._wireframe

    def set_wireframe(self, on: bool) -> None:
        self._wireframe = bool(on)
        self._apply_style()
        self._changed()

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

    def set_view(self, preset: str, *, render: bool = True) -> None:
        """Move the camera to a preset (see module docstring); keeps the mesh."""
        if preset not in VIEW_PRESETS:
            raise ValueError(f"view preset must be one of {VIEW_PRESETS}, got {preset!r}")
        cam = self.plotter.camera
        cam.SetParallelProjection(False)
        if preset == "sketch":
            cam.SetFocalPoint(0.0, 0.0, 0.0)
            cam.SetPosition(0.0, 0.0, DEFAULT_DISTANCE)
            cam.SetViewUp(0.0, 1.0, 0.0)
            cam.SetViewAngle(DEFAULT_FOV_DEG)
            self.plotter.renderer.ResetCameraClippingRange()
        else:
            direction, up = _PRESET_DIRECTIONS[preset]
            d = np.asarray(direction, dtype=np.float64)
            d /= np.linalg.norm(d)
            cam.SetFocalPoint(0.0, 0.0, 0.0)
            cam.SetPosition(*(d * DEFAULT_DISTANCE))
            cam.SetViewUp(*up)
            cam.SetViewAngle(DEFAULT_FOV_DEG)
            if self._has_mesh:
                self.plotter.renderer.ResetCamera()  # fit the mesh, keeping the direction
            self.plotter.renderer.ResetCameraClippingRange()
        self._camera_set = True
        if render:
            self._changed()

    def reset_view(self) -> None:
        """Back to the sketch's view."""
        self.set_view("sketch")

    def camera_position(self) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
        """(position, focal point, view up) of the current camera."""
        cam = self.plotter.camera
        return tuple(cam.GetPosition()), tuple(cam.GetFocalPoint()), tuple(cam.GetViewUp())

    # ---- rendering --------------------------------------------------------------------------
    def _changed(self) -> None:
        self._dirty = True
        if self.isVisible():
            self.render_now()

    def render_now(self) -> None:
        """Render if visible and dirty (no-op otherwise)."""
        if self._closed or not self._dirty or not self.isVisible():
            return
        self.plotter.renderer.ResetCameraClippingRange()
        self.plotter.render()
        self._dirty = False
        self.render_count += 1

    def showEvent(self, event: QShowEvent) -> None:  # noqa: N802 (Qt API)
        super().showEvent(event)
        self.render_now()

    def screenshot(self) -> np.ndarray:
        """(H, W, 3) uint8 image of the 3D view as VTK rendered it (forces a render)."""
        if self._closed:
            raise RuntimeError("the viewport is closed")
        self._dirty = True
        self.render_now()
        img = self.plotter.screenshot(return_img=True)
        return np.asarray(img, dtype=np.uint8)[..., :3]

    def close_plotter(self) -> None:
        """Release VTK resources (call before the window is destroyed)."""
        if self._closed:
            return
        self._closed = True
        self.plotter.close()
        # pyvistaqt keeps Python wrappers of its GL context and of the widget's internal
        # QSurface. When Qt deletes those C++ objects before the context's aboutToBeDestroyed
        # reaches pyvistaqt, the stale wrappers stay registered, and PySide hands them out for
        # new objects at the same address (seen: a QMenu typed QSurface). Drop them now.
        forget = getattr(self.plotter, "_forget_context", None)
        if callable(forget):
            forget()
