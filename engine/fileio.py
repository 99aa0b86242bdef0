"""Atomic file writes: write to a temporary file in the same folder, fsync, rename.

A reader never sees a half-written file, and a crash mid-write leaves the old file intact
(and, at worst, a ``.NAME.XXXX.tmp`` sibling; :func:`remove_stale_temporaries` clears those).
:class:`StagedWrites` extends this to several files: all of them appear, or none does.

Test hook: with ``SKETCHMESH_TEST_STALL_WRITE=NAME`` in the environment, a write to a file
called ``NAME`` puts the first half of its bytes into the temporary file, fsyncs, then sleeps
``SKETCHMESH_TEST_STALL_SECONDS`` (default 60) before writing the rest, so a test can SIGKILL
the process while the write is provably in flight.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO

STALL_ENV = "SKETCHMESH_TEST_STALL_WRITE"
STALL_SECONDS_ENV = "SKETCHMESH_TEST_STALL_SECONDS"
TMP_SUFFIX = ".tmp"


def _current_umask() -> int:
    umask = os.umask(0o022)  # reading the umask means setting it: done once, at import, before threads
    os.umask(umask)
    return umask


_UMASK = _current_umask()


def _target_mode(path: Path) -> int:
    try:
        return path.stat().st_mode & 0o7777
    except FileNotFoundError:
        return 0o666 & ~_UMASK


def _temporary_sibling(path: Path) -> tuple[int, str]:
    """Create the parents of ``path`` and a temporary file beside it; (fd, temp path).

    Raises:
        OSError: naming ``path`` (not the temporary file) and why it cannot be written.
    """
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        return tempfile.mkstemp(prefix=f".{path.name}.", suffix=TMP_SUFFIX, dir=path.parent)
    except OSError as exc:
        blocker = nearest_existing(path.parent)
        if not blocker.is_dir():
            raise NotADirectoryError(errno.ENOTDIR, f"{blocker} is a file, not a folder", str(path)) from None
        raise type(exc)(exc.errno, exc.strerror, str(path)) from None


def nearest_existing(path: str | os.PathLike) -> Path:
    """``path`` itself if it exists, else its nearest existing ancestor (a file or a folder)."""
    p = Path(os.path.abspath(path))
    while not os.path.lexists(p) and p != p.parent:
        p = p.parent
    return p


def _stall_seconds(path: Path) -> float | None:
    if os.environ.get(STALL_ENV) != path.name:
        return None
    return float(os.environ.get(STALL_SECONDS_ENV, "60"))


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb") -> Iterator[IO]:
    """Open a temporary sibling of ``path`` for writing; rename it over ``path`` on success.

    On an exception the temporary file is removed and ``path`` is left untouched. The file gets
    the permissions a plain ``open`` would give (``0o666`` less the umask; an existing file keeps
    its mode), not ``mkstemp``'s private ``0o600``. An OSError raised before the data is written
    (a parent that is a file, a read-only folder) names ``path``, never the temporary file.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open mode must be 'w' or 'wb', got {mode!r}")
    path = Path(path)
    fd, tmp = _temporary_sibling(path)
    stall = _stall_seconds(path)
    try:
        with os.fdopen(fd, mode, **({"encoding": "utf-8"} if mode == "w" else {})) as fh:
            if stall is None:
                yield fh
            else:  # the test hook: half the bytes on disk, then a pause a test can kill into
                buf = io.StringIO() if mode == "w" else io.BytesIO()
                yield buf
                data = buf.getvalue()
                fh.write(data[: len(data) // 2])
                fh.flush()
                os.fsync(fh.fileno())
                time.sleep(stall)
                fh.write(data[len(data) // 2:])
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _target_mode(path))
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_open(path, "wb") as fh:
        fh.write(data)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_open(path, "w") as fh:
        fh.write(text)


class StagedWrites:
    """Write several files all or nothing.

    :meth:`add` writes each file's bytes to a temporary sibling (fsynced); :meth:`commit` renames
    them all into place; :meth:`discard` (or leaving the ``with`` block by an exception) removes
    the temporaries and leaves every target untouched. Parent folders created for a file that is
    then discarded are removed again when empty.

    Example::

        with StagedWrites() as staged:
            staged.add(mesh_path, mesh_bytes)
            staged.add(report_path, report_bytes)   # fails? the mesh is not written either
    """

    def __init__(self) -> None:
        self._staged: list[tuple[str, Path]] = []
        self._created_dirs: list[Path] = []

    def add(self, path: str | os.PathLike, data: bytes | str) -> None:
        """Stage ``data`` (str is written as UTF-8) for ``path``; raises OSError naming ``path``."""
        path = Path(path)
        missing = []
        parent = path.parent
        while not parent.exists() and parent != parent.parent:
            missing.append(parent)
            parent = parent.parent
        self._created_dirs.extend(missing)  # deepest first: removal order (also if the next line fails midway)
        fd, tmp = _temporary_sibling(path)
        self._staged.append((tmp, path))
        with os.fdopen(fd, "wb") as fh:
            fh.write(data.encode("utf-8") if isinstance(data, str) else data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _target_mode(path))

    def commit(self) -> list[Path]:
        """Rename every staged file into place; returns the paths written."""
        done = []
        try:
            for tmp, path in self._staged:
                os.replace(tmp, path)
                done.append(path)
        except BaseException:
            for path in done:  # a rename failed (very rare): do not leave a partial set behind
                with contextlib.suppress(OSError):
                    path.unlink()
            self.discard()
            raise
        self._staged, self._created_dirs = [], []
        return done

    def discard(self) -> None:
        """Remove every staged temporary file (and the folders created for them, when empty)."""
        for tmp, _ in self._staged:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
        for folder in self._created_dirs:
            with contextlib.suppress(OSError):
                folder.rmdir()
        self._staged, self._created_dirs = [], []

    def __enter__(self) -> StagedWrites:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()


def remove_stale_temporaries(folder: str | os.PathLike, name_glob: str = "*") -> list[Path]:
    """Delete the temporary siblings a killed atomic write left in ``folder`` (``.NAME.XXXX.tmp``).

    Only the process that writes ``folder`` may call this (it would delete another writer's
    temporary file mid-write). Returns the files removed.
    """
    removed = []
    folder = Path(folder)
    if not folder.is_dir():
        return removed
    for p in folder.glob(f".{name_glob}.*{TMP_SUFFIX}"):
        if p.is_file():
            with contextlib.suppress(FileNotFoundError):
                p.unlink()
                removed.append(p)
    return removed
