"""Sketchmesh desktop app (PySide6). Calls :mod:`engine` only, on a worker thread."""
