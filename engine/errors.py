"""User-facing errors. The CLI prints their message on one line and exits non-zero."""


class SketchmeshError(Exception):
    """Base class: a problem with the user's input or environment, described in the message."""

    exit_code = 2


class SketchInputError(SketchmeshError):
    """The sketch (image file or stroke data) cannot be used: unreadable, blank, absurd size, NaN."""


class EmptySketchError(SketchInputError):
    """The sketch has no ink."""


class ModelError(SketchmeshError):
    """A model file or folder is missing, corrupt, or does not match the engine's contract."""


class MeshInputError(SketchmeshError):
    """A mesh file cannot be read or has no usable triangles."""


class ExportError(SketchmeshError):
    """A mesh cannot be written (unknown format, unwritable path)."""


class OutputError(SketchmeshError):
    """An output file or folder cannot be written (a parent that is a file, a read-only folder)."""


class MissingExtraError(SketchmeshError):
    """A command needs an optional dependency group that is not installed."""
