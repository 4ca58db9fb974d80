"""Files that appear whole or not at all: atomic writes, streamed writers, output sets, CSV tables, safe names.

Everything the packages save goes through `atomic_path`: the data is written to a temporary file
in the same directory and renamed onto the target, so a crash or a bad input mid-write never
corrupts or loses what was saved before. A process killed mid-write leaves its temporary file
(``.NAME-xxxxxxxx.tmp.SUFFIX``) behind; `remove_stale_temporaries` clears old ones. The files of one
result (a state, its picture, its movie, ...) are an `labrig.outputset.OutputSet`:
a folder that replaces the earlier one in one step, even against a kill (`labrig.staging`).
"""

from __future__ import annotations

import contextlib
import csv
import io
import os
import re
import secrets
import stat
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

from .staging import SetBusyError, recover_beside
from .validate import InputError, printable

__all__ = ["atomic_path", "write_text_atomic", "write_csv", "temporary_beside", "existing_file",
           "remove_stale_temporaries", "writable_directory", "AllOrNothing", "StreamedFile", "SetBusyError",
           "recover_beside", "slug"]

#: Temporary files older than this (s) are left over from a killed process (`remove_stale_temporaries`).
STALE_AFTER = 3600.0


def temporary_beside(path: Path) -> Path:
    """Create an empty, uniquely named file next to ``path`` with the same suffix."""
    path = Path(path)
    if not path.name or path.name in (".", ".."):
        raise IsADirectoryError(f"{str(path)!r} names a directory, not a file")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"cannot write {str(path)!r}: the directory {str(path.parent)!r} does not exist")
    tmp = path.with_name(f".{path.stem}-{secrets.token_hex(4)}.tmp{path.suffix}")
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    return tmp


def existing_file(path: str | os.PathLike, what: str) -> Path:
    """``path`` as a Path if it names a regular file; FileNotFoundError if nothing is there, `InputError` if it
    is a directory, a pipe or another kind of file, or cannot be opened (a symbolic link loop, no permission)
    (``what`` names the file in messages, e.g. "scene file")."""
    path = Path(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise FileNotFoundError(f"{what} {str(path)!r} does not exist") from None
    except OSError as exc:  # ELOOP (a symbolic link loop), EACCES, ENAMETOOLONG, ...
        raise InputError(f"{what} {str(path)!r} cannot be opened: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"{what} {str(path)!r} is not a regular file (a directory or a pipe?)")
    return path


def writable_directory(path: str | os.PathLike, what: str = "output directory") -> Path:
    """``path`` as a Path if it is a directory or can be made one; `InputError` naming what is in the way (a
    file at ``path`` or at one of its parents, a symbolic link to nothing). Nothing is created."""
    path = Path(path)
    for part in (path, *path.parents):
        if part.is_symlink() and not part.exists():
            raise InputError(f"{what} {str(path)!r}: {str(part)!r} is a symbolic link to {os.readlink(part)!r}, "
                             "which does not exist")
        if part.exists():
            if not part.is_dir():
                where = "" if part == path else f": {str(part)!r}"
                raise InputError(f"{what} {str(path)!r}{where} is a file, not a directory")
            break
    return path


_TEMPORARY = re.compile(r"^\..+-[0-9a-f]{8}\.tmp(\..*)?$")


def remove_stale_temporaries(directory: str | os.PathLike, older_than: float = STALE_AFTER) -> list[Path]:
    """Delete the temporary files of `atomic_path` in ``directory`` older than ``older_than`` s.

    A process that is killed mid-write leaves its temporary file behind; a newer one may belong to
    a writer still running, so it is kept. Returns the files removed.
    """
    removed: list[Path] = []
    now = time.time()
    try:
        entries = list(os.scandir(os.fspath(directory)))
    except OSError:
        return removed
    for entry in entries:
        if not _TEMPORARY.match(entry.name):
            continue
        with contextlib.suppress(OSError):
            if entry.is_file(follow_symlinks=False) and now - entry.stat().st_mtime > older_than:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
    return removed


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` if the block succeeds.

    On any exception the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    tmp = temporary_beside(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through `atomic_path`; return the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


class AllOrNothing:
    """Base of what a ``with`` block writes whole or not at all: the block's normal end calls `finish`, an
    exception in it calls `abort`."""

    def finish(self):
        raise NotImplementedError

    def abort(self) -> None:
        raise NotImplementedError

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.finish()
        else:
            self.abort()


class StreamedFile(AllOrNothing):
    """Base of writers that stream into a temporary file and rename it into place on `close`.

    Subclasses open their stream on ``self._tmp`` and implement `_close_stream`;
    `_is_empty` may say that nothing worth keeping was written. Used as a
    context manager, an exception in the block calls `abort`: the partial file
    is removed and ``path`` is left as it was.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self._tmp = temporary_beside(self.path)
        self._open = True

    @property
    def closed(self) -> bool:
        return not self._open

    def _close_stream(self) -> None:
        raise NotImplementedError

    def _is_empty(self) -> bool:
        return False

    def close(self) -> Path | None:
        """Finish the file and move it onto ``path``; returns it, or None if nothing was written.

        Closing twice does nothing.
        """
        if self.closed:
            return self.path if self.path.exists() else None
        self._open = False
        try:
            self._close_stream()
            if self._is_empty():
                self._tmp.unlink(missing_ok=True)
                return None
            os.replace(self._tmp, self.path)
        except BaseException:
            self._tmp.unlink(missing_ok=True)
            raise
        return self.path

    def abort(self) -> None:
        """Drop the partial file; ``path`` is left untouched."""
        if self.closed:
            return
        self._open = False
        with contextlib.suppress(Exception):
            self._close_stream()
        self._tmp.unlink(missing_ok=True)

    def finish(self) -> Path | None:
        """`close` (what the end of a ``with`` block calls)."""
        return self.close()


def write_csv(path: str | os.PathLike, rows: Sequence[dict]) -> Path:
    """Write ``rows`` (dicts with the same keys) as CSV, atomically; returns the path.

    Control characters in text cells and column names are written escaped (`labrig.validate.printable`:
    ``\\x1b``, ``\\n``): a table holds one line per row, and nothing in it drives a terminal that shows it."""
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    columns = list(rows[0])
    writer.writerow([printable(key) for key in columns])
    writer.writerows([printable(value) if isinstance(value, str) else value for value in
                      (row.get(key, "") for key in columns)] for row in rows)
    return write_text_atomic(path, text.getvalue())


def slug(name: str) -> str:
    """A file-name-safe form of a run's name: ``"fig2-2a sigma=0"`` -> ``"fig2-2a_sigma0"``."""
    text = re.sub(r"[^A-Za-z0-9._-]+", "_", name.replace("=", "")).strip("_.")
    return text or "run"


def __getattr__(name: str):
    """``OutputSet``, imported from here until 0.4 (it is `labrig.outputset.OutputSet`; importing it here made
    the two modules import each other)."""
    if name == "OutputSet":
        import warnings

        from .outputset import OutputSet

        warnings.warn("labrig.files.OutputSet is labrig.outputset.OutputSet; importing it from labrig.files stops "
                      "working in 0.4", DeprecationWarning, stacklevel=2)
        return OutputSet
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
