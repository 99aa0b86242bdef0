"""Persistent user settings (QSettings, INI format, user scope).

Stored: window geometry and dock/toolbar state, brush width, last folders, the model folder
and a few view toggles. Everything is read once into an :class:`AppSettings` dataclass and
written back explicitly; nothing else in the app touches QSettings.

Tests isolate the location with ``QSettings.setPath(QSettings.IniFormat, QSettings.UserScope,
tmp_path)`` (see ``tests/gui_helpers.py``); subprocesses get ``XDG_CONFIG_HOME``.
"""

from __future__ import annotations

from dataclasses import dataclass

from PySide6.QtCore import QByteArray, QSettings

ORGANIZATION = "Sketchmesh"
APPLICATION = "Sketchmesh"

MIN_BRUSH_WIDTH = 0.5
MAX_BRUSH_WIDTH = 40.0
DEFAULT_BRUSH_WIDTH = 3.0


def open_settings() -> QSettings:
    """The app's QSettings store (INI file under the user-scope path Qt resolves)."""
    return QSettings(QSettings.Format.IniFormat, QSettings.Scope.UserScope, ORGANIZATION, APPLICATION)


def _clamp_width(value: object) -> float:
    try:
        w = float(value)
    except (TypeError, ValueError):
        return DEFAULT_BRUSH_WIDTH
    if not (w == w) or w in (float("inf"), float("-inf")):  # NaN / inf from a hand-edited file
        return DEFAULT_BRUSH_WIDTH
    return min(max(w, MIN_BRUSH_WIDTH), MAX_BRUSH_WIDTH)


def _as_bool(value: object, default: bool) -> bool:
    if value is None:
        return default
    if isinstance(value, bool):
        return value
    return str(value).strip().lower() in ("1", "true", "yes", "on")


@dataclass
class AppSettings:
    """Everything the app persists between sessions.

    Attributes:
        geometry: QMainWindow.saveGeometry() bytes, or empty.
        window_state: QMainWindow.saveState() bytes, or empty.
        brush_width: pen width in canvas pixels, clamped to [MIN_BRUSH_WIDTH, MAX_BRUSH_WIDTH].
        eraser_width: eraser width in canvas pixels, same range.
        last_open_dir, last_save_dir, last_export_dir: folders last used in file dialogs ("" = none).
        models_dir: the model folder chosen by the user ("" = the bundled models).
        show_guide: draw the framing guide on the canvas.
        wireframe: show the mesh as a wireframe.
    """

    geometry: bytes = b""
    window_state: bytes = b""
    brush_width: float = DEFAULT_BRUSH_WIDTH
    eraser_width: float = 12.0
    last_open_dir: str = ""
    last_save_dir: str = ""
    last_export_dir: str = ""
    models_dir: str = ""
    show_guide: bool = True
    wireframe: bool = False

    @staticmethod
    def load(store: QSettings | None = None) -> AppSettings:
        """Read the settings; missing or malformed values fall back to defaults."""
        s = store if store is not None else open_settings()

        def text(key: str) -> str:
            v = s.value(key, "")
            return v if isinstance(v, str) else ""

        def blob(key: str) -> bytes:
            v = s.value(key)
            if isinstance(v, QByteArray):
                return bytes(v.data())
            if isinstance(v, (bytes, bytearray)):
                return bytes(v)
            return b""

        return AppSettings(
            geometry=blob("window/geometry"),
            window_state=blob("window/state"),
            brush_width=_clamp_width(s.value("brush/width", DEFAULT_BRUSH_WIDTH)),
            eraser_width=_clamp_width(s.value("brush/eraser_width", 12.0)),
            last_open_dir=text("folders/open"),
            last_save_dir=text("folders/save"),
            last_export_dir=text("folders/export"),
            models_dir=text("models/folder"),
            show_guide=_as_bool(s.value("view/show_guide"), True),
            wireframe=_as_bool(s.value("view/wireframe"), False),
        )

    def save(self, store: QSettings | None = None) -> None:
        """Write every field and flush to disk."""
        s = store if store is not None else open_settings()
        s.setValue("window/geometry", QByteArray(self.geometry))
        s.setValue("window/state", QByteArray(self.window_state))
        s.setValue("brush/width", float(_clamp_width(self.brush_width)))
        s.setValue("brush/eraser_width", float(_clamp_width(self.eraser_width)))
        s.setValue("folders/open", self.last_open_dir)
        s.setValue("folders/save", self.last_save_dir)
        s.setValue("folders/export", self.last_export_dir)
        s.setValue("models/folder", self.models_dir)
        s.setValue("view/show_guide", bool(self.show_guide))
        s.setValue("view/wireframe", bool(self.wireframe))
        s.sync()
