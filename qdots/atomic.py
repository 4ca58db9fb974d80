"""Atomic file writes: a result appears whole under its name, or not at all.

Everything qdots saves goes through `atomic_path`: the data is written to a
temporary file in the same directory and renamed onto the target, so a crash
or a bad input mid-write never corrupts or loses what was saved before.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from pathlib import Path
from typing import Iterator


def temporary_beside(path: Path) -> Path:
    """Create an empty, uniquely named file next to ``path`` with the same suffix."""
    tmp = path.with_name(f".{path.stem}-{secrets.token_hex(4)}.tmp{path.suffix}")
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    return tmp


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


class StreamedFile:
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

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
