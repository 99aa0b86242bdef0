"""Shared command-line plumbing: one-line flag errors, validated argument types, the error guard.

Every layer's subcommands (``engine.cli``, ``training.cli_*``) and the ``sketchmesh``
dispatcher use these, so a bad flag or a failing command reads the same everywhere: one
``sketchmesh ...: error: ...`` line on stderr and a non-zero exit, never a traceback.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import types
from collections.abc import Callable
from pathlib import Path

from engine.errors import OutputError, SketchmeshError
from engine.fileio import nearest_existing


def one_line_errors(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Make a parser report bad flags on one line (no usage block) and catch unknown flags itself.

    Without the second part, a sub-parser's unknown flags would be reported by the
    top-level parser with its multi-line usage text. Returns the same parser.
    """

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_known_args(self, args=None, namespace=None):
        ns, extras = argparse.ArgumentParser.parse_known_args(self, args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return ns, extras

    parser.error = types.MethodType(error, parser)
    parser.parse_known_args = types.MethodType(parse_known_args, parser)
    return parser


def int_in(lo: int, hi: int) -> Callable[[str], int]:
    """argparse type: an integer in [lo, hi]."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be in [{lo}, {hi}], got {value}")
        return value

    return parse


def int_from_env(name: str, lo: int, hi: int, what: str = "") -> int | None:
    """The whole number environment variable ``name`` sets, in [lo, hi]; None where it is unset or blank.

    Raises:
        SketchmeshError: ``name`` is set but not a whole number from ``lo`` to ``hi`` (``what`` follows the range in
            the message, e.g. " threads").
    """
    value = os.environ.get(name, "").strip()
    if not value:
        return None
    if not (value.isdigit() and lo <= int(value) <= hi):
        raise SketchmeshError(f"{name} must be a whole number from {lo} to {hi}{what}, got {value!r}")
    return int(value)


def positive_int(text: str) -> int:
    """argparse type: an integer > 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {value}")
    return value


def float_in(lo: float, hi: float) -> Callable[[str], float]:
    """argparse type: a finite number in [lo, hi] (``hi`` may be ``math.inf`` for 'no upper bound')."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not (math.isfinite(value) and lo <= value <= hi):
            raise argparse.ArgumentTypeError(f"must be a finite number in [{lo}, {hi}], got {text!r}")
        return value

    return parse


unit_float = float_in(0.0, 1.0)
"""argparse type: a number in [0, 1]."""


def _label(path: Path, what: str) -> str:
    return f"{what} {path}" if what else str(path)


def _check_can_create(path: Path, what: str, folder: Path) -> None:
    """Something can be created in ``folder`` (or, if absent, in its nearest existing ancestor)."""
    base = nearest_existing(folder)
    if not base.is_dir():
        raise OutputError(f"{_label(path, what)}: {base} is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".sketchmesh-write-test-", dir=base)
    except OSError as exc:
        raise OutputError(f"{_label(path, what)}: cannot write in {base} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)


def check_output_file(path: str | os.PathLike, what: str = "") -> Path:
    """Check, before any work, that a file can be written at ``path`` (created or replaced).

    Writes nothing that stays: a probe file is created and removed in the nearest existing
    folder. ``what`` names the flag in the message (``"--report"``).

    Raises:
        OutputError: ``path`` is a folder, a parent of it is a file, or its folder is not writable.
    """
    p = Path(path)
    if p.is_dir():
        raise OutputError(f"{_label(p, what)}: is a folder, expected a file name")
    _check_can_create(p, what, p.parent)
    return p


def check_output_dir(path: str | os.PathLike, what: str = "") -> Path:
    """Check, before any work, that ``path`` is a writable folder or can be created as one.

    Raises:
        OutputError: ``path`` is a file, a parent of it is a file, or nothing can be written there.
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputError(f"{_label(p, what)}: is a file, expected a folder")
    _check_can_create(p, what, p)
    return p


def _one_line(exc: BaseException) -> str:
    """The message on one line (torch's load_state_dict errors, for one, span several)."""
    return " ".join(str(exc).split())


def run_guarded(func: Callable[[argparse.Namespace], int | None], args: argparse.Namespace) -> int:
    """Run a command function; turn errors into one stderr line and an exit code.

    :class:`SketchmeshError` -> its message and ``exit_code``; Ctrl-C -> 130; OSError -> the file
    and the system's reason, exit 1; anything else -> its type and message, exit 1. With ``args.debug`` or ``SKETCHMESH_DEBUG=1`` the exception
    propagates with its traceback instead.
    """
    debug = getattr(args, "debug", False) or os.environ.get("SKETCHMESH_DEBUG") == "1"
    try:
        return int(func(args) or 0)
    except SketchmeshError as exc:
        if debug:
            raise
        print(f"sketchmesh: error: {_one_line(exc)}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("sketchmesh: interrupted", file=sys.stderr)
        return 130
    except OSError as exc:  # the file system said no (disk full, permissions): name the file
        if debug:
            raise
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"sketchmesh: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 1
    except Exception as exc:  # last resort: one line, not a traceback
        if debug:
            raise
        print(f"sketchmesh: error: {type(exc).__name__}: {_one_line(exc)} (rerun with --debug for the traceback)",
              file=sys.stderr)
        return 1
